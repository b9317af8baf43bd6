"""Large arrays from the heap (morphoshell._runtime.allocator)."""
import ctypes
import platform

import pytest

from morphoshell import keep_large_blocks
from morphoshell.cli import main


@pytest.mark.skipif(platform.system() != "Linux" or platform.libc_ver()[0] != "glibc",
                    reason="mallopt is glibc's")
def test_glibc_accepts_the_thresholds():
    assert keep_large_blocks() is True
    assert keep_large_blocks(1 << 40) is True        # capped at 1 GiB (int32 arguments)


def test_without_mallopt_nothing_changes(monkeypatch):
    class NoMallopt:
        def __init__(self, name):
            pass
    monkeypatch.setattr(ctypes, "CDLL", NoMallopt)
    assert keep_large_blocks() is False


def test_the_command_line_keeps_large_blocks(monkeypatch, capsys):
    calls = []
    monkeypatch.setattr("morphoshell._runtime.allocator.keep_large_blocks",
                        lambda: calls.append(1) or True)
    assert main(["example", "toy2_ablation"]) == 0
    assert calls == [1]
