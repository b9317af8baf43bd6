"""Toy problem 2 as a forward map k ↦ recoil, with its exact derivative in k.

The numerical model of the inverse estimates (paper, main text "Quantitative
estimates of the curvature mismatch during *Volvox* invagination…", Fig. 2 J;
Supplementary, toy problem 2): a sphere of uniform intrinsic curvature k and
relative thickness h = H/R, cut by a circular hole of angular radius Σ.  The
recoil (opening o, rotation ϱ, displacement d of the cut edge) is that of
:func:`morphoshell.mechanics.ablation.ablate`: the post-ablation minus the
intact (Σ = 0) equilibrium of the same shell at the material point s = Σ, z in
the far-end gauge.  Its k-derivatives are exact, by the implicit function
theorem (:func:`morphoshell.mechanics.ablation.recoil_jacobian`'s route), and
the solution's own tangent dx/dk predicts the next solve, so that a walk in k
costs one Newton solve per step.
"""
from __future__ import annotations

import math
import weakref
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from ..mechanics.ablation import intact_problem, recoil_function
from ..model.problem import Problem
from ..numerics.mesh import mesh_spec
from ..solvers.continuation import continue_to
from ..solvers.direct import DirectSolver
from ..solvers.observables import Observable, state_at
from ..solvers.parametric import parametric
from ..solvers.results import Equilibrium, SolverError
from ..solvers.routes import cache_info, direct_solver

__all__ = ["NODES", "RecoilPoint", "RecoilModel"]

#: Mesh nodes of the numerical model, fourth order (tuned against 800 nodes on the synthetic table)
NODES = 60


@dataclass(frozen=True, eq=False)
class RecoilPoint:
    """The recoil of toy problem 2 at one (h, Σ, k), with its derivatives in k.

    ``opening``, ``rotation``, ``displacement`` and the ``radial_displacement``
    and ``axial_displacement`` of the rim are those of
    :func:`morphoshell.mechanics.ablation.ablate` (units of R, radians);
    ``derivative[name]`` is d(name)/dk, exact (implicit function theorem).
    """

    h: float
    cut: float
    k: float
    opening: float
    rotation: float
    displacement: float
    radial_displacement: float
    axial_displacement: float
    derivative: Mapping[str, float]
    pre: Equilibrium
    post: Equilibrium
    _tangents: tuple = field(repr=False, default=())
    _solvers: tuple = field(repr=False, default=())

    def __repr__(self) -> str:
        return (f"RecoilPoint(h={self.h:g}, cut={self.cut:g} rad, k={self.k:g}/R, "
                f"opening={self.opening:.6g} R, rotation={self.rotation:.6g} rad, "
                f"displacement={self.displacement:.6g} R)")

    @property
    def Sigma(self) -> float:
        """Deprecated alias of ``cut`` (the one name of the cut)."""
        return self.cut

    @property
    def signed_displacement(self) -> float:
        """d with the sign of 1 − k: smooth through k = 1, where d = |·| has a kink."""
        return math.copysign(self.displacement, 1 - self.k) if self.k != 1 else 0.0

    @property
    def d_signed_displacement(self) -> float:
        """d(signed_displacement)/dk: ±dd/dk, and −|(dΔr/dk, dΔz/dk)| where d = 0."""
        dr, dz = self.derivative["radial_displacement"], self.derivative["axial_displacement"]
        if self.displacement < 1e-12:
            return -math.hypot(dr, dz)
        return (1.0 if self.k < 1 else -1.0) * self.derivative["displacement"]


_RIM: "weakref.WeakKeyDictionary[DirectSolver, Observable]" = weakref.WeakKeyDictionary()


def _rim(solver: DirectSolver) -> Observable:
    """(r, z, ψ) at the rim's material point s = Σ, far-end gauge, built once per solver.

    The rim is the first node of a cut shell (s = ``cut``, a parameter) and
    the anchor node of the intact one (s = q₀, the anchor's position), so one
    observable serves every Σ the solver is used for.
    """
    if solver not in _RIM:
        d = solver.disc
        if solver.structure.start == "free":
            obs = state_at(d, lambda prm: prm["cut"], 0, gauge="far_end")
        else:
            node = int(np.argmin(np.abs(solver.t - solver.mesh.knots[0].t)))
            obs = state_at(d, lambda prm: d.q[0], min(node, d.layout.cells - 1),
                           gauge="far_end")
        _RIM[solver] = obs
    return _RIM[solver]


class RecoilModel:
    """Toy problem 2 (uniform intrinsic curvature k, sphere, circular cut) as a map k ↦ recoil.

    Parameters
    ----------
    theory : {"large_bending", "classical"}
    nodes, stages : int
        Mesh of both direct solvers (see :class:`morphoshell.solvers.direct.DirectSolver`).
    mesh_for : (h, Σ), optional
        Build one pair of solvers, meshed for this shell, and use it for every
        (h, Σ): they are NLP parameters, and the intact shell's anchor (the
        node at s = Σ) moves with Σ.  Over a table of similar shells a mesh
        for its median shell changes k no more than the shells' own meshes
        do.  Without it, each shell gets the solvers
        :func:`morphoshell.mechanics.ablation.ablate` would use
        (:func:`morphoshell.solvers.routes.direct_solver`, meshes quantised in
        h and Σ), so that a table needs a few builds.

    Attributes
    ----------
    builds : int
        The number of direct solvers this model built.
    """

    def __init__(self, theory: str = "large_bending", nodes: int = NODES, stages: int = 2,
                 mesh_for: tuple[float, float] | None = None):
        Problem("uniform", theory=theory)   # validates the theory
        self.theory, self.nodes, self.stages = theory, int(nodes), int(stages)
        self.builds = 0
        self._fixed = None
        if mesh_for is not None:
            post_p = self.problem(mesh_for[0], mesh_for[1], 0.0)
            pre_p = intact_problem(post_p)
            self._fixed = tuple(DirectSolver(p.structure, stages=self.stages,
                                             mesh=mesh_spec(p, self.nodes, self.stages, a))
                                for p, a in ((pre_p, (post_p.cut,)), (post_p, ())))
            self.builds = 2

    def problem(self, h: float, cut: float, k: float) -> Problem:
        """The cut shell of toy problem 2.

        Parameters
        ----------
        h : float
            Relative thickness H/R.
        cut : float
            The cut Σ (radians).
        k : float
            Uniform intrinsic curvature (units of 1/R).

        Returns
        -------
        Problem
            Family ``uniform``, named ``toy2``, in this model's theory.
        """
        return Problem("uniform", {"k": float(k)}, h=float(h), cut=float(cut),
                       theory=self.theory, name="toy2")

    def _solvers(self, post_p: Problem, pre_p: Problem) -> tuple[DirectSolver, DirectSolver]:
        if self._fixed is not None:
            try:   # the anchor's map t -> s must stay monotone
                self._fixed[0].disc.check_anchors(pre_p.parameter_vector(), (post_p.cut,))
                return self._fixed
            except ValueError:
                pass
        before = cache_info()["builds"]
        pre_s = direct_solver(pre_p, self.nodes, anchors=(post_p.cut,), stages=self.stages)
        post_s = direct_solver(post_p, self.nodes, stages=self.stages)
        self.builds += cache_info()["builds"] - before
        return pre_s, post_s

    def evaluate(self, h: float, cut: float, k: float,
                 start: RecoilPoint | None = None) -> RecoilPoint:
        """The recoil at (h, Σ = ``cut``, k) and its exact k-derivatives.

        Parameters
        ----------
        start : RecoilPoint, optional
            A solution on the same solvers: the solve starts from its tangent
            predictor x + (dx/dk)(k − k_start); a failing step is split in two
            (recursively), and the last resort is continuation from the
            stress-free k = 1 (:func:`morphoshell.solvers.continuation.continue_to`).
            Without ``start`` the solve is that continuation: the physical
            branch.

        Returns
        -------
        RecoilPoint
            o, ϱ, d and the rim's displacements (units of R, radians), each
            with its exact k-derivative, and both equilibria.

        Raises
        ------
        SolverError
            No converged, stable solution.
        """
        post_p = self.problem(h, cut, k)
        pre_p = intact_problem(post_p)
        solvers = self._solvers(post_p, pre_p)
        if start is not None and start._solvers == solvers:
            try:
                return self._step(start, pre_p, post_p, solvers, depth=0)
            except SolverError:
                pass
        eqs = [continue_to(s, p, a) for s, p, a in zip(solvers, (pre_p, post_p), ((cut,), ()))]
        return self._point(post_p, *eqs, solvers)

    def _step(self, start: RecoilPoint, pre_p: Problem, post_p: Problem, solvers,
              depth: int) -> RecoilPoint:
        """From ``start`` by the tangent predictor; a failing step is halved (at most 4 times)."""
        dk = post_p.params["k"] - start.k
        try:
            eqs = [s.solve(p, x0=eq.x + tangent * dk, lam_g0=eq.lam_g, anchors=a)
                   for s, p, a, eq, tangent in zip(solvers, (pre_p, post_p), ((post_p.cut,), ()),
                                                   (start.pre, start.post), start._tangents)]
        except SolverError:
            if depth >= 4:
                raise
            half = post_p.with_updates(k=start.k + dk / 2)
            mid = self._step(start, intact_problem(half), half, solvers, depth + 1)
            return self._step(mid, pre_p, post_p, solvers, depth + 1)
        return self._point(post_p, *eqs, solvers)

    def _point(self, post_p: Problem, pre: Equilibrium, post: Equilibrium,
               solvers) -> RecoilPoint:
        values, jacobians, tangents = [], [], []
        for eq, solver in zip((pre, post), solvers):
            par = parametric(solver)
            y, J = par.jacobian(eq, _rim(solver), ["k"])
            values.append(y)
            jacobians.append(J)
            tangents.append(par.derivative(eq, ["k"]).dx[:, 0])
        y, dy = recoil_function()(*values)
        y = np.asarray(y).ravel()
        dydk = (np.asarray(dy) @ np.vstack(jacobians)).ravel()
        names = ("opening", "rotation", "displacement", "radial_displacement",
                 "axial_displacement")
        return RecoilPoint(post_p.h, post_p.cut, post_p.params["k"],
                           **{n: float(v) for n, v in zip(names, y)},
                           derivative={n: float(v) for n, v in zip(names, dydk)},
                           pre=pre, post=post, _tangents=tuple(tangents), _solvers=solvers)
