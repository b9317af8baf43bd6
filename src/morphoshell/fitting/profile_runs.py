"""Profiles of several parameters run one after another, those finished kept when Ctrl-C or
SIGTERM stops the run (:class:`ProfilesInterrupted`).

A profile of each of a Volvox fit's 12 parameters at 200 nodes takes minutes to an hour
(20 refits of 1-10 s each); ``morphoshell fit --profile`` interrupted lost the fit, done in
the first second, and every profile finished (audit 23).  The command line writes them,
marked partial, as ``continue`` and ``sweep`` do with theirs.
"""
from __future__ import annotations

from typing import Callable, Sequence

from .._runtime import interrupts

__all__ = ["ProfilesInterrupted", "each_profile"]


class ProfilesInterrupted(KeyboardInterrupt):
    """Ctrl-C (or SIGTERM) during the profiles of
    :func:`~morphoshell.fitting.profiles.profiled_fit`, with what it finished.

    Attributes
    ----------
    fit : FitResult
        The fit the finished profiles are about (the given one, or a lower refit).
    profiles : dict
        :class:`~morphoshell.fitting.profiles.Profile` by name, those finished, in order.
    """

    def __init__(self, fit, profiles: dict):
        super().__init__(f"{interrupts.reason()} after {len(profiles)} profile(s)")
        self.fit, self.profiles = fit, profiles


def each_profile(names: Sequence[str], fit, compute: Callable) -> dict:
    """``{name: compute(name)}`` for ``names`` in turn (each a (Profile, lowest refit) pair),
    or :class:`ProfilesInterrupted` with the finished profiles about ``fit`` where Ctrl-C or
    SIGTERM stops it (one reaching Python through CasADi included:
    :func:`~morphoshell._runtime.interrupts.interrupted`)."""
    done: dict = {}
    try:
        for name in names:
            done[name] = compute(name)
    except BaseException as exc:
        if not interrupts.interrupted(exc) or isinstance(exc, ProfilesInterrupted):
            raise
        raise ProfilesInterrupted(fit, {n: p for n, (p, _) in done.items()}) from exc
    return done
