"""Pseudo-arclength continuation: follow a branch of equilibria through its folds.

Natural-parameter continuation (:mod:`morphoshell.solvers.continuation`) steps
the parameter τ of a :class:`~morphoshell.solvers.paths.ParameterLine` and
re-solves; at a *fold* (a limit point, where the branch turns back in τ) there
is no solution beyond, and it stops.  Keller's pseudo-arclength method steps
the arclength s of the branch instead (Keller 1977; Allgower & Georg 2003,
§2.2): from a point w = (u, τ) with unit tangent t, the predictor w + Δs t is
corrected by Newton's method on

    F(u, τ) = 0,     tᵀ(w − w_prev) − Δs = 0,

the bordered KKT system of :mod:`morphoshell.numerics.bordered`, nonsingular
at a simple fold.  The norm weighs x's entries by 1/n_x (their mean square),
capped next to a pole by their share of its area (:func:`norm_weights`), against
τ, and leaves the multipliers out.

At every point the inertia of the reduced Hessian says whether the equilibrium
is stable (a minimum) or how many directions lower its energy.  Events between
two points are located, not just noticed:

* a *fold* where τ's tangent component changes sign: the root of t_τ(s) along
  the step (Brent's method; τ is stationary there, so an arclength located to
  1e-9 puts τ within round-off);
* a *branch point* where the inertia changes without a fold: by bisection on
  s until τ is known to :data:`BRANCH_TOL`.

At a simple branch point another branch crosses.  :meth:`Arclength.switch`
starts on it: the tangents of both branches there span the null space of
[K F_τ], the KKT matrix K being singular with one null vector φ (the
eigenvector of the eigenvalue that changed sign there, by subspace iteration
among those nearest zero); the direction in that null space orthogonal to the
branch's own tangent is the predictor onto the other one, and the corrector's
border row, that direction, keeps Newton's iterations off the branch it left
(Keller 1977, §5; AUTO-07p's and BifurcationKit's branch switching).

Where a branch stalls, :mod:`morphoshell.solvers.crossings` goes past: a
snap-through at a fold, a switch of branches at a branch point.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np

from ..numerics.bordered import BorderedKKT, Inertia
from .direct import DirectSolver
from .paths import ParameterLine
from .results import Equilibrium, SolverStats

__all__ = ["Arclength", "ArcPoint", "NullMode", "Snap", "Switch", "bordered_kkt", "MAX_STEP",
           "MIN_STEP", "EVENT_TOL", "BRANCH_TOL"]

#: Newton iterations of a corrector before the step is retried smaller.
MAX_CORRECTOR = 8
#: Steps in a row that no longer cut the KKT error tenfold (within ``acceptable_tol``) that
#: make a round-off floor, where one that did not cut it at all does alone
#: (:meth:`Arclength._converged`).  One that cut it a few-fold is no floor: a corrector's
#: first step from a predictor next to a branch point, where the state is soft, cut it
#: 7.7-fold (the blister 1e-3 past its first branch point: 1.5e-6 to 2.0e-7, taken at
#: λ = 1, 1.1e-4 of x from the dome, its energy 1.9e-12 C R² above it and the flat state's).
FLOOR_STALLS = 2
#: A step corrected in at most this many iterations lets the next one grow by GROWTH.
EASY = 3
GROWTH = 1.5
#: Largest and smallest arclength step (norm of (x, τ): x by its root mean square).
MAX_STEP = 0.02
MIN_STEP = 1e-7
#: A step whose tangent turns by more than this angle (its cosine below) is retried
#: smaller: it may have jumped to another branch.
MIN_COS = 0.5
#: ... as is one that turns the meridian's tangent ψ somewhere by more than a quarter turn.
MAX_TURN = np.pi / 2
#: Step in p of the bordering column's central difference (relative error ~1e-10).
DIFFERENCE = 1e-5
#: Folds (where τ is stationary) are located to this arclength.
EVENT_TOL = 1e-9
#: Branch points are located to this τ, relatively below τ = BRANCH_SCALE
#: (:meth:`Arclength.locate_change`): switching there needs their zero eigenvalue far
#: below the others, which crowd near zero in thin shells (located to 1e-9, a disc at
#: h = 1e-2 did not switch at its first, at τ = 0.0038; at h = 3e-4 not at its second).
BRANCH_TOL, BRANCH_SCALE = 1e-11, 1e-3
#: Subspace iterations for the null vector of K at a branch point, and the change of its
#: direction at which it has converged: on the blister disc at 800 nodes 5 to 9 iterations
#: bring it below 1e-8 (three brought the 60-node disc's to 1e-13).
NULL_ITERATIONS, NULL_TOL = 20, 1e-8
#: Eigenpairs of K nearest zero iterated together (:meth:`Arclength.null_vector`): a
#: located branch point's eigenvalue is not always the nearest, nor alone there.  The
#: blister disc and the Volvox shell have two soft positive ones that fall like N⁻⁷ with
#: the mesh (blister: 2.9e-8 and 7.6e-8 at 200 nodes, 1.7e-12 and 4.5e-12 at 800, below
#: the located branch point's -5e-11); the next ones are 1e2-1e3 times theirs, so
#: six converge the branch point's at ~1e-3 an iteration.  Ten inverse iterations of one
#: vector, pulled between them, did not converge from 400 nodes and found the soft
#: mode at 800.
MODES = 6
#: The eigenvalue that changed sign at a branch point, over the nearest other of its sign
#: (:attr:`NullMode.crowding`), above which it is not told apart from them: located to
#: :data:`BRANCH_TOL` it is 1e-11..1e-10 of K's scale, the next ones of its sign (a mode
#: that changed sign at an earlier branch point) orders farther.
SEPARATION = 0.1
#: A step whose tangent turns by more than this angle (its cosine below) is retried at
#: half, down to a SMOOTH_SHRINK-th of the largest step (:meth:`Arclength.folds_within`):
#: a pair of folds within one step leaves t_τ's sign as it was, and was missed at
#: --max-step 0.05 (a user audit: the fold shell's folds at λ = 0.54653 and 0.54596,
#: where the steps turned by 30-43°).
SMOOTH_COS = 0.9
SMOOTH_SHRINK = 16
#: At a fold the null vector is the branch's own tangent: a null vector whose part
#: orthogonal to the tangent is smaller than this is no branch point's.
MIN_ORTHOGONAL = 1e-3
#: The radius of the cap round a pole whose area bounds the weights of the norm there
#: (:func:`norm_weights`): the width of the mesh's grading toward a pole
#: (:func:`morphoshell.numerics.mesh.graded_mesh`'s ``pole_width``).
POLE_CAP = 0.01


@dataclass(frozen=True)
class ArcPoint:
    """A point of a branch with its tangent and stability.

    Attributes
    ----------
    tau : float
        The path parameter (:class:`~morphoshell.solvers.paths.ParameterLine`).
    u : ndarray, shape (order.size,)
        (x, λ) in cell order (:class:`~morphoshell.numerics.bordered.BorderedKKT`).
    t : ndarray, shape (k,)
        The unit tangent's u part (over the system's unknowns u[lo:hi]).
    t_tau : float
        The tangent's τ component: positive while τ grows along the branch.
    inertia : Inertia
        Of the reduced Hessian.
    iterations : int
        Newton iterations of its corrector.
    """

    tau: float
    u: np.ndarray
    t: np.ndarray
    t_tau: float
    inertia: Inertia
    iterations: int = 0


@dataclass(frozen=True)
class NullMode:
    """The eigenpair of the KKT matrix that changed sign at a branch point
    (:meth:`Arclength.null_vector`).

    Attributes
    ----------
    vector : ndarray, shape (k,)
        Its unit eigenvector φ over the system's unknowns.
    value : float
        Its eigenvalue (the Ritz value).
    change : float
        How much φ's direction changed in the last iteration (converged below
        :data:`NULL_TOL`).
    crowding : float
        |value| over the nearest other eigenvalue of its sign among the
        :data:`MODES` nearest zero (or, with none, the farthest of them): simple and
        told apart below :data:`SEPARATION`.
    """

    vector: np.ndarray
    value: float
    change: float
    crowding: float


@dataclass(frozen=True)
class Snap:
    """A snap-through: where the branch folded and where the shell landed.

    Attributes
    ----------
    tau : float
        The fold's path parameter.
    tau_after : float
        Where the snapped equilibrium was solved (just past the fold).
    energy_before, energy_after : float
        The energies at the fold and of the snapped equilibrium, at ``tau_after`` (C R²).
    energy_landed : float
        The energy of the snapped equilibrium's branch at the fold's τ: below
        ``energy_before`` by the energy the snap releases (``energy_after``, at another
        τ, may be higher: the energy grows along the path).
    """

    tau: float
    tau_after: float
    energy_before: float
    energy_after: float
    energy_landed: float

    def describe(self) -> str:
        """One line for ``solver.details["path"]``."""
        return (f"snapped through a fold at {self.tau:.6g} of the way (energy there "
                f"{self.energy_before:.6g} -> {self.energy_landed:.6g} C R^2; "
                f"{self.energy_after:.6g} at {self.tau_after:.6g})")

    def to_dict(self) -> dict:
        """Plain numbers (JSON)."""
        return asdict(self)


@dataclass(frozen=True)
class Switch:
    """A switch of branches where the branch lost its stability at a branch point.

    Attributes
    ----------
    tau : float
        The branch point's path parameter.
    tau_after : float
        Where the first point on the other branch was solved.
    direction : float
        Which half of the other branch (:meth:`Arclength.switch`): the first of
        +1, −1 that is stable (at a symmetric pitchfork the other half is its
        mirror image, as good a solution).
    energy_before, energy_after : float
        The energies at the branch point and on the other branch (C R²).
    descent : bool
        Whether the shell got there by minimisation down the branch point's
        unstable mode (:func:`switch_stable`: no half of the other branch
        could be followed from the point), not along the other branch.
    """

    tau: float
    tau_after: float
    direction: float
    energy_before: float
    energy_after: float
    descent: bool = False

    def describe(self) -> str:
        """One line for ``solver.details["path"]``."""
        where = f"at a branch point at {self.tau:.6g} of the way, where the branch lost its " \
                f"stability"
        energy = f"(energy {self.energy_before:.6g} -> {self.energy_after:.6g} C R^2)"
        if self.descent:
            return (f"buckled {where}: minimised from there down its unstable mode "
                    f"({self.direction:+g}) to a stable state at {self.tau_after:.6g} {energy}")
        return f"switched branches {where}, to the stable half {self.direction:+g} of the " \
               f"other, followed to {self.tau_after:.6g} {energy}"

    def to_dict(self) -> dict:
        """Plain numbers (JSON)."""
        return asdict(self)


def bordered_kkt(solver: DirectSolver) -> BorderedKKT:
    """The :class:`BorderedKKT` of ``solver``'s transcription, built once and kept with it."""
    if getattr(solver, "_bordered", None) is None:
        solver._bordered = BorderedKKT(solver.disc)
    return solver._bordered


def norm_weights(kkt: BorderedKKT, points) -> np.ndarray:
    """The weights of the continuation's norm over the system's unknowns u[lo:hi].

    Each of x's n entries weighs 1/n (the mean square), except next to a pole, where
    an entry of a cell weighs at most the cell's share of the pole's cap of radius
    :data:`POLE_CAP` (Δs d / (3S ℓ²), d the cell's distance from the pole): where
    f_s⁰ ≠ f_φ⁰ the stretches there are singular, f_s ~ d^(β−1) (β = 0.13 at f0 = −0.62
    in the anisotropic family), and the mesh, graded toward the pole, puts ever more
    entries ever nearer to it; their mean square grows without bound with the mesh
    (and so does ∫f_s² ds for β < 1/2), their area-weighted mean ∫f_s² ρ ds does not.
    The multipliers weigh nothing; the weights sum to 1.
    """
    S, cells, lo, hi = kkt.order.stages, kkt.order.cells, kkt.order.lo, kkt.order.hi
    nodes = points.s[::S]
    ds, mid = np.diff(nodes), 0.5 * (nodes[1:] + nodes[:-1])
    poles = [end for end, pole in ((nodes[0], kkt.order.start_pole),
                                   (nodes[-1], kkt.order.end_pole)) if pole]
    d = np.min([np.abs(mid - end) for end in poles], axis=0) if poles else np.inf
    cap = np.minimum(1.0 / kkt.x_mask.sum(), ds * d / (3 * S * POLE_CAP ** 2))
    w = np.append(np.repeat(cap, 4 * S), [cap[-1], cap[-1]])[lo:hi] * kkt.x_mask
    return w / w.sum()


def _nearest(mu: np.ndarray, sign: float) -> int:
    """The index of the eigenvalue of sign ``sign`` nearest zero in ``mu`` (of any sign if
    none has it)."""
    ours = np.flatnonzero(sign * mu > 0)
    ours = ours if ours.size else np.arange(mu.size)
    return int(ours[np.argmin(np.abs(mu[ours]))])


def _crowding(mu: np.ndarray, j: int) -> float:
    """|μ_j| over the nearest other of its sign in ``mu``, or over the farthest of ``mu``
    if none (those not iterated lie farther still): :attr:`NullMode.crowding`."""
    others = np.delete(mu, j)
    same = others[np.sign(others) == np.sign(mu[j])]
    return float(abs(mu[j]) / np.min(np.abs(same)) if same.size
                 else abs(mu[j]) / np.max(np.abs(mu)))


class Arclength:
    """Pseudo-arclength continuation of one solver's equilibria along a parameter line.

    Parameters
    ----------
    solver : DirectSolver
        Built for the line's structure.
    line : ParameterLine
        p(τ) = p_a + τ (p_b − p_a).
    anchors : sequence of float
        Mesh anchors, as for :meth:`DirectSolver.solve` (held fixed).
    at : float
        The τ where the mesh is checked to hold (a mesh rebuilt along the line).
    """

    def __init__(self, solver: DirectSolver, line: ParameterLine, anchors=(), at: float = 0.0):
        self.solver, self.line = solver, line
        self.kkt = bordered_kkt(solver)
        d = solver.disc
        self._p0, self._dp = line.source.parameter_vector(), line.direction
        self.q = d.check_anchors(self.parameters(at), anchors)
        self._weight = norm_weights(self.kkt, d.point_data(self.parameters(at), self.q))
        self.tol, self.acceptable_tol = solver.tol, solver.backend.acceptable_tol

    # -- parameters and data ----------------------------------------------------
    def parameters(self, tau: float) -> np.ndarray:
        """p(τ), shape (len(p),)."""
        return self._p0 + tau * self._dp

    def _data(self, tau: float):
        return self.solver.disc.pre_numeric(self.parameters(tau), self.q)

    def _around(self, tau: float) -> tuple:
        """(D(τ + h), D(τ − h), h): the data for the bordering column's central difference
        (:meth:`BorderedKKT.state`), h scaled so that p moves by about 1e-5."""
        h = self.around_parameters(tau)[2]
        return self._data(tau + h), self._data(tau - h), h

    def around_parameters(self, tau: float) -> tuple:
        """(p(τ + h), p(τ − h), h): :meth:`_around`'s parameters
        (:meth:`BorderedKKT.iterate_around`)."""
        h = DIFFERENCE / max(1.0, float(np.max(np.abs(self._dp))))
        return self.parameters(tau + h), self.parameters(tau - h), h

    def norm(self, t: np.ndarray, t_tau: float) -> float:
        """The continuation's norm of (u part over the unknowns, τ part)."""
        return float(np.sqrt(self._weight @ (t * t) + t_tau * t_tau))

    # -- points ---------------------------------------------------------------------
    def start(self, eq: Equilibrium, tau: float, direction: float = 1.0) -> ArcPoint:
        """The branch point of the solution ``eq`` at τ, its tangent pointing to ``direction``
        (+1: growing τ)."""
        u = self.kkt.pack(eq.x, eq.lam_g)
        state = self.kkt.state(u, self._data(tau), self._around(tau))
        t, t_tau = self.kkt.solve(state, np.zeros_like(state.rhs), np.zeros_like(state.rhs),
                                  1.0, 1.0)
        scale = np.copysign(self.norm(t, t_tau), direction * t_tau)
        return ArcPoint(tau, u, t / scale, t_tau / scale, self.kkt.inertia(state))

    def switch(self, point: ArcPoint, direction: float = 1.0, sign: float = -1.0,
               mode: NullMode | None = None) -> ArcPoint:
        """``point``, a located branch point, with the tangent of the other branch through it.

        The null vector φ of the KKT matrix there (:meth:`null_vector`), less
        its part along the point's own tangent (the continuation's norm), as
        the tangent (module docstring): :meth:`correct` from the returned
        point steps onto the other branch.

        Parameters
        ----------
        point : ArcPoint
            A branch point (:meth:`locate_change`), or :meth:`start` at one.
        direction : float
            +1 or −1: the two halves of the other branch (mirror images at a
            pitchfork); +1 the half along which the far end rises (z at the
            shell's end grows: the same half whatever the parameters, so that
            a sweep's rows and solve() agree), or where that does not change,
            the half where the largest entry of φ's shape part grows.
        sign : float
            The sign at ``point`` of the eigenvalue that changed sign there: −1
            where ``point`` has one negative eigenvalue more than the other side
            (the first point past a loss of stability, as :meth:`locate_change`
            gives one), +1 where it has one fewer.
        mode : NullMode, optional
            :meth:`null_vector` at ``point`` of that ``sign``, if already computed (both
            halves of one branch point take the same).

        Returns
        -------
        ArcPoint
            At ``point``'s (u, τ); ``t``, ``t_tau`` the other branch's unit
            tangent.

        Raises
        ------
        ValueError
            The null vector did not converge (no simple zero eigenvalue: not a
            located branch point), other eigenvalues of its sign crowd near it
            (:data:`SEPARATION`), or it is the branch's own tangent (a fold).
        """
        mode = mode or self.null_vector(point, sign)
        if mode.change > NULL_TOL:
            raise ValueError(f"no simple zero eigenvalue at {point.tau:.6g} of the way (the "
                             f"null vector changed by {mode.change:.1e} after "
                             f"{NULL_ITERATIONS} subspace iterations): not a located branch "
                             f"point")
        if mode.crowding > SEPARATION:
            raise ValueError(f"the eigenvalue that changed sign at {point.tau:.6g} of the way "
                             f"({mode.value:.1e}) is not told apart from others of its sign "
                             f"near zero ({abs(mode.value) / mode.crowding:.1e}): eigenvalues "
                             f"crowd near zero on this mesh (fewer nodes may help)")
        v = mode.vector
        along = self._weight @ (v * point.t)
        phi, phi_tau = v - along * point.t, -along * point.t_tau
        size = self.norm(phi, phi_tau)
        if size < MIN_ORTHOGONAL * self.norm(v, 0.0):
            raise ValueError(f"the null vector at {point.tau:.6g} of the way is the branch's "
                             f"own tangent: a fold, not a branch point")
        sign = np.copysign(1.0, direction) * self._rising(point, phi)
        return replace(point, t=sign * phi / size, t_tau=sign * phi_tau / size)

    def _rising(self, point: ArcPoint, phi: np.ndarray) -> float:
        """+1 if the far end's z rises along ``phi`` from ``point`` (central difference),
        else −1; where it does not change, the sign of φ's largest shape entry."""
        step = 1e-6 / max(np.max(np.abs(phi)), 1e-300)
        z = [self.equilibrium(replace(point, u=self.kkt.moved(point.u, e * phi))).z[-1]
             for e in (step, -step)]
        if abs(z[0] - z[1]) > 1e-12:
            return 1.0 if z[0] > z[1] else -1.0
        shape = np.where(self.kkt.x_mask, phi, 0.0)
        return float(np.copysign(1.0, shape[np.argmax(np.abs(shape))]))

    def null_vector(self, point: ArcPoint, sign: float = -1.0) -> NullMode:
        """The eigenpair of the KKT matrix at ``point`` that changed sign there: of the
        :data:`MODES` nearest zero (subspace iteration with the LDLᵀ's solves and a
        Rayleigh–Ritz step, at most :data:`NULL_ITERATIONS`; Saad 2011, §5.2), the nearest
        of sign ``sign`` (:meth:`switch`).  The inertia says which: a soft mode of the
        other sign may lie nearer zero (:data:`MODES`)."""
        state = self.kkt.state(point.u, self._data(point.tau))
        k = len(point.t)
        # (any start with a part along each mode)
        Q = np.linalg.qr(np.sin(np.outer(np.arange(1.0, k + 1.0), np.arange(1.0, MODES + 1.0))))[0]
        v, change = Q[:, 0], np.inf
        for _ in range(NULL_ITERATIONS):
            Q = np.linalg.qr(self.kkt.solve_columns(state, Q))[0]
            T = Q.T @ self.kkt.times(state, Q)
            mu, Y = np.linalg.eigh(0.5 * (T + T.T))
            Q = Q @ Y
            j = _nearest(mu, sign)
            change = min(np.linalg.norm(Q[:, j] - v), np.linalg.norm(Q[:, j] + v))
            v = Q[:, j]
            if change <= NULL_TOL:
                break
        return NullMode(v, float(mu[j]), float(change), _crowding(mu, j))

    def correct(self, prev: ArcPoint, ds: float) -> ArcPoint | None:
        """The point at arclength ``ds`` from ``prev`` along its tangent, or None (no
        convergence)."""
        found = self._corrected(prev, ds)
        return None if found is None else self._point(*found, *self._border(prev))

    def _border(self, prev: ArcPoint) -> tuple[np.ndarray, float]:
        """The border row (c, c_τ) of the steps from ``prev``: its tangent, weighted."""
        return self._weight * prev.t, prev.t_tau

    def _arclength(self, prev: ArcPoint, u: np.ndarray, tau: float) -> float:
        """The arclength coordinate of (u, τ) along ``prev``'s tangent (the border row)."""
        c, c_tau = self._border(prev)
        return float(c @ (self.kkt.free(u) - self.kkt.free(prev.u)) + c_tau * (tau - prev.tau))

    def distance(self, prev: ArcPoint, point: ArcPoint) -> float:
        """The arclength of ``point`` from ``prev`` along ``prev``'s tangent: the ``ds`` of
        :meth:`correct` that gives ``point`` (one found otherwise: :meth:`at_tau`)."""
        return self._arclength(prev, point.u, point.tau)

    def _corrected(self, prev: ArcPoint, ds: float, guess: tuple | None = None):
        """Newton's (u, τ, iterations) at arclength ``ds`` from ``prev``, or None; from
        ``guess`` = (u, τ) if given (after one step at least: a guess within the
        tolerance is still that far off), else from ``prev``'s tangent."""
        c, c_tau = self._border(prev)
        steps = 0 if guess is None else 1
        if guess is None:
            guess = self.kkt.moved(prev.u, ds * prev.t), prev.tau + ds * prev.t_tau

        def row(u, tau):
            return self._arclength(prev, u, tau) - ds
        return self._newton(*guess, c, c_tau, row, steps)

    def first_step(self, start: ArcPoint, ds: float) -> ArcPoint | None:
        """The point at arclength ``ds`` from ``start``, the step halved until the corrector
        converges without turning (:meth:`turned`), or None below :data:`MIN_STEP`."""
        while ds >= MIN_STEP:
            new = self.correct(start, ds)
            if new is not None and not self.turned(start, new):
                return new
            ds /= 2
        return None

    def _point(self, u, tau, iterations, c, c_tau) -> ArcPoint:
        """The converged (u, τ) with its tangent (oriented along the border row c, c_τ) and
        inertia, from the system there."""
        Z = self.kkt.iterate_around(u, self.parameters(tau), self.q,
                                    self.around_parameters(tau))[0]
        Z[:, 0] = 0.0                                   # K⁻¹ 0: the tangent's right-hand side
        t, t_tau = self.kkt.eliminate(Z, c, c_tau, 1.0)
        scale = self.norm(t, t_tau)
        inertia = self.kkt.inertia(self.kkt.state(u, self._data(tau)))
        return ArcPoint(tau, u, t / scale, t_tau / scale, inertia, iterations)

    def stationary(self, x: np.ndarray, tau: float) -> ArcPoint | None:
        """The stationary point of the energy at τ next to the shape ``x`` (this mesh's
        unknowns; multipliers from zero) by Newton's iterations, with its inertia; None
        if they do not converge.  Unlike a solve it does not minimise: a saddle stays a
        saddle, and its inertia says so (another route's shape checked here)."""
        zero = np.zeros(self.kkt.order.hi - self.kkt.order.lo)
        u = self.kkt.pack(x, np.zeros(self.kkt.m))
        found = self._newton(u, tau, zero, 1.0, lambda u, t: t - tau)
        return None if found is None else self._point(*found, zero, 1.0)

    def at_tau(self, prev: ArcPoint, tau: float) -> ArcPoint | None:
        """The point of the branch at the parameter ``tau`` next to ``prev`` (τ fixed: a
        natural-parameter step from ``prev``'s tangent), or None."""
        ds = (tau - prev.tau) / prev.t_tau
        u = self.kkt.moved(prev.u, ds * prev.t)
        zero = np.zeros(len(prev.t))
        found = self._newton(u, tau, zero, 1.0, lambda u, t: t - tau)
        if found is None:
            return None
        return self._point(*found, self._weight * prev.t, prev.t_tau)

    def _newton(self, u, tau, c, c_tau, row, steps: int = 0):
        """Newton's iterations on (F = 0, row = 0): (u, τ, iterations) or None; converged
        only after at least ``steps`` steps."""
        # the bordering column at the predictor, kept through the iterations (a chord in it:
        # the solution does not depend on it)
        last, column, stalls = np.inf, None, 0
        for it in range(MAX_CORRECTOR + 1):
            if it:
                Z, _, error = self.kkt.iterate(u, self.parameters(tau), self.q, column)
            else:
                Z, _, error, column = self.kkt.iterate_around(
                    u, self.parameters(tau), self.q, self.around_parameters(tau))
            residual = row(u, tau)
            stalls = stalls + 1 if self._stalled(error, last) else 0
            if it >= steps and self._converged(error, last, stalls) and abs(residual) <= 1e-12:
                return u, tau, it
            if not np.isfinite(error) or (it >= 2 and error > last) or it == MAX_CORRECTOR:
                return None
            du, dtau = self.kkt.eliminate(Z, c, c_tau, -residual)
            if not np.all(np.isfinite(du)) or not np.isfinite(dtau):
                return None
            u, tau, last = self.kkt.moved(u, du), tau + dtau, error
        return None

    def _stalled(self, error: float, last: float) -> bool:
        """Whether the step from the error ``last`` to ``error`` no longer cut it tenfold,
        within ``acceptable_tol``."""
        return error <= self.acceptable_tol and error > 0.1 * last

    def _converged(self, error: float, last: float, stalls: int) -> bool:
        """Within ``tol``, or within ``acceptable_tol`` at the round-off floor of thin shells:
        a step that no longer cut the error at all (round-off alone moved it), or
        :data:`FLOOR_STALLS` steps in a row that no longer cut it tenfold.  One step that
        cut it a few-fold is no floor: a corrector's first steps from a predictor next to a
        branch point, where the state is soft, do that, and the point taken there was no
        equilibrium to ``tol`` (the Newton back end's test, which takes one, is another)."""
        return error <= self.tol or stalls >= FLOOR_STALLS or stalls > 0 and error >= last

    # -- results ------------------------------------------------------------------------
    def equilibrium(self, point: ArcPoint, stats: SolverStats | None = None) -> Equilibrium:
        """The :class:`Equilibrium` of a branch point (``converged`` True: F = 0 to ``tol``;
        stable or not, as its inertia says)."""
        x, lam = self.kkt.unpack(point.u)
        problem = self.line.at(point.tau)
        p = problem.parameter_vector()
        D = self.solver.disc.cell_data(p, self.q)
        stats = stats or SolverStats("direct", point.iterations, 0.0, "Arclength_Converged",
                                     self.solver.nodes, self.solver.build_seconds,
                                     {"path": "pseudo-arclength continuation"})
        return self.solver.equilibrium(problem, x, lam, p, self.q, D, stats, converged=True)

    def cos(self, prev: ArcPoint, new: ArcPoint) -> float:
        """The cosine of the angle between the two points' tangents (the continuation's norm)."""
        return float(self._weight @ (prev.t * new.t) + prev.t_tau * new.t_tau)

    def turned(self, prev: ArcPoint, new: ArcPoint) -> bool:
        """Whether the step from ``prev`` to ``new`` turned too sharply (a branch jump?)."""
        if self.cos(prev, new) < MIN_COS:
            return True
        layout = self.solver.disc.layout
        dpsi = layout.split(self.kkt.unpack(new.u)[0])[1] - \
            layout.split(self.kkt.unpack(prev.u)[0])[1]
        return bool(np.max(np.abs(dpsi)) > MAX_TURN)

    def folds_within(self, prev: ArcPoint, new: ArcPoint, ds: float, max_step: float) -> bool:
        """Whether the step ``ds`` from ``prev`` to ``new`` may hide a pair of folds, and is
        retried at half (by a walk whose largest step is ``max_step``): it moved τ against
        both its ends' tangents, or turned by more than :data:`SMOOTH_COS`'s angle while it
        may still shrink to a :data:`SMOOTH_SHRINK`-th of the largest (two folds within one
        step cancel in the sign of t_τ, and the step goes back in τ between them, or
        turns)."""
        moved = new.tau - prev.tau
        back = moved * prev.t_tau < 0 and moved * new.t_tau < 0
        return back or self.cos(prev, new) < SMOOTH_COS and ds > max_step / SMOOTH_SHRINK

    # -- events --------------------------------------------------------------------------
    def locate_fold(self, prev: ArcPoint, ds: float) -> ArcPoint:
        """The fold between ``prev`` and the point at arclength ``ds`` from it (where t_τ
        changes sign): the root of t_τ(s) by Brent's method."""
        from scipy.optimize import brentq

        found: dict[float, ArcPoint] = {}

        def t_tau(s: float) -> float:
            point = self.correct(prev, s)
            if point is None:
                raise _NoPoint(s)
            found[s] = point
            return point.t_tau
        try:
            s = brentq(t_tau, 0.0, ds, xtol=EVENT_TOL, rtol=4 * np.finfo(float).eps)
        except _NoPoint:
            # a corrector failed inside: the best point of the bracket so far (its ends were
            # corrected before Brent's first inner step, so there is one); the failed s
            # itself has no point, and correcting it again fails again
            return min(found.values(), key=lambda point: abs(point.t_tau))
        return found.get(s) or self.correct(prev, s)

    def locate_change(self, prev: ArcPoint, ds: float, new: ArcPoint | None = None) -> ArcPoint:
        """The point between ``prev`` and arclength ``ds`` where the inertia changes (a
        branch point): bisection on s until τ is known to :data:`BRANCH_TOL`, relatively
        below τ = :data:`BRANCH_SCALE` (a thin shell's first branch point lies at τ ∝ h²,
        4e-7 for a disc at h = 1e-4).  ``new``, the point at ``ds`` if known, starts the
        trials nearer (:meth:`_bisect_change`)."""
        return self._bisect_change(prev, ds, new)[0]

    def locate_changes(self, prev: ArcPoint, new: ArcPoint, ds: float) -> list[ArcPoint]:
        """Every branch point between ``prev`` and ``new`` (arclength ``ds``): one per
        change of the number of negative eigenvalues, each located from the last (a thin
        shell's step can pass several: a disc at h = 1e-3 passes ten in one)."""
        out, left = [], ds
        # (at most one located point per eigenvalue changing sign, twice for a count that
        # goes back and forth)
        for _ in range(2 * abs(new.inertia.negative - prev.inertia.negative) + 2):
            if prev.inertia.negative == new.inertia.negative or left <= 0:
                break
            change, s = self._bisect_change(prev, left, new)
            if change is None or change.inertia.negative == prev.inertia.negative:
                break
            out.append(change)
            prev, left = change, left - s
        return out

    def _bisect_change(self, prev: ArcPoint, ds: float,
                       new: ArcPoint | None = None) -> tuple[ArcPoint | None, float]:
        """(the first point past the change of inertia within arclength ``ds`` of ``prev``,
        its arclength from ``prev``) (:meth:`locate_change`).

        A trial needs only its inertia: the tangent is solved for the located point
        alone.  Once a point beyond the change is known, each trial starts from the
        line between the bracket's two points, whose error shrinks with the bracket's
        square: the late trials converge at their first evaluation.
        """
        lo, hi = 0.0, ds
        ends = {"lo": (prev.u, prev.tau), "hi": None if new is None else (new.u, new.tau)}
        found, tol = None, BRANCH_TOL * min(1.0, abs(prev.tau) / BRANCH_SCALE)
        while (hi - lo) * max(abs(prev.t_tau), 1e-3) > tol and hi - lo > 1e-14:
            mid = 0.5 * (lo + hi)
            trial = self._trial(prev, mid, ends)
            if trial is None:
                break
            if trial[3].negative == prev.inertia.negative:
                lo, ends["lo"] = mid, trial[:2]
            else:
                hi, ends["hi"], found = mid, trial[:2], trial
        if found is None:
            return self.correct(prev, hi), hi
        return self._point(*found[:3], *self._border(prev)), hi

    def _trial(self, prev: ArcPoint, s: float, ends: dict) -> tuple | None:
        """(u, τ, iterations, inertia) of the point at arclength ``s`` from ``prev``, from
        the line between the bracket's ends (where both are known) or ``prev``'s tangent;
        None where neither converges."""
        found = None
        if ends["hi"] is not None:
            a, b = ends["lo"], ends["hi"]
            sa, sb = (self._arclength(prev, *end) for end in (a, b))
            w = (s - sa) / (sb - sa) if sb != sa else 0.5
            guess = (a[0] + w * (b[0] - a[0]), a[1] + w * (b[1] - a[1]))
            found = self._corrected(prev, s, guess)
        found = found or self._corrected(prev, s)
        if found is None:
            return None
        u, tau, _ = found
        return (*found, self.kkt.inertia(self.kkt.state(u, self._data(tau))))


class _NoPoint(Exception):
    def __init__(self, s: float):
        self.s = s
