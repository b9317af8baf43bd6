"""How a solve ended: the errors every route raises.

:class:`SolverError` carries the solver's status (Ipopt's return status, the
Newton back end's, or a route's own) and the last iterate; its subclass
:class:`NotAMinimumError` is a converged stationary point that is not a strict
minimum.  They sit with the back ends, the lowest layer that raises them.
"""
from __future__ import annotations

from typing import Any

__all__ = ["SolverError", "NotAMinimumError"]


class SolverError(RuntimeError):
    """The solver did not deliver a (stable) equilibrium.

    Attributes
    ----------
    status : str
        Ipopt's return status (or the BVP solver's message).
    last_iterate : Equilibrium or None
        The last iterate, with ``converged=False``, for inspection
        (a :class:`morphoshell.solvers.results.Equilibrium`, defined a layer up).
    """

    def __init__(self, message: str, status: str, last_iterate: Any = None):
        super().__init__(message)
        self.status = status
        self.last_iterate = last_iterate


class NotAMinimumError(SolverError):
    """Ipopt converged to a stationary point whose reduced Hessian is not positive definite."""
