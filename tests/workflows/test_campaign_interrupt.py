"""Ctrl-C on a campaign: it stops at once, its workers with it, on one line that says how far
it got; exit status 130.  (A process pool waited for its running fits, 103 s on the
synthetic data; Dask printed three warnings and took 4.7 s; in this process a Ctrl-C within
CasADi read as a bug, exit 1, or within Ipopt was swallowed: the campaign ran on.)
SIGTERM (a batch system's stop) is handled alike, exit status 143: it ended with no message
and Python's resource_tracker warning of leaked semaphores (user audit 5)."""
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from morphoshell.io.timepoints import read_timepoints

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "data" / "synthetic_inversion"
#: A campaign's command line, run in a subprocess whose Dask can be hidden (a process pool).
ENTRY = """import sys
if sys.argv[1] != "dask":
    sys.modules["distributed"] = None           # as without Dask installed
from morphoshell.cli import main
raise SystemExit(main(sys.argv[2:]))
"""
LINE = re.compile(r"morphoshell: (interrupted|terminated \(SIGTERM\)): (\d+) of (\d+) fits done "
                  r"\(in .+\), resume with the same command\n")
#: What CasADi prints itself when Ctrl-C reaches it within Ipopt (this process only).
CASADI = re.compile(r"CasADi - .* WARNING\(\"KeyboardInterruptException\"\) .*\n")


@pytest.mark.parametrize("backend, method, sig", [
    ("processes", "gradient", signal.SIGINT), ("dask", "gradient", signal.SIGINT),
    ("serial", "kkt", signal.SIGINT),
    ("processes", "gradient", signal.SIGTERM), ("serial", "kkt", signal.SIGTERM)])
def test_ctrl_c_stops_a_campaign_at_once_on_one_line(tmp_path, backend, method, sig):
    psutil = pytest.importorskip("psutil")
    if backend == "dask":
        pytest.importorskip("distributed")
    out = tmp_path / "fits"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "src"),
                                                        os.environ.get("PYTHONPATH", "")])}
    # a new session: Ctrl-C reaches the whole group (the campaign and its workers), as on
    # a terminal
    proc = subprocess.Popen(
        [sys.executable, "-c", ENTRY, backend, "campaign", str(DATA), "--variants",
         "flat,free", "--method", method, "--nodes", "20",
         "--workers", "1" if backend == "serial" else "2", "--out", str(out)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
        start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        while not (out / "campaign_settings.json").exists():     # the workers are starting
            assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
            time.sleep(0.1)
        time.sleep(1.5)                                        # and fitting
        workers = psutil.Process(proc.pid).children(recursive=True)
        assert (backend == "serial" or workers) and proc.poll() is None
        t0 = time.monotonic()
        if sig == signal.SIGINT:
            os.killpg(proc.pid, sig)        # (the terminal's Ctrl-C)
        else:
            os.kill(proc.pid, sig)          # (`kill PID`: the campaign's process alone)
        stdout, stderr = proc.communicate(timeout=60)
        seconds = time.monotonic() - t0
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == (130 if sig == signal.SIGINT else 143), stderr
    if backend == "serial":       # (CasADi's own line, when Ctrl-C reached it within Ipopt)
        stderr = CASADI.sub("", stderr, count=1)
    assert LINE.fullmatch(stderr), stderr
    word, done, total = LINE.fullmatch(stderr).groups()
    assert (word == "interrupted") == (sig == signal.SIGINT)
    done, total = int(done), int(total)
    assert total == 2 * len(read_timepoints(DATA))
    assert done == len(list(out.glob("t*_*.json")))
    assert seconds < 3, seconds
    time.sleep(0.5)
    alive = [w for w in workers if w.is_running() and w.status() != psutil.STATUS_ZOMBIE]
    assert not alive, alive
