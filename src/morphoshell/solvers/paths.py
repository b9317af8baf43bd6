"""Straight paths in parameter space: what continuation and branches follow.

A path is the line p(τ) = p_a + τ (p_b − p_a), τ ∈ [0, 1], between two problems of
one structure, through the parameters that differ (any of h, the cut Σ, the opening
P and the family's parameters).  The family's *neutral* parameters make the
undeformed shell stress-free (:class:`morphoshell.model.profiles.ProfileFamily`):
the path from there to a problem (:func:`neutral_problem`) is the one along which
the physical branch grows out of the stress-free shell.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model.problem import Problem

__all__ = ["ParameterLine", "neutral_problem", "stress_free", "PATH_KEYS"]

#: Parameters of a problem that are not its family's but may move along a path.
PATH_KEYS = ("h", "cut", "opening")


def neutral_problem(problem: Problem) -> Problem | None:
    """``problem`` at its family's stress-free parameters, or None if it has none to move.

    The family's ``neutral`` values (:class:`morphoshell.model.profiles.ProfileFamily`)
    make the undeformed shell stress-free: the start of
    :func:`morphoshell.solvers.continuation.continue_to`.
    """
    neutral = {n: v for n, v in problem.family_obj.neutral.items() if n in problem.params}
    if not neutral or all(problem.params[n] == v for n, v in neutral.items()):
        return None
    return problem.with_updates(**neutral)


def stress_free(problem: Problem) -> bool:
    """Whether ``problem`` is at its family's stress-free (``neutral``) parameters: its exact
    equilibrium is the undeformed shell, of energy 0 (whatever h, the cut and the opening).
    False for a family that lists none."""
    neutral = {n: v for n, v in problem.family_obj.neutral.items() if n in problem.params}
    return bool(neutral) and neutral_problem(problem) is None


def _value(problem: Problem, name: str) -> float:
    return float(problem.params[name] if name in problem.params else getattr(problem, name))


@dataclass(frozen=True)
class ParameterLine:
    """The straight path from one problem's parameters to another's.

    Attributes
    ----------
    source, problem : Problem
        The ends: τ = 0 and τ = 1 (one structure).
    names : tuple of str
        The parameters that differ between them.
    a, b : ndarray, shape (len(names),)
        Their values at the ends.
    """

    source: Problem
    problem: Problem
    names: tuple
    a: np.ndarray
    b: np.ndarray

    @classmethod
    def between(cls, source: Problem, problem: Problem) -> "ParameterLine":
        """From ``source``'s values of the parameters that differ to ``problem``'s.

        Raises
        ------
        ValueError
            The ends differ in structure: a cut (or an opening of a closed
            shell) that is 0 at one end and not at the other would turn a pole
            into a free edge along the path.
        """
        if source.structure != problem.structure:
            name = "cut" if source.cut != problem.cut else "opening"
            raise ValueError(
                f"a path cannot take {name} from {getattr(source, name)!r} to "
                f"{getattr(problem, name)!r}: at 0 the shell ends in a pole, otherwise in a free "
                f"edge (another problem); continue between values > 0")
        names = [n for n in problem.params if problem.params[n] != source.params.get(n)]
        names += [n for n in PATH_KEYS if getattr(problem, n) != getattr(source, n)]
        return cls(source, problem, tuple(names),
                   np.array([_value(source, n) for n in names]),
                   np.array([_value(problem, n) for n in names]))

    @classmethod
    def along(cls, problem: Problem, name: str, to: float) -> "ParameterLine":
        """From ``problem`` to the same problem with the one parameter ``name`` at ``to``.

        Raises
        ------
        ValueError
            ``name`` is not h, cut, opening or a parameter of the family, or
            ``to`` is its present value or an invalid one (the problem's own
            check names it).
        """
        valid = (*PATH_KEYS, *problem.params)
        if name not in valid:
            raise ValueError(f"unknown parameter {name!r} to continue in; valid: {list(valid)}")
        if float(to) == _value(problem, name):
            raise ValueError(f"{name} is already {to!r}: give another value to continue to")
        return cls.between(problem, problem.with_updates(**{name: float(to)}))

    def at(self, tau: float) -> Problem:
        """The problem at τ of the way (τ = 0 and 1: the ends themselves)."""
        if tau == 1:
            return self.problem
        if tau == 0:
            return self.source
        return self.problem.with_updates(**dict(zip(self.names, self.a + tau * (self.b - self.a))))

    def invalid(self, tau: float) -> str | None:
        """Why the parameters at τ make no valid problem (its own check's message), or None.

        Beyond the ends (a step past the path's end, a branch that turns back past its
        start) the parameters are extrapolated and may leave the family's ranges: σ below
        its bound 1e-3 a step past the end of a path to σ = 1e-3 (audit 17)."""
        try:
            self.at(tau)
        except ValueError as exc:
            return str(exc)
        return None

    def clipped(self, tau: float) -> float:
        """τ, or where its parameters leave their ranges (:meth:`invalid`) the path's end
        on its side (0 or 1: the ends are valid problems).

        A state solved a little past an event (a snap's or buckle's descent, up to 0.064 in
        τ past a fold or branch point) lies beyond a path's end at a parameter's bound
        (σ = 1e-3) when the event lies that close before it: it is solved at the end."""
        return tau if self.invalid(tau) is None else min(max(tau, 0.0), 1.0)

    def values(self, tau: float) -> dict[str, float]:
        """The moving parameters' values at τ: the ends' own at τ = 0 and 1, as :meth:`at`
        (a + 1·(b − a) is not b in floating point: h = 0.010000000000000009 for 0.01)."""
        if tau == 1:
            return dict(zip(self.names, self.b.tolist()))
        if tau == 0:
            return dict(zip(self.names, self.a.tolist()))
        return dict(zip(self.names, (self.a + tau * (self.b - self.a)).tolist()))

    @property
    def direction(self) -> np.ndarray:
        """dp/dτ of the parameter vector (``Problem.parameter_vector``).

        Returns
        -------
        ndarray, shape (len(p),)
        """
        return self.problem.parameter_vector() - self.source.parameter_vector()
