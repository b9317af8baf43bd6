"""The executor: Dask LocalCluster, process pool, serial; results complete out of order."""
import gc
import os

import pytest

from morphoshell.workflows.executor import SerialExecutor, backend_name, open_executor, run


def _square_and_pid(x):
    return x * x, os.getpid(), os.environ.get("OMP_NUM_THREADS")


def test_serial_runs_in_this_process():
    with open_executor(workers=1) as ex:
        assert isinstance(ex, SerialExecutor) and backend_name(ex) == "serial"
        out = dict(run(_square_and_pid, range(4), ex))
    assert [out[i][0] for i in range(4)] == [0, 1, 4, 9]
    assert {v[1] for v in out.values()} == {os.getpid()}


def test_a_two_worker_dask_cluster_runs_single_threaded_processes():
    pytest.importorskip("distributed")
    import sys

    import cloudpickle
    # the workers cannot import this test module: send the task function by value
    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    with open_executor(workers=2) as ex:
        assert backend_name(ex) == "dask"
        out = dict(run(_square_and_pid, range(8), ex))
    assert sorted(v[0] for v in out.values()) == [i * i for i in range(8)]
    pids = {v[1] for v in out.values()}
    assert os.getpid() not in pids and 1 <= len(pids) <= 2
    assert {v[2] for v in out.values()} == {"1"}      # MUMPS: one thread per worker
    assert os.environ.get("OMP_NUM_THREADS") != "1" or "OMP_NUM_THREADS" in os.environ


def test_dask_workers_keep_large_blocks_in_the_heap():
    # Dask starts its workers with MALLOC_TRIM_THRESHOLD_=65536, which had every block
    # above 128 KiB mapped and unmapped at each evaluation (audit 18, F12)
    pytest.importorskip("distributed")
    import platform

    from morphoshell._runtime.allocator import served_from_heap
    from morphoshell._runtime.workers import WORKER_ENVIRON

    if platform.libc_ver()[0] != "glibc":
        pytest.skip("mallinfo2 is glibc's")
    import sys

    import cloudpickle
    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    with open_executor(workers=2) as ex:
        report = [ex.submit(_allocator_state, served_from_heap, sorted(WORKER_ENVIRON)).result()
                  for _ in range(4)]
    assert {heap for heap, _ in report} == {True}
    assert all(env == {k: WORKER_ENVIRON[k] for k in env} for _, env in report)


def _allocator_state(probe, names):
    return probe(), {k: os.environ.get(k) for k in names}


def test_dask_workers_do_not_take_the_terminals_ctrl_c():
    """A Ctrl-C to the terminal's process group reached the Dask workers too: one that was
    starting printed "Fatal Python error: init_import_site ... KeyboardInterrupt" (audit
    23 F5).  They start with SIGINT blocked, as the main process kills them anyway."""
    pytest.importorskip("distributed")
    import signal
    import sys

    import cloudpickle
    if not hasattr(signal, "pthread_sigmask"):
        pytest.skip("no signal masks")
    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    with open_executor(workers=2) as ex:
        blocked = {ex.submit(_sigint_blocked, i).result() for i in range(4)}
    assert blocked == {True}
    assert signal.SIGINT not in signal.pthread_sigmask(signal.SIG_BLOCK, [])    # (not here)


def _sigint_blocked(_):
    import signal
    return signal.SIGINT in signal.pthread_sigmask(signal.SIG_BLOCK, [])


def test_no_free_core_compares_the_load_with_the_cores(monkeypatch):
    from morphoshell.workflows import executor

    monkeypatch.setattr(executor.os, "cpu_count", lambda: 2)
    for load, busy in ((1.99, False), (2.0, True), (5.3, True)):
        monkeypatch.setattr(executor.os, "getloadavg", lambda: (load, 0.0, 0.0))
        assert executor.no_free_core() is busy
    monkeypatch.delattr(executor.os, "getloadavg")      # (no load average: not busy)
    assert executor.no_free_core() is False


def test_errors_in_tasks_reach_the_caller():
    with open_executor(workers=1) as ex, pytest.raises(ZeroDivisionError):
        list(run(lambda x: 1 / x, [1, 0], ex))


def test_bad_worker_counts_are_named():
    with pytest.raises(ValueError, match=r"workers = 0 must be a positive integer"):
        with open_executor(workers=0):
            pass


@pytest.mark.parametrize("address", ["tcp://127.0.0.1:9", "no-port-here"])
def test_a_scheduler_that_does_not_answer_is_named_and_leaves_dask_as_it_was(address):
    pytest.importorskip("distributed")
    import dask

    from distributed import Client

    gc.collect()
    clients = {id(o) for o in gc.get_objects() if isinstance(o, Client)}   # other tests'
    before = dask.config.get("scheduler", None)
    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
        with pytest.raises(ValueError, match=f"--scheduler {address}: no Dask scheduler "
                                             "answered there"):
            with open_executor(scheduler=address):
                pass
    # (a Client that failed on a malformed address set it to "dask.distributed": xarray's
    # computations in the same process then failed)
    assert dask.config.get("scheduler", None) == before
    # and it is gone: left to the garbage collector, its __del__ ran inside the next
    # Client's start and deadlocked the suite
    assert not [o for o in gc.get_objects() if isinstance(o, Client) and id(o) not in clients]


def test_a_ctrl_c_dropped_in_a_serial_task_stops_the_next_one():
    """The serial executor runs each task at submission: a Ctrl-C that CasADi dropped in
    one task (morphoshell._runtime.interrupts) is raised before the next runs."""
    import signal
    import time

    from morphoshell._runtime.interrupts import noted

    def dropped(i):
        if i == 0:
            try:
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(5)
            except KeyboardInterrupt:           # as CasADi drops one
                pass
        return i

    ran = []
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with noted(), pytest.raises(KeyboardInterrupt):
            list(run(lambda i: ran.append(i) or dropped(i), range(3), SerialExecutor()))
    finally:
        signal.signal(signal.SIGINT, previous)
    assert ran == [0]


_SCRIPT = """
import sys
from morphoshell.workflows.executor import _check_main_guard
{call}
print("passed")
"""


@pytest.mark.parametrize("call, refused", [
    ('_check_main_guard("spawn")', True),                          # the docs' script, unguarded
    ('if __name__ == "__main__":\n    _check_main_guard("spawn")', False),
    ('_check_main_guard("fork")', False),                          # fork imports nothing
])
def test_a_script_that_starts_workers_outside_the_main_guard_is_told_on_one_line(
        tmp_path, call, refused):
    """Spawned workers import the script: unguarded, each would start the work again, and
    the script died in 299 lines of Dask and multiprocessing tracebacks (user audit 5)."""
    import subprocess
    import sys
    from pathlib import Path

    script = tmp_path / "script.py"
    script.write_text(_SCRIPT.format(call=call))
    src = str(Path(__file__).resolve().parents[2] / "src")
    run = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                         env={**os.environ, "PYTHONPATH": src}, timeout=120)
    if refused:
        last = run.stderr.strip().splitlines()[-1]
        assert run.returncode == 1 and last.startswith("RuntimeError: ")
        assert f"{script}, line 4: " in last and 'if __name__ == "__main__":' in last
    else:
        assert run.returncode == 0 and run.stdout.strip() == "passed", run.stderr


def test_the_bar_counts_what_each_task_is_worth(monkeypatch, recorded_bar):
    """A sweep's bar counts points, each chunk worth its points (it counted chunks)."""
    from morphoshell.workflows import executor

    seen, counter = recorded_bar
    monkeypatch.setattr(executor, "counter", counter)
    with open_executor(workers=1) as ex:
        assert dict(run(abs, [-1, -2], ex, sizes=[3, 5], unit="point")) == {0: 1, 1: 2}
        assert dict(run(abs, [-1], ex)) == {0: 1}
    # (in order of completion)
    assert seen[0] == (8, "point") and sorted(seen[1:3]) == [3, 5] and seen[3:] == [(1, "task"), 1]
