"""What every worker process is given (morphoshell._runtime.workers)."""
import os
import platform
import subprocess
import sys
from pathlib import Path

import pytest

from morphoshell._runtime.workers import WORKER_ENVIRON, worker_environment

SRC = str(Path(__file__).resolve().parents[2] / "src")
glibc = pytest.mark.skipif(platform.system() != "Linux" or platform.libc_ver()[0] != "glibc",
                           reason="mallopt and mallinfo2 are glibc's")

#: A pool of two forked workers, each asked how a 4 MiB block is served, in a process started
#: as Dask starts its workers (MALLOC_TRIM_THRESHOLD_=65536: no adaptive mmap threshold).
POOL = """
import multiprocessing
from morphoshell._runtime.allocator import served_from_heap
from morphoshell.workflows.executor import _process_pool
multiprocessing.set_start_method("fork")
with _process_pool(2) as pool:
    print(served_from_heap(), sorted(set(pool.map(served_from_heap, [4 << 20] * 4))))
"""


def _python(code: str, **env) -> str:
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env={**os.environ, "PYTHONPATH": SRC, **env}, timeout=120)
    assert out.returncode == 0, out.stderr
    return out.stdout.strip()


@glibc
def test_a_dask_like_allocator_maps_every_large_block_and_the_worker_environment_does_not():
    probe = "from morphoshell._runtime.allocator import served_from_heap as s; print(s(), s())"
    # (the second block too: the threshold no longer adapts to the first one freed)
    assert _python(probe, MALLOC_TRIM_THRESHOLD_="65536") == "False False"
    assert _python(probe, **{"MALLOC_TRIM_THRESHOLD_": "65536", **WORKER_ENVIRON}) == \
        "True True"


@glibc
def test_a_forked_pool_worker_keeps_large_blocks_whatever_its_parent_does():
    # the parent maps them (printed first); its forked workers, set up by worker_start, do not
    assert _python(POOL, MALLOC_TRIM_THRESHOLD_="65536") == "False [True]"


def test_the_worker_environment_is_set_in_the_block_and_restored_after(monkeypatch):
    monkeypatch.setenv("OMP_NUM_THREADS", "7")
    monkeypatch.delenv("MALLOC_MMAP_THRESHOLD_", raising=False)
    with worker_environment():
        assert {k: os.environ.get(k) for k in WORKER_ENVIRON} == WORKER_ENVIRON
        assert int(os.environ["MALLOC_MMAP_THRESHOLD_"]) >= 1 << 30
    assert os.environ["OMP_NUM_THREADS"] == "7" and "MALLOC_MMAP_THRESHOLD_" not in os.environ


@glibc
def test_the_probe_sees_the_heap_after_keep_large_blocks():
    code = ("from morphoshell import keep_large_blocks; from morphoshell._runtime.allocator "
            "import served_from_heap as s; a = s(); keep_large_blocks(); print(a, s())")
    assert _python(code, MALLOC_TRIM_THRESHOLD_="65536") == "False True"
