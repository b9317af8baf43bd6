"""Ctrl-C however it arrives (morphoshell._runtime.interrupts): as a SystemError out of a
CasADi function, or swallowed by an Ipopt solve that returns NonIpopt_Exception_Thrown."""
import os
import signal
import time

import pytest

from morphoshell._runtime.interrupts import interrupted, noted, swallowed
from morphoshell.numerics.ipopt import ipopt_status


def test_an_exception_caused_by_ctrl_c_is_an_interrupt():
    try:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as exc:     # as CPython reports an error CasADi returned
            raise SystemError("returned a result with an exception set") from exc
    except SystemError as exc:
        assert interrupted(exc)
    loop = ValueError("a")
    loop.__context__ = RuntimeError("b")
    loop.__context__.__context__ = loop
    assert not interrupted(loop) and not interrupted(SystemError("a bug"))
    assert interrupted(KeyboardInterrupt())


@pytest.fixture(autouse=True)
def _sigterm_flag_kept():
    """The "a SIGTERM arrived" flag (kept after noted() for the command line's message)
    as it was: a test's SIGTERM made a later test's sweep say "terminated (SIGTERM)"."""
    from morphoshell._runtime import interrupts

    kept = interrupts._terminated[0]
    yield
    interrupts._terminated[0] = kept


@pytest.fixture
def default_handler():
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


def test_an_ipopt_solve_that_swallowed_a_ctrl_c_raises_it(default_handler):
    status = {"return_status": "NonIpopt_Exception_Thrown"}
    assert ipopt_status(status) == "NonIpopt_Exception_Thrown"      # no Ctrl-C: a failure
    with noted():
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(5)
        # as if CasADi had caught that one within Ipopt: the solve's status says so
        with pytest.raises(KeyboardInterrupt):
            ipopt_status(status)
        assert ipopt_status(status) == "NonIpopt_Exception_Thrown"   # (claimed once)
        assert not swallowed()
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_a_ctrl_c_that_casadi_dropped_stops_a_campaign_between_fits(default_handler, tmp_path,
                                                                    monkeypatch):
    """CasADi's wrappers drop a KeyboardInterrupt raised while they try a conversion's
    overloads (ca.DM(list) during Ctrl-C returned normally, and a serial campaign ran to its
    end, exit 3).  The fits' loop checks the count: the fit so cut is not stored, and the
    Ctrl-C is raised before the next."""
    import morphoshell.workflows.timepoint_fits as timepoint_fits
    from morphoshell._runtime.interrupts import check
    from morphoshell.io.timepoints import Timepoint

    def dropped(*args):             # a fit during which CasADi dropped a Ctrl-C
        try:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(5)
        except KeyboardInterrupt:
            pass
        return {"status": "ok"}

    monkeypatch.setattr(timepoint_fits, "_fit_one", dropped)
    monkeypatch.setattr(timepoint_fits, "_settings", lambda *args: {"x": 1})
    task = type("Task", (), {"out": str(tmp_path), "variant": "flat", "owner": None,
                             "timepoints": (Timepoint("t01", 0.0, "a.csv"),)})()
    with noted():
        check()                     # nothing pending: no effect
        with pytest.raises(KeyboardInterrupt):
            timepoint_fits.fit_variant(task)
        check()                     # (claimed)
    assert not list(tmp_path.iterdir())


def test_a_ctrl_c_that_casadi_dropped_during_a_command_writes_nothing(default_handler, tmp_path,
                                                                      monkeypatch, capsys):
    """A single `solve` (or `fit`, `estimate`) has no loop to check between steps: a Ctrl-C
    CasADi dropped let it write its outputs and exit 0.  Outputs.commit checks first."""
    import morphoshell.solvers.routes as routes
    from morphoshell.cli import main

    solve = routes.solve

    def dropped(*args, **kwargs):   # a solve during which CasADi dropped a Ctrl-C
        try:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(5)
        except KeyboardInterrupt:
            pass
        return solve(*args, **kwargs)

    monkeypatch.setattr(routes, "solve", dropped)
    out = tmp_path / "eq.json"
    assert main(["solve", "problems/toy1_sphere.toml", "--nodes", "40",
                 "--json", str(out)]) == 130
    assert "interrupted" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())
    monkeypatch.setattr(routes, "solve", solve)     # (without a Ctrl-C: written, exit 0)
    assert main(["solve", "problems/toy1_sphere.toml", "--nodes", "40",
                 "--json", str(out)]) == 0 and out.exists()


def test_casadis_own_line_of_a_ctrl_c_is_dropped_from_stderr(default_handler, capsys):
    """Ctrl-C within Ipopt printed CasADi's `WARNING("KeyboardInterruptException")` line above
    the command's own one-line message (user audit 9).  Under noted() it is dropped, written
    as CasADi writes it (in pieces, through sys.stderr); its other lines and the rest pass."""
    import sys

    pieces = ["CasADi - ", "2026", "-", "11", " WARNING(\"", "KeyboardInterruptException",
              "\") [", ".../ipopt_nlp.cpp:132", "]\n", "morphoshell: interrupted", "\n",
              "Cas", "ADi - 2026 WARNING(\"other\")\n", "50%\r"]
    with noted():
        for piece in pieces:
            sys.stderr.write(piece)
    assert capsys.readouterr().err == ("morphoshell: interrupted\n"
                                       "CasADi - 2026 WARNING(\"other\")\n50%\r")
    assert "Quiet" not in type(sys.stderr).__name__       # (restored)


def test_sigterm_is_handled_when_ctrl_c_is_ignored():
    """A job started in a script's background (`cmd &`) has Ctrl-C ignored; noted() then
    installed no handler at all, and a SIGTERM killed it at once, exit 143, no word and
    nothing written (audit 22, F1).  SIGTERM is handled; the ignored Ctrl-C stays ignored."""
    from morphoshell._runtime.interrupts import Terminated, exit_status

    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    term = signal.signal(signal.SIGTERM, signal.SIG_DFL)
    try:
        with noted():
            assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
            # (checked before the signal: at its default it would kill the tests' process)
            assert signal.getsignal(signal.SIGTERM) != signal.SIG_DFL
            with pytest.raises(Terminated):
                os.kill(os.getpid(), signal.SIGTERM)
                time.sleep(5)
        assert exit_status() == 143
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
        assert signal.getsignal(signal.SIGTERM) == signal.SIG_DFL
    finally:
        signal.signal(signal.SIGINT, previous)
        signal.signal(signal.SIGTERM, term)


def test_a_deferred_signal_is_raised_when_delivered_and_a_second_one_at_once(default_handler):
    """deferred(): held within the block (a Dask cluster's start, which an exception
    stopped half way: audit 23 F5), raised by the handler in force when delivered; a
    second one is raised at once (a start that hangs can still be stopped)."""
    from morphoshell._runtime.interrupts import Terminated, deferred, exit_status

    term = signal.signal(signal.SIGTERM, signal.SIG_DFL)
    try:
        with noted():
            with deferred() as deliver:
                os.kill(os.getpid(), signal.SIGTERM)
                time.sleep(0.2)                 # (no exception: held)
                with pytest.raises(Terminated):
                    deliver()
            assert exit_status() == 143
            reached = []
            with pytest.raises(KeyboardInterrupt):
                with deferred():
                    os.kill(os.getpid(), signal.SIGINT)
                    time.sleep(0.2)
                    reached.append("end")       # (held until the block's end)
            assert reached == ["end"]
            start = time.monotonic()
            with pytest.raises(KeyboardInterrupt), deferred():
                os.kill(os.getpid(), signal.SIGINT)
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(5)
            assert time.monotonic() - start < 4     # (raised at once, not after the sleep)
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
        assert signal.getsignal(signal.SIGTERM) == signal.SIG_DFL
    finally:
        signal.signal(signal.SIGTERM, term)


def test_an_ignored_ctrl_c_stays_ignored_under_deferred():
    from morphoshell._runtime.interrupts import deferred

    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        with deferred():
            assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
            os.kill(os.getpid(), signal.SIGINT)
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, previous)
