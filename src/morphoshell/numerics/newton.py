"""Newton back end: Newton's method on the KKT conditions, certified by its own LDLᵀ.

Warm starts first, and cold starts under stricter rules ("Cold starts" below).

A warm re-solve (continuation, fitting, sweeps) starts next to the solution:
Newton's method on the KKT conditions ∇f + Jᵀλ = 0, g = 0 converges in two or
three full steps, and Ipopt's fixed cost per call (set-up, MUMPS' analysis, a
separate factorisation for the minimum certificate) was most of a warm solve.
This back end takes those steps itself with one sparse LDLᵀ per iterate
(CasADi's ``ldl``, symbolic analysis once), and reads the minimum certificate off the factorisation
*at the returned point*.  It returns None whenever it cannot certify a converged minimum (no
convergence within a few steps, a growing residual, the wrong inertia), and
the caller falls back to Ipopt: it can only make a warm solve faster, never
change what is accepted.

The linear system.  With weights W > 0 per constraint (as in
:meth:`morphoshell.numerics.ipopt.IpoptBackend.penalised_certificate`) and
M = ∇²ℒ + Jᵀ W J, the Newton step (dx, dλ) solves

    [ M   Jᵀ ] [dx]     [ ∇f + Jᵀλ + Jᵀ W g ]
    [ J  −Δ  ] [dλ] = − [ g                  ],     Δ = ε W⁻¹

(assembled per cell by the transcription), which for Δ = 0 is exactly
Newton's KKT system (J dx = −g turns Jᵀ W J dx into −Jᵀ W g); ε = 1e-8
perturbs the step by a relative 1e-8, invisible in Newton's convergence.  The matrix is
quasi-definite when M is positive definite, so an LDLᵀ factorisation without pivoting exists in any
ordering and is stable (Vanderbei 1995).  By Sylvester's law its inertia is that of
M + Jᵀ Δ⁻¹ J plus m negative pivots: exactly m negative pivots and full rank
mean vᵀ ∇²ℒ v > 0 for every v ≠ 0 with Jv = 0, a strict local minimum
(Nocedal & Wright, Thm 12.6).  A saddle can never pass this test.

The chord step.  From a warm start (x_w, λ_w), the solution of parameters
p_w, the first step solves the system K_w of that point (its own parameters,
ρ = 1) with the right-hand side at the new parameters: a chord (simplified
Newton) step, whose error is that of a Newton step times the distance
between the two parameter sets (Deuflhard 2004, §2.1.4).  K_w is usually
at hand: the certificate of the solve that produced the warm start, or of
an earlier warm start from the same point (two are kept).  The step then
needs no Hessian.  K_w depends on the warm start alone, never on what was
solved before, so a result is the same to the last bit whether K_w was
kept or built again (campaigns resumed in another process, workers that
solved other things).  A chord step that does not cut the KKT error by
:data:`CHORD_GAIN`, or after which Newton's steps do not end certified,
is dropped: Newton starts again from the warm start, so the chord step
never turns a warm start that Newton's steps certify into an Ipopt solve
(a weak chord step had led the next steps off the branch near folds).
The chord step, Newton's step after it and the system where that lands
are one call (a call from Python has a fixed cost, whatever its size); the
tests above are made afterwards, on the errors the call returns for each
of the three points.

Factorisations.  ``Linsol.solve(A, b)`` factorises A itself (a solve with
2A after a factorisation of A returns half the solution), so a step is one
solve, and only the returned point is factorised apart, for its inertia:
three factorisations for two steps, not one before every solve.  A solve's
factorisation is not the one ``neig`` and ``rank`` read (both give 0 after a
``solve``), so the inertia is always read after an ``nfact``.  A warm solve's
solves run inside CasADi Functions, with the update and the norms the floor's
test needs: from Python, a solve's conversions cost as much as its arithmetic.

Cold starts.  From the undeformed shell (no multipliers), Newton's steps are
taken only while they are the steps Ipopt would take unmodified: each step's
system must have the inertia of a minimum (Ipopt would otherwise add δ_w I to
the Hessian, a different step) and each step must reduce the KKT error, or
Ipopt solves from the start.  On small meshes this converges in no more
steps than Ipopt's, to the same solution, and Ipopt's set-up is never built (where a
shell has several minima near the start, Ipopt's line search can take it to another:
tests/test_fuzz.py asks that Newton's steps never end at a higher one).

The round-off floor.  Thin shells cannot reach ``tol``: the dual residual
stops at a floor set by round-off (of order 1e-8 for h = 1e-4), and a solve
used to end, as Ipopt's "acceptable" exit does, only after a step that no
longer cut the error tenfold, a step that showed nothing but the floor.  A step in Newton's
quadratic phase, one that cut the error a thousandfold (:data:`FLOOR_GAIN`), lands far below the
floor, so what is left is round-off; if Newton's correction there is negligible
too (below :data:`STEP_TOL` of x), the iterate is converged.  The correction
is the next step's solve, which is needed anyway if it is not negligible.  The residual of a start
alone is never taken for the floor: at h = 1e-4 a parameter change may move
the residual hardly above the floor and the solution by very little, which is
still a change to follow (continuation).  The test depends on the iterate
and its step alone.
"""
from __future__ import annotations

import time
from contextlib import contextmanager
from typing import Iterator

import casadi as ca
import numpy as np

from .ipopt import BackendResult
from .status import NEWTON_CONVERGED

__all__ = ["NewtonBackend", "S_MAX", "CHORD_GAIN", "FLOOR_GAIN", "STEP_TOL",
           "THIRD_STEP_CELLS"]

#: A chord step is kept only if it cuts the KKT error at least this much (a warm start's
#: Newton step cuts it a hundredfold or more); a weaker one, from a system far from the
#: start, could lead the next steps away from the branch.
CHORD_GAIN = 0.1

#: An acceptable iterate reached by a step that cut the error at least 1/FLOOR_GAIN-fold,
#: whose Newton correction is below STEP_TOL relative to max(1, ‖x‖∞), is converged
#: (Newton at a round-off floor of its residual, where the corrections are a few 1e-14
#: to 1e-13 of x).
FLOOR_GAIN = 1e-3
STEP_TOL = 1e-12

#: A warm start's first call (:attr:`NewtonBackend._chord_start`) also takes the third step
#: on meshes of up to this many cells: there a step's arithmetic costs less than a call of
#: its own, which it saves whenever the warm start does not end at the second step
#: (tuned by scripts/bench_equilibrium.py: warm re-solves).
THIRD_STEP_CELLS = 100

#: Ipopt's ``s_max``: the dual infeasibility is scaled down by ‖λ‖₁/(n + m)/s_max when larger.
S_MAX = 100.0


class NewtonBackend:
    """Certified Newton iterations on the KKT conditions of ``nlp`` (see the module docstring).

    Parameters
    ----------
    nlp : object
        With the CasADi symbol ``x``, ``constraints``, the ``cell_order`` u of
        (x, λ) in which the system is assembled and its ``cell_assembly``
        (:mod:`morphoshell.numerics.cell_order`), ``kkt_pack(x, λ)`` giving u, and
        methods ``newton_system()``, the
        Function ``(u, D, ρ) -> (K, rhs, ‖∇f + Jᵀλ‖∞, ‖g‖∞, ‖λ‖₁, W)`` of
        the system above (its unknowns u[lo:hi]), and ``newton_rhs()``,
        ``(u, D, W) -> (rhs, …, ‖λ‖₁)``
        (:meth:`morphoshell.numerics.discretisation.Discretisation.newton_system`).
    tol : float
        Converged when max(‖∇f + Jᵀλ‖∞ / s_d, ‖g‖∞) ≤ tol, Ipopt's
        unscaled KKT error (s_d as in Ipopt: max(1, ‖λ‖₁/((n + m) s_max))).
    acceptable_tol : float
        Also converged when the error is below this, ‖g‖∞ ≤ 1e-10 and a step
        no longer reduced it tenfold, or reached by a step that reduced it
        1/FLOOR_GAIN-fold and with a Newton correction below STEP_TOL
        (Newton at its round-off floor: Ipopt's "acceptable" exit, which
        thin shells need).
    max_iter : int
        Newton steps before giving up (warm starts need 2–3).
    """

    def __init__(self, nlp, *, tol: float, acceptable_tol: float, max_iter: int = 8):
        self.tol, self.acceptable_tol, self.max_iter = float(tol), float(acceptable_tol), max_iter
        self._nlp = nlp
        self._system = nlp.newton_system()
        self.n, self.m = nlp.x.shape[0], nlp.constraints
        self._order = nlp.cell_order
        self._x_mask = nlp.cell_assembly.x_mask
        self._linsol = ca.Linsol("newton", "ldl", self._system.sparsity_out(0))
        self._kept = [_System(), _System()]
        self._clock = 0
        self._fused: dict = {}

    @property
    def _step(self) -> ca.Function:
        """A step in one call (the system, its solve and the update): faster than the
        three calls, the same bits; built on first use (cold starts do not use it)."""
        if "step" not in self._fused:
            u, D = self._symbols()
            K, rhs, *errors, _ = self._system(u, D, 1.0)
            self._fused["step"] = ca.Function("newton_step", [u, D],
                                              [self._advance(u, K, rhs), *errors])
        return self._fused["step"]

    @property
    def _solve_step(self) -> ca.Function:
        """``(u, K, rhs) -> (u + du, ‖du‖∞, ‖u‖∞)`` with du[lo:hi] = K⁻¹ rhs, both norms over x
        only: a step with a system at hand, in one call, in place of a ``Linsol.solve``,
        the update and two norms, each called from Python."""
        if "solve" not in self._fused:
            u = ca.MX.sym("u", self._system.sparsity_in(0))
            K = ca.MX.sym("K", self._system.sparsity_out(0))
            rhs = ca.MX.sym("rhs", self._system.sparsity_out(1))
            u_next, step = self._advance(u, K, rhs, with_step=True)
            self._fused["solve"] = ca.Function("newton_solve_step", [u, K, rhs],
                                               [u_next, *self._norms(u, step)])
        return self._fused["solve"]

    def _norms(self, u, step) -> tuple:
        """(‖du‖∞, ‖u‖∞) over x of a step du[lo:hi] from u (CasADi matrices or expressions)."""
        mask = self._x_mask
        return (ca.mmax(ca.fabs(step * mask)),
                ca.mmax(ca.fabs(u[self._order.lo:self._order.hi] * mask)))

    def _python_step(self, u, K, rhs, norms: bool = True) -> tuple:
        """:attr:`_solve_step` by a ``Linsol.solve`` and CasADi operations from Python (the
        norms only if asked for)."""
        step = self._linsol.solve(K, rhs)
        return u + self._order.padded(step), *(self._norms(u, step) if norms else (None, None))

    @property
    def _chord_start(self) -> ca.Function:
        """``(u₀, D, K_w, W_w) -> (u₁, u₂, errors, K, W, u₃, ‖du‖∞, ‖u₂‖∞)``: a warm start's
        first three evaluations in one call: the chord step with the warm start's
        system K_w, W_w, Newton's step from where it lands, and the system K, W at u₂;
        ``errors`` holds (‖∇f + Jᵀλ‖∞, ‖g‖∞, ‖λ‖₁) at u₀, u₁ and u₂ in turn.  On up to
        :data:`THIRD_STEP_CELLS` cells also Newton's step from u₂ (u₃, with the norms over
        x of :attr:`_solve_step`); on more, K's right-hand side in place of u₃ and no norms.
        Each call from Python has a fixed cost whatever its size, a good part of a warm
        re-solve on a small mesh.  A warm start always takes the first two steps; the
        third unless u₂ meets ``tol`` (at the round-off floor its correction decides),
        which is why the third is fused only where it is cheap."""
        if "chord" not in self._fused:
            u, D = self._symbols()
            K_w = ca.MX.sym("K_w", self._system.sparsity_out(0))
            w = ca.MX.sym("w", self.m)
            rhs, *errors0 = self._nlp.newton_rhs()(u, D, w)
            u1 = self._advance(u, K_w, rhs)
            K, rhs, *errors1, _ = self._system(u1, D, 1.0)
            u2 = self._advance(u1, K, rhs)
            K, rhs, *errors2, w2 = self._system(u2, D, 1.0)
            third = [rhs]
            if self._order.cells <= THIRD_STEP_CELLS:
                u3, step = self._advance(u2, K, rhs, with_step=True)
                third = [u3, *self._norms(u2, step)]
            self._fused["chord"] = ca.Function(
                "newton_chord_start", [u, D, K_w, w],
                [u1, u2, ca.vertcat(*errors0, *errors1, *errors2), K, w2, *third])
        return self._fused["chord"]

    def _advance(self, u, K, rhs, with_step: bool = False):
        """u + du with du[lo:hi] = K⁻¹ rhs (LDLᵀ), as CasADi expressions (and du[lo:hi])."""
        # (the backend's own LDLᵀ solver: ca.solve would make and analyse another, in the
        # first warm solve)
        step = self._linsol.solve(K, rhs, False)
        u_next = u + self._order.padded(step)
        return (u_next, step) if with_step else u_next

    def _symbols(self) -> tuple:
        return tuple(ca.MX.sym(name, self._system.sparsity_in(i))
                     for i, name in enumerate(("u", "D")))

    def solve(self, x0: np.ndarray, D, lam_g0: np.ndarray, at: tuple = (),
              origin: tuple | None = None, cold: bool = False) -> BackendResult | None:
        """Newton from (x0, λ0) at parameters D (a ``casadi.DM``); None if not certified.

        Parameters
        ----------
        x0, lam_g0 : ndarray
            The start, (n,) and (m,).
        D : casadi.DM
            The cell data of the parameters to solve for.
        at : tuple of ndarray
            Those parameters (p, q): with them the system at the result is
            kept for a chord step from it.
        origin : tuple, optional
            ``(p_w, q_w, data)`` when (x0, λ0) solves the parameters p_w, q_w
            (a warm start), with ``data()`` their cell data: the first step is
            then a chord step with that point's system.
        cold : bool
            (x0, λ0) is not near a solution (the undeformed shell): every
            step must be one Ipopt would take unmodified, a Newton step whose
            system has the inertia of a minimum, and must reduce the KKT error
            (see the module docstring, "Cold starts").

        Returns
        -------
        BackendResult or None
            None if there is no converged, certified minimum within
            ``max_iter`` steps (the caller then runs Ipopt).  Its
            ``details["stability"]`` names the certificate: ``"newton_ldl"``,
            or ``"newton_ldl_rho100"`` when the weights W had to be raised;
            ``details["chord"]`` whether the first step was a chord step.
        """
        t0 = time.perf_counter()
        chord = None if origin is None else self._chord(x0, lam_g0, origin)
        if chord is not None:
            uk = chord.start              # (kept: converting x, λ again costs a warm solve)
        else:
            uk = self._point(x0, lam_g0)
        res, system = NotImplemented, None
        if chord is not None:
            res, system = self._iterate(uk, D, t0, chord)
        if res is NotImplemented:
            res, system = self._iterate(uk, D, t0, cold=cold)
        if res is not None and at and system is not None:
            self._keep((res.x, res.lam_g, *at), *system)
        return res

    def _chord(self, x0, lam0, origin) -> "_System":
        """The system (K, W) at the warm start ``origin``: kept, or evaluated now."""
        p_w, q_w, data = origin
        key = (np.asarray(x0), np.asarray(lam0), np.asarray(p_w), np.asarray(q_w))
        for kept in self._kept:
            if kept.matches(key):
                self._clock += 1
                kept.used = self._clock
                return kept
        uk = self._point(key[0], key[1])
        K, *_, w = self._system(uk, data(), 1.0)
        return self._keep(key, K, w, uk)

    @contextmanager
    def unchanged(self) -> Iterator[None]:
        """Solves within leave the systems kept for chord steps as they were (and their
        order of use): a check's solve (a warm step solved back,
        :func:`morphoshell.solvers.continuation.left_branch`) must not change which chord
        step the next solve takes, its iterations or its last bits (a sweep's rows are
        equal to the bit whatever the checks)."""
        saved = [tuple(getattr(k, a) for a in _System.__slots__) for k in self._kept]
        clock = self._clock
        try:
            yield
        finally:
            for kept, values in zip(self._kept, saved):
                for name, value in zip(_System.__slots__, values):
                    setattr(kept, name, value)
            self._clock = clock

    def _point(self, x, lam) -> ca.DM:
        """u (cell order, a DM) of (x, λ)."""
        # (lists convert to DM faster than NumPy arrays)
        return ca.DM(self._nlp.kkt_pack(np.asarray(x, dtype=float),
                                        np.asarray(lam, dtype=float)).tolist())

    def _keep(self, key: tuple, K, w, start) -> "_System":
        """Keep (K, W) at ``key`` = (x, λ, p, q), with its u as ``start`` (DM), in place of
        the least recently used."""
        kept = min(self._kept, key=lambda k: k.used)
        self._clock += 1
        kept.key, kept.K, kept.w, kept.start, kept.used = (
            tuple(np.array(v, dtype=float) for v in key), K, w, start, self._clock)
        return kept

    def _error(self, dual, primal, l1) -> tuple[float, float]:
        """(KKT error, ‖g‖∞): Ipopt's unscaled error, the dual part scaled by s_d."""
        n, m, primal = self.n, self.m, float(primal)
        return max(float(dual) / max(1.0, float(l1) / ((n + m) * S_MAX)), primal), primal

    def _iterate(self, uk, D, t0: float, chord: "_System | None" = None,
                 cold: bool = False):
        """Newton's iterations from uk (cell order), the first a chord step with the system
        ``chord``.

        Returns (result, system): the BackendResult and, to keep for a chord step
        from it, (K, W, u) at ρ = 1 (None if certified only at
        ρ = 100), or (None, None) when Newton does not end certified.
        With a chord step, NotImplemented instead of None (and if the start
        needs no step): the caller starts again without it, so that the chord
        step never turns a warm start that Newton's steps certify into an Ipopt
        solve (a weak chord step had led the next steps off the branch near
        folds).  ``cold``: every step's system is factorised apart and must
        have the inertia of a minimum, and every step must reduce the error.
        """
        last = np.inf
        # (a cold start's solver is new: building the one-call step would cost it more
        # than the calls save)
        solve_step = self._python_step if cold else self._solve_step
        fail = (None, None) if chord is None else (NotImplemented, None)
        start = None if chord is None else self._chord_evaluations(uk, D, chord)
        for it in range(self.max_iter + 1):
            fused = _fused(it, cold, chord is not None)
            point = self._evaluate(it, uk, D, start, fused)
            err, primal = self._error(point.dual, point.primal, point.l1)
            acceptable, done = self._converged(err, primal, last)
            if chord is not None and _chord_rejected(it, done, err, last):
                return NotImplemented, None
            if not (done or fused) and _floor_reached(acceptable, err, last):
                done = self._negligible_correction(point, uk, solve_step)
            if done:
                return self._finish(point, uk, D, it, t0, chord, fused) or fail
            if self._stalled(it, err, last, cold) or cold and not self._cold_system(point, uk, D):
                return fail
            uk, last = self._next_iterate(point, uk, cold), err
        return fail

    def _chord_evaluations(self, uk, D, chord: "_System") -> list["_Point"]:
        """A warm start's first three evaluations, from one call of :attr:`_chord_start`:
        the chord step to u₁, Newton's step to u₂, and the system at u₂ (with its step
        to u₃ on small meshes, else with its right-hand side)."""
        u1, u2, errors, K2, w2, *third = self._chord_start(uk, D, chord.K, chord.w)
        e = errors.nonzeros()
        if len(third) == 3:            # the system at u₂ with its step
            rhs, (u3, du, size) = None, third
        else:                          # or with its right-hand side
            rhs, u3, du, size = third[0], None, None, None
        return [_Point(*e[0:3], u_next=u1), _Point(*e[3:6], u_next=u2),
                _Point(*e[6:9], K=K2, rhs=rhs, w=w2, u_next=u3, du=du, size=size)]

    def _evaluate(self, it: int, uk, D, start: list | None, fused: bool) -> "_Point":
        """What iteration ``it`` knows at uk: a warm start's evaluations from the chord
        call (``start``); a fused step (:attr:`_step`), which returns the next iterate
        but no system; or the system at uk, whose step is taken later."""
        if start and it <= 2:
            return start[it]
        if fused:
            u_next, dual, primal, l1 = self._step(uk, D)
            return _Point(dual, primal, l1, u_next=u_next)
        K, rhs, dual, primal, l1, w = self._system(uk, D, 1.0)
        return _Point(dual, primal, l1, K=K, rhs=rhs, w=w)

    def _converged(self, err: float, primal: float, last: float) -> tuple[bool, bool]:
        """(acceptable, done): the error within ``acceptable_tol`` with ‖g‖∞ ≤ 1e-10; done
        within ``tol``, or acceptable after a step that no longer cut the error tenfold."""
        acceptable = err <= self.acceptable_tol and primal <= 1e-10
        return acceptable, err <= self.tol or acceptable and err > 0.1 * last

    @staticmethod
    def _negligible_correction(point: "_Point", uk, solve_step) -> bool:
        """At a round-off floor, whether Newton's correction there is negligible (if it is
        not, it is the next step, kept in ``point``)."""
        if point.u_next is None:
            point.u_next, point.du, point.size = solve_step(uk, point.K, point.rhs)
        return float(point.du) <= STEP_TOL * max(1.0, float(point.size))

    def _stalled(self, it: int, err: float, last: float, cold: bool) -> bool:
        """Not converging: Ipopt's globalisation is needed (a non-finite error, a growing
        one after the first steps, or the last step taken)."""
        return (not np.isfinite(err) or (it >= (1 if cold else 2) and err > last)
                or it == self.max_iter)

    def _cold_system(self, point: "_Point", uk, D) -> bool:
        """A cold step's system with the inertia of a minimum, at ρ = 1 or else ρ = 100 (its
        step then taken with that system); False if neither has it: Ipopt would correct
        the inertia, its step and not Newton's."""
        found = self._minimum(point.K, point.rhs, uk, D)
        if found is None:
            return False
        if found[2] != 1:          # (a floor test's step is ρ = 1's)
            point.K, point.rhs, point.u_next = *found[:2], None
        return True

    def _next_iterate(self, point: "_Point", uk, cold: bool):
        """The iterate after uk: the step ``point`` holds, or a solve with its system (which
        factorises K)."""
        if point.u_next is not None:
            return point.u_next
        if cold:
            return self._python_step(uk, point.K, point.rhs, norms=False)[0]
        return self._solve_step(uk, point.K, point.rhs)[0]

    def _finish(self, point: "_Point", uk, D, it: int, t0: float, chord, fused: bool):
        """(BackendResult, system to keep) at the converged uk, or None if its system does
        not certify a minimum."""
        K, w = point.K, point.w
        if fused:        # (rare: its step is not needed)
            K, *_, w = self._system(uk, D, 1.0)
        how = self._certify(K, uk, D)
        if how is None:
            return None
        # kept for a chord step from here: ρ = 1's system only, as _chord builds
        system = (K, w, uk) if how == "newton_ldl" else None
        # (np.fromiter reads a DM's nonzeros faster than np.array)
        u = np.fromiter(ca.densify(uk).nonzeros(), float, uk.numel())
        return BackendResult(*self._order.unpack(u),
                             NEWTON_CONVERGED, it, time.perf_counter() - t0, True,
                             {"stability": how, "inertia_correction": 0.0,
                              "route": "newton", "chord": chord is not None}), system

    def _minimum(self, K, rhs, u, D) -> tuple | None:
        """(K, rhs, ρ): the system K given (ρ = 1), or else the system at ρ = 100, whichever
        first has the inertia of a minimum, factorised; None if neither has."""
        lin = self._linsol
        for rho in (1.0, 100.0):
            if rho > 1:
                K, rhs = self._system(u, D, rho)[:2]
            lin.nfact(K)
            if lin.neig(K) == self.m and lin.rank(K) == self.n + self.m:
                return K, rhs, rho
        return None

    def _certify(self, K, u, D) -> str | None:
        """The certificate of the returned point's system K, trying ρ = 100 if ρ = 1 fails."""
        found = self._minimum(K, None, u, D)
        return None if found is None else "newton_ldl" if found[2] == 1 else "newton_ldl_rho100"


class _System:
    """The Newton system K (ρ = 1) and weights W of the point ``key`` = (x, λ, p, q);
    ``start`` its u (cell order) as a CasADi matrix."""

    __slots__ = ("key", "K", "w", "start", "used")

    def __init__(self):
        self.key, self.K, self.w, self.start, self.used = None, None, None, None, 0

    def matches(self, key: tuple) -> bool:
        return self.key is not None and all(
            a.shape == b.shape and np.array_equal(a, b) for a, b in zip(self.key, key))


class _Point:
    """What one iteration knows at its iterate: the KKT errors (‖∇f + Jᵀλ‖∞, ‖g‖∞, ‖λ‖₁),
    the system K, rhs and weights W there (None after a fused step), and the next iterate
    with the norms of its step over x, where already taken."""

    __slots__ = ("dual", "primal", "l1", "K", "rhs", "w", "u_next", "du", "size")

    def __init__(self, dual, primal, l1, K=None, rhs=None, w=None, u_next=None, du=None,
                 size=None):
        self.dual, self.primal, self.l1 = dual, primal, l1
        self.K, self.rhs, self.w = K, rhs, w
        self.u_next, self.du, self.size = u_next, du, size


def _fused(it: int, cold: bool, chord: bool) -> bool:
    """Whether iteration ``it`` is a fused step (:attr:`NewtonBackend._step`): a warm start's
    first two steps are not the last, so no system is returned for them (with a chord step,
    they come from the chord call); later iterates, where Newton usually stops, give K for
    the certificate."""
    return not cold and it <= 1 and (it == 1 or chord)


def _chord_rejected(it: int, done: bool, err: float, last: float) -> bool:
    """The chord step is dropped if the start needs no step, or if it did not cut the KKT
    error by :data:`CHORD_GAIN`."""
    return it == 0 and done or it == 1 and not err <= CHORD_GAIN * last


def _floor_reached(acceptable: bool, err: float, last: float) -> bool:
    """An acceptable iterate reached by a step that cut the error 1/FLOOR_GAIN-fold (never
    the start): what is left may be round-off (module docstring, "The round-off floor")."""
    return acceptable and err <= FLOOR_GAIN * last < np.inf
