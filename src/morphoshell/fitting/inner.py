"""The inner problem of a fit: the model's midline at θ, its misfit and their derivatives.

The fit energy (paper, Supplementary, "Fitting of the morphoelastic theory to
the average cell sheet midlines of Volvox inversion", "Fitting methods and
details")

    E_fit = { Σᵢ [(rᵢ − Rᵢ)² + (zᵢ − Zᵢ)²] }^½,   i = 1 … N_fit = 100,

compares points equally spaced in arclength along the data (Rᵢ, Zᵢ) and along
the model's midline (rᵢ, zᵢ), posterior pole at the origin, axis along z.  The
model's midline is an *equilibrium*: :class:`InnerProblem` solves it at each θ,
warm-started from the nearest state solved so far so that the solves follow
one branch of equilibria, and gives the residuals and their exact Jacobian
(implicit function theorem, :mod:`morphoshell.solvers.parametric`).
:func:`model_midline` and :func:`synthetic_midline` sample a solution's
midline the same way.

Lengths in units of R.
"""
from __future__ import annotations

import numpy as np

from ..model.problem import Problem
from ..numerics.mesh import mesh_spec
from ..solvers.continuation import continue_between, continue_to
from ..solvers.direct import DirectSolver, solver_of
from ..solvers.observables import midline
from ..solvers.options import check_guess
from ..solvers.parametric import parametric
from ..solvers.refinement import solve_from
from ..solvers.results import Equilibrium, SolverError
from .spec import FitSpec

__all__ = ["InnerProblem", "model_midline", "synthetic_midline", "N_FIT", "NEAR", "ARCHIVE"]

#: Points of the fit energy (documentation: "Problems and families", Volvox).
N_FIT = 100
#: A solved state this near (max over θ of |Δθ|/bound width) is warm-started from;
#: farther, the inner solve continues from it (one branch of equilibria).
NEAR = 0.02
#: Inner states kept as starting points.
ARCHIVE = 64
#: A trial point whose solve fails on a mesh whose knots lie more than this many knot
#: widths from the trial's breakpoints is tried once more on a mesh of its own
#: (:meth:`InnerProblem.solve`): the graded cells then no longer sit at the breakpoints.
STALE_MESH = 2.0


def model_midline(eq: Equilibrium, n: int = N_FIT) -> np.ndarray:
    """Points (r, z) of a direct solution's midline, equally spaced in deformed arclength.

    The model's fit points (rᵢ, zᵢ) of the fit energy (paper, Supplementary,
    "Fitting of the morphoelastic theory to the average cell sheet midlines
    of Volvox inversion", "Fitting methods and details").  z is counted from
    the first point (the posterior pole): the gauge of traced midlines.

    Parameters
    ----------
    eq : Equilibrium
        A solution of :class:`morphoshell.solvers.direct.DirectSolver`.
    n : int
        Points (the paper's N_fit, :data:`N_FIT`).

    Returns
    -------
    ndarray, shape (n, 2)
        r and z, from the posterior pole to the rim.

    Raises
    ------
    ValueError
        ``eq`` is not a direct solution.
    """
    from ..solvers.direct import solver_of
    solver = solver_of(eq)
    if solver is None:
        raise ValueError("model_midline needs a direct solution")
    y = midline(solver.disc, n).at(eq)
    return np.column_stack([y[:n], y[n:]])


def synthetic_midline(problem: Problem, like: Problem | None = None, *, nodes: int = 200,
                      n: int = N_FIT, noise: float = 0.0, seed: int | None = None) -> np.ndarray:
    """The midline of the forward model, with Gaussian noise of std ``noise`` (units of R).

    Solved on ``problem``'s own mesh, the one a fit that ends at ``problem``
    uses (:meth:`InnerProblem.own_mesh`), so that noiseless data can be fitted
    exactly: a test of the fit, not of the discretisation.

    Parameters
    ----------
    problem : Problem
        The generating problem (solved by continuation from its stress-free
        parameters).
    like : Problem, optional
        Solve on this problem's mesh instead (a fit's start, say: then the
        fit's end differs from ``problem`` by the two meshes' discretisations).
    nodes : int
        Mesh nodes.
    n : int
        Points (:data:`N_FIT`).
    noise : float
        Standard deviation of the noise added to r and z, except at the pole.
    seed : int, optional
        Of the noise.

    Returns
    -------
    ndarray, shape (n, 2)
        r and z (:func:`model_midline`), plus the noise.
    """
    solver = DirectSolver(problem.structure, mesh=mesh_spec(like or problem, nodes, 2))
    points = model_midline(continue_to(solver, problem), n)
    if noise:
        points = points + np.random.default_rng(seed).normal(0.0, noise, points.shape)
        points[0] = 0.0      # the pole is the origin of the gauge
    return points


class InnerProblem:
    """The inner problem of a fit: warm-started solves, residuals and their Jacobian.

    Keeps the states solved so far (the last :data:`ARCHIVE`), so that each
    solve starts from the nearest one and the fit follows one branch of
    equilibria.

    Parameters
    ----------
    spec : FitSpec
        What is fitted.
    data : ndarray, shape (N, 2)
        The data midline (r, z).
    nodes : int
        Mesh nodes of the inner solves.
    start : Equilibrium, optional
        A direct solution of ``spec.base`` on this mesh to start from; by
        default the physical branch by continuation from the stress-free
        parameters.
    solver : DirectSolver, optional
        The inner solver (its mesh); by default one on the mesh of
        ``spec.base`` (a profile's refits use the fit's own, so that their
        objective is the fit's at the fitted parameters).

    Attributes
    ----------
    eq : Equilibrium
        The current state (the last solved or kept).
    solver : DirectSolver
        The inner solver (rebuilt when the breakpoints move too far for its
        mesh).
    n : int
        N, the data's points.
    solves : int
        Inner solves so far.
    warm : bool
        Whether the fit started (or goes on) from a given state.
    """

    def __init__(self, spec: FitSpec, data: np.ndarray, nodes: int,
                 start: Equilibrium | None = None, solver: DirectSolver | None = None):
        check_guess(start, "start")     # (before the mesh is built; 3 raised "no attribute 'x'")
        self.spec, self.data, self.nodes = spec, np.asarray(data, dtype=float), nodes
        self.n = len(self.data)
        self.solves = 0
        if solver is None:
            self._build(spec.base)
        else:
            self.solver, self.midline = solver, midline(solver.disc, self.n)
        if start is not None:
            if start.x is None or len(start.x) != self.solver.disc.layout.size:
                raise ValueError(f"the start state must be a direct solution on {nodes} nodes "
                                 f"of this mesh")
            self.eq = start
        else:
            self.eq = continue_to(self.solver, spec.base)
            self.solves += 1
        self._cache: dict = {}
        self._archive = [(spec.theta0, self.eq)]
        #: whether a trial point's continuation crosses folds by their snap-through (a
        #: profile's refits do not: :mod:`morphoshell.fitting.profiles`)
        self.snap_trials = True
        #: whether the fit started from a given state (a previous fit's)
        self.warm = start is not None

    def _build(self, problem: Problem) -> None:
        """A solver on the mesh of ``problem`` (its breakpoints) and its midline observable."""
        self.solver = DirectSolver(problem.structure, mesh=self._mesh(problem))
        self.midline = midline(self.solver.disc, self.n)

    def _mesh(self, problem: Problem):
        """The mesh of the inner solves at ``problem`` (its breakpoints as knots)."""
        return mesh_spec(problem, self.nodes, 2)

    def solve(self, theta, trial: bool = False) -> Equilibrium:
        """The inner solution at θ, on the branch of the fit's start.

        From the nearest state solved so far (θ scaled by its bounds' widths):
        one warm solve if it is near, else continuation from it, so that the
        solves follow one branch of equilibria even when θ jumps.  A ``trial``
        point (a least-squares step, which the outer loop rejects and
        shortens when its solve fails) gets no continuation after a failed
        warm solve: it raises at once.

        Parameters
        ----------
        theta : array_like, shape (k,)
            The fitted parameters.
        trial : bool
            A trial point of the outer iteration.

        Returns
        -------
        Equilibrium

        Raises
        ------
        SolverError
            The solve failed (at once for a trial point).
        """
        theta = np.asarray(theta, dtype=float)
        key = tuple(theta)
        if key in self._cache:
            return self._cache[key]
        problem = self.spec.problem(theta)
        near = min(self._archive, key=lambda item: self._distance(item[0], theta))
        try:
            if self._distance(near[0], theta) < NEAR:
                eq = self.solver.solve(problem, warm_start=near[1])
            else:
                eq = continue_between(self.solver, near[1], problem,
                                      snap=self.snap_trials or not trial)
        except ValueError:           # the mesh's breakpoints moved too far: a new mesh
            eq = self._remeshed(problem, near[1])
        except SolverError:
            if trial and self._stale(problem):
                eq = self._remeshed(problem, near[1])
            elif trial:
                raise
            else:
                eq = continue_between(self.solver, near[1], problem, first_step=0.25, snap=True)
        return self._keep(theta, eq)

    def _stale(self, problem: Problem) -> bool:
        """Whether the mesh's knots lie more than :data:`STALE_MESH` knot widths from where
        ``problem``'s mesh would put them (its breakpoints)."""
        own = self._mesh(problem).knots
        return any(abs(a.t - b.t) > STALE_MESH * (a.width or 0.0)
                   for a, b in zip(own, self.solver.mesh.knots))

    def _remeshed(self, problem: Problem, eq: Equilibrium) -> Equilibrium:
        """``problem`` solved on a mesh of its own, from the state ``eq`` of another mesh; the
        new mesh becomes the inner problem's (after the solve: a failure keeps the old one)."""
        solver = DirectSolver(problem.structure, mesh=self._mesh(problem))
        new = solve_from(solver, problem, eq)
        self.solver, self.midline, self._archive = solver, midline(solver.disc, self.n), []
        return new

    def own_mesh(self, theta):
        """θ's own mesh: the one a fit started at θ builds
        (:class:`morphoshell.numerics.mesh.MeshSpec`).

        The mesh follows the breakpoints (they are its knots) but keeps the knots'
        places of the problem it was built for; on a coarse mesh E_fit at θ on
        another problem's mesh differs from E_fit on θ's own by more than the fit's
        tolerances (1.7 % at 60 nodes, the synthetic t02 average's fit).
        """
        return self._mesh(self.spec.problem(theta))

    def on_own_mesh(self, theta) -> bool:
        """Whether the inner solves use θ's own mesh (:meth:`own_mesh`)."""
        return self.solver.mesh == self.own_mesh(theta)

    def remesh(self, theta) -> Equilibrium:
        """The state at θ solved on θ's own mesh (:meth:`own_mesh`), from the current
        state of θ; that mesh becomes the inner problem's, its archive emptied.

        Raises
        ------
        SolverError
            The solve failed (the mesh stays as it was).
        """
        theta = np.asarray(theta, dtype=float)
        return self._keep(theta, self._remeshed(self.spec.problem(theta), self.solve(theta)))

    def keep(self, theta, eq: Equilibrium) -> None:
        """Make ``eq``, solved before at θ, the state of θ again (without a solve)."""
        self._adopt(eq)
        self.eq = eq
        self._cache = {tuple(np.asarray(theta, dtype=float)): eq}
        self._archive = (self._archive + [(np.asarray(theta, dtype=float), eq)])[-ARCHIVE:]

    def _adopt(self, eq: Equilibrium) -> None:
        """Make the solver of ``eq`` the inner problem's, if the mesh has moved since ``eq``.

        A state is only read through its own mesh: the gradient fit's best point,
        kept after trials that moved the mesh, read through the new one's midline
        gave E_fit² 1.6 R² for 2.9e-5 (a profile's refit of the synthetic t05).
        The archived states of other meshes are dropped.
        """
        if self._on_this_mesh(eq):
            return
        solver = solver_of(eq)
        self.solver, self.midline = solver, midline(solver.disc, self.n)
        self._archive = [(t, e) for t, e in self._archive if self._on_this_mesh(e)]

    def _on_this_mesh(self, eq) -> bool:
        """Whether ``eq`` was solved on the current solver's mesh (or is no direct solution)."""
        return getattr(eq, "source", None) is None or self.solver.made(eq)

    def restart(self, spec: FitSpec, eq: Equilibrium) -> None:
        """Fit ``spec`` next, from the state ``eq`` (solved on this mesh, e.g. for a neighbouring
        value of a parameter ``spec`` holds).

        The solver becomes ``eq``'s again, should the mesh have moved since.  The
        states kept so far belong to another θ (another spec: a profile's
        step holds one parameter at a new value, :mod:`morphoshell.fitting.profiles`),
        so they are dropped; ``eq`` is kept as the state of ``spec.theta0``, from
        which the first solve warm-starts (continues, should that fail).
        """
        self.spec, self.eq, self.warm = spec, eq, True
        self._adopt(eq)
        self._cache = {}
        self._archive = [(spec.theta0, eq)]

    def reset(self, theta, eq: Equilibrium) -> None:
        """Make ``eq`` the current state and the only cached one, θ's (not archived)."""
        self.eq = eq
        self._cache = {tuple(theta): eq}

    def _keep(self, theta, eq: Equilibrium) -> Equilibrium:
        """Count a solve at θ and keep its state ``eq``."""
        self.solves += 1
        self.keep(theta, eq)
        return eq

    def transfer(self, theta, eq: Equilibrium) -> Equilibrium:
        """The inner solution at θ on the branch of ``eq``, a solution at θ on another mesh.

        Interpolated and solved (:func:`morphoshell.solvers.refinement.solve_from`); if
        that fails, by :meth:`solve`.  A coarse mesh's state can lie near a fold
        of the branch that the fine mesh has a little earlier: continuation
        from the fit's start then stops short of θ, while the coarse state's
        branch continues.
        """
        theta = np.asarray(theta, dtype=float)
        problem = self.spec.problem(theta)
        try:
            try:
                eq = solve_from(self.solver, problem, eq)
            except ValueError:           # the breakpoints moved too far: a new mesh
                self._build(problem)
                self._archive = []
                eq = solve_from(self.solver, problem, eq)
        except SolverError:
            return self.solve(theta)
        return self._keep(theta, eq)

    def _distance(self, a, b) -> float:
        """max over θ of |a − b| over the bounds' widths (or |a|, at least 1, if unbounded)."""
        lo, hi = self.spec.box()
        width = np.where(np.isfinite(hi - lo), hi - lo, np.maximum(np.abs(a), 1.0))
        return float(np.max(np.abs(a - b) / width))

    def residuals(self, eq: Equilibrium) -> np.ndarray:
        """r − R then z − Z at the N fit points of the state ``eq``: ndarray, shape (2N,).

        Raises ValueError for a state of another mesh (its unknowns would be read as
        this mesh's: :meth:`_adopt`).
        """
        if not self._on_this_mesh(eq):
            raise ValueError("a state of another mesh read through the fit's current one "
                             "(a bug)")
        y = self.midline.at(eq)
        return np.concatenate([y[:self.n] - self.data[:, 0], y[self.n:] - self.data[:, 1]])

    def jacobian(self, eq: Equilibrium, theta) -> np.ndarray:
        """d residuals / dθ at the state ``eq`` of θ, exact (implicit function theorem).

        Returns
        -------
        ndarray, shape (2N, k)
            Rows as :meth:`residuals`, columns in ``spec.fitted`` order (tied
            parameters' dependence included).
        """
        names = tuple(self.spec.fitted) + tuple(self.spec.tied)
        _, J = parametric(self.solver).jacobian(eq, self.midline, names)
        return J @ self.spec.chain(theta, names)
