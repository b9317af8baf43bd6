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
