"""Ctrl-C or SIGTERM while a Dask LocalCluster starts: one line, no Dask tracebacks.

Audit 23 F5: interrupted 0.7-1.3 s into ``sweep --workers 2`` or ``campaign``, the
command printed its line and then 20-110 lines of Dask's: its exit hook closing the
half-built cluster ("AssertionError: Status.init"), a worker that took the terminal's
Ctrl-C while it started ("Fatal Python error: init_import_site ... KeyboardInterrupt"),
nannies whose workers died ("Task exception was never retrieved ... Nanny failed to
start.").  Each run below starts a cluster the way the command line does (under
``interrupts.noted``) and is interrupted at a point of its start.
"""
import os
import signal
import subprocess
import sys
import time

import pytest

pytest.importorskip("distributed")
psutil = pytest.importorskip("psutil")
if not hasattr(signal, "pthread_sigmask"):       # (no process groups nor signal masks)
    pytest.skip("POSIX signals", allow_module_level=True)

#: The command line's handling, in small: the one line is the script's.
_SCRIPT = """
import sys, time
from morphoshell._runtime.interrupts import exit_status, noted, reason
from morphoshell.workflows.executor import open_executor

if __name__ == "__main__":
    try:
        with noted():
            print("starting", flush=True)
            with open_executor(workers=2):
                print("started", flush=True)
                time.sleep(60)
    except KeyboardInterrupt:
        print(f"stopped: {reason()}", file=sys.stderr)
        sys.exit(exit_status())
"""


def _workers(process: psutil.Process) -> list:
    """The started worker processes of ``process`` (spawned: past their exec)."""
    found = []
    for child in process.children(recursive=True):
        try:
            line = " ".join(child.cmdline())
        except psutil.Error:
            continue
        if "spawn_main" in line and "resource_tracker" not in line:
            found.append(child)
    return found


def _interrupted(tmp_path, when: str, delay: float, sig: int, group: bool):
    """Run the script, send ``sig`` ``delay`` s after ``when`` ("start": the script's
    "starting"; "worker": its first worker process, Python still starting in it), to the
    process group (a terminal's Ctrl-C) or the process; its status, standard error, and
    its worker processes still running 5 s after it ended."""
    script = tmp_path / "start.py"
    script.write_text(_SCRIPT)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    run = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, text=True, env=env, cwd=tmp_path,
                           start_new_session=True)
    try:
        assert run.stdout.readline() == "starting\n"
        process, workers = psutil.Process(run.pid), []
        deadline = time.time() + 60
        while when == "worker" and not workers and time.time() < deadline:
            workers = _workers(process)
            time.sleep(0.005)
        time.sleep(delay)
        workers = workers or _workers(process)
        (os.killpg if group else os.kill)(run.pid, sig)
        _, err = run.communicate(timeout=60)
    finally:
        if run.poll() is None:
            os.killpg(run.pid, signal.SIGKILL)
            run.wait()
    _, alive = psutil.wait_procs(workers, timeout=5)
    for p in alive:
        p.kill()
    return run.returncode, err, alive


@pytest.mark.parametrize("when, delay, sig, group", [
    ("worker", 0.0, signal.SIGINT, True),       # Ctrl-C while Python starts in a worker
    ("worker", 0.3, signal.SIGINT, True),       # ... while it imports Dask
    ("worker", 0.0, signal.SIGTERM, False),     # SIGTERM with the nannies starting
    ("start", 0.3, signal.SIGINT, True),        # before any worker: the scheduler starts
])
def test_an_interrupt_while_the_cluster_starts_prints_one_line(tmp_path, when, delay, sig,
                                                               group):
    status, err, alive = _interrupted(tmp_path, when, delay, sig, group)
    reason = "terminated (SIGTERM)" if sig == signal.SIGTERM else "interrupted"
    assert (status, err) == (128 + sig, f"stopped: {reason}\n"), err
    assert not alive, f"{len(alive)} worker processes still running"
