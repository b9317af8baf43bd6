"""Equilibria of morphoelastic shells by direct energy minimisation.

:class:`DirectSolver` builds the NLP of :mod:`morphoshell.discretisation`
once for a (structure, mesh) and re-solves it with Ipopt for new parameter
values, warm-started from a previous :class:`Equilibrium`: continuation and
fitting call it thousands of times.  :func:`solve` is the one-call interface
(solvers are cached), which also dispatches to the boundary-value reference.

Nothing unconverged is returned: an Ipopt failure raises :class:`SolverError`
naming Ipopt's status, a converged stationary point that is not a local
minimum (a saddle, which interior-point methods can report as success) raises
:class:`NotAMinimumError`; both carry the last iterate.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, fields
from typing import Any, Mapping

import casadi as ca
import numpy as np

from .discretisation import Discretisation, boundary_layer_width, graded_mesh, pole_exponent
from .geometry import get_geometry
from ._buffered import Buffered
from .problem import Problem, Structure

__all__ = ["Equilibrium", "SolverStats", "SolverError", "NotAMinimumError", "DirectSolver",
           "Sensitivities", "solve", "FIELDS"]

#: Nodal arrays of an :class:`Equilibrium`, in order.
FIELDS = ("s", "r", "z", "psi", "f_s", "f_phi", "kappa_s", "kappa_phi",
          "E_s", "E_phi", "K_s", "K_phi", "N_s", "N_phi", "M_s", "M_phi", "eta", "e")


@dataclass(frozen=True)
class SolverStats:
    """How an equilibrium was obtained."""

    method: str
    iterations: int
    seconds: float
    status: str
    nodes: int
    build_seconds: float = 0.0
    details: Mapping[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {"method": self.method, "iterations": self.iterations, "seconds": self.seconds,
                "status": self.status, "nodes": self.nodes, "build_seconds": self.build_seconds,
                **{k: v for k, v in self.details.items() if np.isscalar(v)}}


@dataclass(frozen=True, eq=False)
class Equilibrium:
    """An equilibrium shape and its mechanics, all on the points ``s`` (increasing).

    For the direct solver the points are the mesh nodes and the interior
    interpolation points of each cell (``stages − 1`` per cell); for the
    boundary-value reference they are the collocation mesh.

    Attributes
    ----------
    problem : Problem
    s, r, z, psi : ndarray
        Undeformed arclength, deformed distance from the axis, height and
        tangent angle.  z is fixed by z(s[0]) = z₀(s[0]) (the undeformed height).
    f_s, f_phi, kappa_s, kappa_phi : ndarray
        Stretches and curvatures (paper, Eq. 5).
    E_s, E_phi, K_s, K_phi : ndarray
        Strains (paper, Eq. 6).
    N_s, N_phi, M_s, M_phi : ndarray
        Resultants ∂e/∂E_a and ∂e/∂K_a (units of C).
    eta : ndarray
        Large-bending parameter η(s).
    e : ndarray
        Energy per undeformed area (units of C); 𝓔 = 2π ∫ e ρ ds.
    energy : float
        Total elastic energy 𝓔 (units of C R²).
    solver : SolverStats
    converged : bool
        True for every returned result; False only on the ``last_iterate`` of
        a :class:`SolverError`.
    """

    problem: Problem
    s: np.ndarray
    r: np.ndarray
    z: np.ndarray
    psi: np.ndarray
    f_s: np.ndarray
    f_phi: np.ndarray
    kappa_s: np.ndarray
    kappa_phi: np.ndarray
    E_s: np.ndarray
    E_phi: np.ndarray
    K_s: np.ndarray
    K_phi: np.ndarray
    N_s: np.ndarray
    N_phi: np.ndarray
    M_s: np.ndarray
    M_phi: np.ndarray
    eta: np.ndarray
    e: np.ndarray
    energy: float
    solver: SolverStats
    converged: bool = True
    x: np.ndarray | None = field(default=None, repr=False)
    lam_g: np.ndarray | None = field(default=None, repr=False)
    quadrature: tuple | None = field(default=None, repr=False)

    def __repr__(self) -> str:
        return (f"Equilibrium({self.problem.name or self.problem.family!r}, "
                f"energy={self.energy:.10g}, points={len(self.s)}, method={self.solver.method!r}, "
                f"converged={self.converged})")

    def edge(self, which: str = "start") -> dict[str, float]:
        """Values at the first (``"start"``) or last (``"end"``) node."""
        i = 0 if which == "start" else -1
        return {k: float(getattr(self, k)[i]) for k in FIELDS}

    def at(self, s: float) -> dict[str, float]:
        """Fields interpolated (cubic) at the undeformed arclength ``s``."""
        from scipy.interpolate import CubicSpline

        if not self.s[0] <= s <= self.s[-1]:
            raise ValueError(f"s = {s} lies outside the shell [{self.s[0]}, {self.s[-1]}]")
        return {k: float(CubicSpline(self.s, getattr(self, k))(s)) for k in FIELDS}

    def energy_between(self, a: float, b: float) -> float:
        """2π ∫_a^b e ρ ds: the energy of the part a ≤ s ≤ b of the shell.

        Direct solutions use their own Gauss rule (exact integration of the
        cell's interpolant of L = 2πρe where a or b cuts a cell), so that
        ``energy_between(s[0], s[-1]) == energy``; BVP solutions integrate the
        cubic spline of L through their collocation mesh.
        """
        from scipy.interpolate import CubicSpline

        if not self.s[0] <= a <= b <= self.s[-1]:
            raise ValueError(f"[{a}, {b}] is not a part of the shell [{self.s[0]}, {self.s[-1]}]")
        if self.quadrature is None:
            rho = self.problem.geometry_obj.numeric(self.s)[0]
            return float(CubicSpline(self.s, 2 * np.pi * rho * self.e).integrate(a, b))
        sk, wk, Lk, stages = self.quadrature
        nodes = self.s[::stages]
        total = 0.0
        for c in range(len(nodes) - 1):
            lo, hi = max(a, nodes[c]), min(b, nodes[c + 1])
            if hi <= lo:
                continue
            sl = slice(c * stages, (c + 1) * stages)
            if lo == nodes[c] and hi == nodes[c + 1]:
                total += float(np.dot(wk[sl], Lk[sl]))
            else:   # the degree S − 1 interpolant through the cell's Gauss values
                poly = np.polynomial.Polynomial.fit(sk[sl], Lk[sl], stages - 1).integ()
                total += float(poly(hi) - poly(lo))
        return total

    def to_dict(self, arrays: bool = True) -> dict:
        """JSON-ready: problem, energy, solver and (optionally) the nodal arrays."""
        out = {"problem": self.problem.describe(), "converged": self.converged,
               "energy": self.energy, "solver": self.solver.to_dict(),
               "edge_start": self.edge("start"), "edge_end": self.edge("end")}
        if arrays:
            out.update({k: getattr(self, k).tolist() for k in FIELDS})
        return out


class SolverError(RuntimeError):
    """The solver did not deliver a (stable) equilibrium.

    Attributes
    ----------
    status : str
        Ipopt's return status (or the BVP solver's message).
    last_iterate : Equilibrium or None
        The last iterate, with ``converged=False``, for inspection.
    """

    def __init__(self, message: str, status: str, last_iterate: Equilibrium | None = None):
        super().__init__(message)
        self.status = status
        self.last_iterate = last_iterate


class NotAMinimumError(SolverError):
    """Ipopt converged to a stationary point whose reduced Hessian is not positive definite."""


def _to_points(s_c: np.ndarray, v: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Gauss-point values to points: linear interpolation, linear extrapolation at the ends."""
    out = np.interp(s, s_c, v)
    for i, (j, k) in ((0, (0, 1)), (-1, (-1, -2))):
        out[i] = v[j] + (v[j] - v[k]) * (s[i] - s_c[j]) / (s_c[j] - s_c[k])
    return out


_IPOPT_DEFAULTS = {
    "print_level": 0, "sb": "yes", "print_timing_statistics": "no",
    "hessian_approximation": "exact",
    # Warm starts hand over the multipliers of the previous solution; for a
    # purely equality-constrained problem a cold start with lam_g = 0 is a
    # plain Newton start, so one setting serves both.
    "warm_start_init_point": "yes",
    # MUMPS' automatic (permuting) scaling dominated the run time on fine
    # meshes (1.5 s instead of 0.2 s per solve at N = 12800) and the NLP is
    # scaled already; AMD ordering suits the banded KKT matrix.
    "mumps_scaling": 0, "mumps_permuting_scaling": 0, "mumps_pivot_order": 0,
}


class DirectSolver:
    """Direct energy minimisation for one structure and mesh, built once.

    Parameters
    ----------
    structure : Structure
        Geometry, profile family, theory and end types (``Problem.structure``).
    nodes : int
        Number of mesh nodes N (N − 1 cells).
    stages : int
        Gauss points per cell S: the scheme has order 2S (see
        :mod:`morphoshell.discretisation`).  1 is the staggered midpoint
        scheme (second order); 2 (default) is fourth order.
    grading_width : float
        Boundary-layer width used to grade the mesh toward free edges
        (default: δ of ``h = 0.1``).  The mesh stays valid for any h.
    domain_length : float
        Typical shell length L − P − Σ for the grading (default: whole meridian).
    edge_scale : float, optional
        Distance of a free edge from the axis when it is below the
        boundary-layer width (a small cut): adds logarithmic grading there.
    linear_solver : str
        Ipopt's linear solver: ``"mumps"`` (bundled) or an HSL solver such as
        ``"ma27"`` if the user provides ``libhsl.so``.
    tol : float
        Ipopt's convergence tolerance (on the scaled KKT error) at N = 800;
        it grows like the square of the number of points on finer meshes, as
        does the round-off floor of the discrete gradient (measured: 2e-12
        with 800 points, 2e-9 with 12800).
        Ipopt's ``Search_Direction_Becomes_Too_Small`` (Newton steps at
        machine precision) counts as converged when the final scaled primal
        and dual infeasibilities are below 1e-9 and 1e-6, and so does
        ``Solved_To_Acceptable_Level`` (three iterations in a row within
        max(1e-6, 100 tol) and constraint violation below 1e-10: the round-off
        floor of thin shells).
        The status is kept in ``Equilibrium.solver.status``.
    stability : {"auto", "exact", "off"}
        How to verify that a solution is a local minimum.  ``"exact"``
        refactorises the KKT matrix at the solution and checks its inertia
        (see :meth:`inertia_correction`).
        ``"auto"`` accepts Ipopt's own certificate when its last Newton step
        needed no inertia correction (MUMPS then found the KKT inertia
        correct) *and* was negligible (‖d‖ < 1e-6), so that the factorised
        iterate is the solution; otherwise it falls back to ``"exact"``.
        (A one-step convergence from a stress-free start is factorised only
        where the compressive stress has not built up yet, and can end on a
        saddle: the exact check catches it.)
    ipopt_options : mapping
        Extra Ipopt options.
    """

    def __init__(self, structure: Structure, nodes: int = 200, *, stages: int = 2,
                 grading_width: float | None = None,
                 domain_length: float | None = None, edge_scale: float | None = None,
                 linear_solver: str = "mumps",
                 tol: float = 1e-10, max_iter: int = 500, stability: str = "auto",
                 ipopt_options: Mapping[str, Any] | None = None):
        if isinstance(nodes, bool) or int(nodes) != nodes or nodes < 5:
            raise ValueError(f"nodes = {nodes!r} must be an integer >= 5")
        if stability not in ("auto", "exact", "off"):
            raise ValueError(f"stability = {stability!r} must be 'auto', 'exact' or 'off'")
        t0 = time.perf_counter()
        self.structure = structure
        self.nodes = int(nodes)
        self.linear_solver = linear_solver
        geo = get_geometry(structure.geometry)
        width = boundary_layer_width(0.1) if grading_width is None else float(grading_width)
        length = geo.length if domain_length is None else float(domain_length)
        self.t = graded_mesh(self.nodes - 1, length, structure.start, structure.end, width,
                             q=pole_exponent(stages), edge_scale=edge_scale)
        self.disc = d = Discretisation(structure, self.t, stages)
        self.tol = float(tol) * max(1.0, (d.layout.points / 800) ** 2)
        # Newton converges quadratically: once within 1e-6 the next step lands
        # far below, so three iterations in a row there mean the round-off
        # floor is reached.  Thin shells raise that floor like 1/h² (stretching
        # stiffness relative to bending; measured 2e-8 at h = 1e-4, N = 200).
        opts = dict(_IPOPT_DEFAULTS, tol=self.tol, max_iter=max_iter, linear_solver=linear_solver,
                    acceptable_tol=max(1e-6, 100 * self.tol), acceptable_iter=3,
                    acceptable_constr_viol_tol=1e-10)
        opts.update(ipopt_options or {})
        nlp = {"x": d.x, "p": d.D, "f": d.objective, "g": d.g}
        self.nlpsol = ca.nlpsol("shell", "ipopt", nlp, {
            "ipopt": opts, "print_time": False, "error_on_fail": False,
            "grad_f": d.grad_f, "jac_g": d.jac_g, "hess_lag": d.hess_lag,
            # Multipliers of bounds and parameters are not needed (there are
            # no bounds; parametric derivatives come from the KKT system).
            "calc_lam_p": False, "calc_lam_x": False, "bound_consistency": False,
            "calc_f": False, "calc_g": False})
        self.stability = stability
        self._nlp_options = {"ipopt": opts, "grad_f": d.grad_f, "jac_g": d.jac_g,
                             "hess_lag": d.hess_lag}
        self._refactor = None
        self._solve = Buffered(self.nlpsol)
        self._pre = Buffered(d.pre)
        n, m = d.layout.size, d.g.shape[0]
        self._bounds = (np.full(n, -np.inf), np.full(n, np.inf), np.zeros(m), np.zeros(m), np.zeros(n))
        self.build_seconds = time.perf_counter() - t0

    # ------------------------------------------------------------------
    def _check(self, problem: Problem) -> None:
        if problem.structure != self.structure:
            raise ValueError(f"this solver is built for {self.structure}, "
                             f"not for {problem.structure}")

    def inertia_correction(self, x: np.ndarray, D: np.ndarray, lam_g: np.ndarray) -> float:
        """Hessian regularisation δ_w that Ipopt needs at (x, λ); 0 iff it is a strict minimum.

        By Sylvester's law of inertia the KKT matrix [[∇²ℒ, Jᵀ], [J, 0]] has
        exactly m negative eigenvalues (m constraints) and none zero iff the
        Hessian of the Lagrangian is positive definite on the tangent space of
        the constraints.  Ipopt factorises it with MUMPS (symmetric indefinite
        LDLᵀ with pivoting, which reports the inertia) and adds δ_w I to the
        Hessian until the inertia is right.  Restarting Ipopt at (x, λ) for
        one iteration, with a tolerance it cannot meet so that it does not stop
        before factorising, therefore tells whether (x, λ) is a minimum.
        """
        if self._refactor is None:
            opts = dict(self._nlp_options)
            opts["ipopt"] = dict(opts["ipopt"], tol=1e-300, max_iter=1, acceptable_iter=0)
            d = self.disc
            self._refactor = Buffered(ca.nlpsol(
                "shell_inertia", "ipopt", {"x": d.x, "p": d.D, "f": d.objective, "g": d.g},
                {**opts, "print_time": False, "error_on_fail": False, "calc_lam_p": False,
                 "calc_lam_x": False, "bound_consistency": False, "calc_f": False,
                 "calc_g": False}))
        lbx, ubx, lbg, ubg, lam_x0 = self._bounds
        self._refactor(x, D, lbx, ubx, lbg, ubg, lam_x0, lam_g)
        reg = self._refactor.stats().get("iterations", {}).get("regularization_size", [])
        if len(reg) < 2:
            raise SolverError("stability check: Ipopt did not factorise the KKT matrix",
                              "Stability_Check_Failed")
        return float(reg[1])

    def sensitivities(self, eq: Equilibrium) -> "Sensitivities":
        """Exact derivatives of the solution with respect to the parameters.

        The solution (x, λ) of the equality-constrained NLP satisfies
        F = [∇ₓℒ(x, λ; p), g(x; p)] = 0, so by the implicit function theorem
        d(x, λ)/dp = −K⁻¹ ∂F/∂p with the KKT matrix K = ∂F/∂(x, λ), nonsingular
        at a strict minimum.  p is the physical parameter vector
        [h, Σ, P, family...] (``Problem.parameter_vector``); the derivative goes
        through the cell data D(p) and the parametric mesh, so ∂/∂Σ moves the
        material points with the cut.

        Returns
        -------
        Sensitivities
        """
        import scipy.sparse.linalg

        self._check(eq.problem)
        if eq.x is None or eq.lam_g is None or len(eq.x) != self.disc.layout.size:
            raise ValueError("eq must be a direct solution on a solver of this mesh")
        d = self.disc
        if not hasattr(self, "_sens"):
            x, p, lam = d.x, d.p, ca.MX.sym("lam", d.g.shape[0])
            D = d.pre(p)
            F = ca.vertcat(d.grad_f(x, D)[1] + ca.mtimes(d.jac_g(x, D)[1].T, lam), d.jac_g(x, D)[0])
            Ht = d.hess_lag(x, D, 1, lam)
            J = d.jac_g(x, D)[1]
            K = ca.blockcat([[Ht + Ht.T - ca.diag(ca.diag(Ht)), J.T],
                             [J, ca.MX(J.shape[0], J.shape[0])]])
            energy = ca.Function("energy", [d.x, d.D], [d.energy])(x, D)
            self._sens = ca.Function("sens", [x, p, lam],
                                     [K, ca.jacobian(F, p), ca.jacobian(energy, p),
                                      ca.gradient(energy, x)])
        p = eq.problem.parameter_vector()
        K, Fp, Ep, Ex = self._sens(eq.x, p, eq.lam_g)
        rhs = -np.asarray(ca.densify(Fp))
        sol = scipy.sparse.linalg.splu(K.sparse().tocsc()).solve(rhs)
        n = d.layout.size
        dx = sol[:n]
        dE = np.asarray(ca.densify(Ep)).ravel() + np.asarray(Ex).ravel() @ dx
        dr, dpsi, _ = (np.stack(v) for v in zip(*[d.layout.split(c, derivative=True)
                                                   for c in dx.T]))
        # points move with the parametric mesh: s = Σ + (L − P − Σ) t
        ds = np.zeros((len(p), len(eq.s)))
        ds[1] = 1 - d.t_points
        ds[2] = -d.t_points
        names = ("h", "cut", "opening", *eq.problem.family_obj.parameters)
        return Sensitivities(names=names, dx=dx, dr=dr.T, dpsi=dpsi.T, ds=ds.T, denergy=dE)

    def solve(self, problem: Problem, warm_start: Equilibrium | None = None,
              x0: np.ndarray | None = None, lam_g0: np.ndarray | None = None) -> Equilibrium:
        """Equilibrium of ``problem``, optionally warm-started.

        Parameters
        ----------
        problem : Problem
            Must have this solver's structure; any parameter values.
        warm_start : Equilibrium, optional
            A previous solution on this solver (continuation, fitting).
        x0, lam_g0 : ndarray, optional
            Raw initial iterate and multipliers (override ``warm_start``).

        Raises
        ------
        SolverError
            Ipopt did not converge; ``.status`` is Ipopt's return status.
        NotAMinimumError
            Ipopt converged to a saddle.
        """
        self._check(problem)
        p = problem.parameter_vector()
        if warm_start is not None and x0 is None:
            if warm_start.x is None or len(warm_start.x) != self.disc.layout.size:
                raise ValueError("warm_start must be a direct solution on a solver of this mesh")
            x0, lam_g0 = warm_start.x, warm_start.lam_g
        if x0 is None:
            x0 = self.disc.initial_guess(p)
        if lam_g0 is None:
            lam_g0 = np.zeros(self.disc.g.shape[0])
        D = self._pre(p)[0]
        lbx, ubx, lbg, ubg, lam_x0 = self._bounds
        t0 = time.perf_counter()
        x, _, _, _, lam, _ = self._solve(x0, D, lbx, ubx, lbg, ubg, lam_x0, lam_g0)
        seconds = time.perf_counter() - t0
        st = self._solve.stats()
        status = st.get("return_status", "unknown")
        iters = int(st.get("iter_count", -1))
        ok = _converged(status, st)
        details: dict[str, Any] = {}
        if ok and self.stability != "off":
            it = st.get("iterations", {})
            reg, step = it.get("regularization_size", []), it.get("d_norm", [])
            # Ipopt's last factorisation was at the previous iterate: it
            # certifies the solution only if the last step was negligible.
            if (self.stability == "auto" and iters >= 2 and len(reg) and reg[-1] == 0
                    and step[-1] < 1e-6):
                details["stability"] = "ipopt_last_step"
                details["inertia_correction"] = 0.0
            else:
                details["stability"] = "ipopt_refactorisation"
                details["inertia_correction"] = self.inertia_correction(x, D, lam)
        stats = SolverStats("direct", iters, seconds, status, self.nodes, self.build_seconds, details)
        eq = self._equilibrium(problem, x, lam, p, D, stats, converged=ok)
        if not ok:
            if status == "Invalid_Option":
                raise SolverError(
                    f"Ipopt rejected its options (status 'Invalid_Option'): with linear_solver = "
                    f"{self.linear_solver!r}, note that the HSL solvers (ma27, ma57, ...) load "
                    f"only if libhsl.so is on the library path; 'mumps' is bundled",
                    status, eq)
            raise SolverError(
                f"Ipopt failed on {problem.name or problem.family!r} with status {status!r} "
                f"after {iters} iterations; the last iterate is attached (.last_iterate)",
                status, eq)
        if details.get("inertia_correction", 0.0) > 0:
            raise NotAMinimumError(
                f"Ipopt converged ({status}) to a stationary point that is not a strict minimum: "
                f"the reduced Hessian is not positive definite (Ipopt needs an inertia "
                f"correction {details['inertia_correction']:.3g} there); perturb the start or "
                f"continue from a stable solution. The saddle is attached (.last_iterate)",
                "Not_A_Minimum", _replace_converged(eq))
        return eq

    def _equilibrium(self, problem, x, lam, p, D, stats, converged) -> Equilibrium:
        d = self.disc
        gf = d.gauss_fields(x, D)
        s = d.points(p)
        r, psi, _ = d.layout.split(x)
        length = problem.end - problem.cut
        rho, z_start, _ = d.geometry.numeric(s)
        z = z_start[0] + length * d.integrate_to_points(gf["f_s"] * np.sin(gf["psi"]))
        derived = {"f_phi": gf["r"] / gf["rho"], "kappa_s": gf["dpsi"] / gf["f_s"],
                   "kappa_phi": np.sin(gf["psi"]) / gf["r"]}
        fields = {k: _to_points(gf["s"], derived[k] if k in derived else gf[k], s)
                  for k in FIELDS if k not in ("s", "r", "z", "psi")}
        # Exact values off the axis (interpolation is only needed at a pole).
        # a pole is on the axis exactly, whatever sin(pi) rounds to
        rho[[0, -1]] = np.where([d.layout.start_pole, d.layout.end_pole], 0.0, rho[[0, -1]])
        off = rho > 0
        fields["f_phi"][off] = r[off] / rho[off]
        fields["kappa_phi"][off] = np.sin(psi[off]) / r[off]
        fields["eta"] = problem.profiles(s)["eta"]   # parameter-only: exact at the points
        energy = float(np.sum(gf["weight"] * gf["ds"] * gf["L"]))
        return Equilibrium(problem=problem, s=s, r=r, z=z, psi=psi, **fields, energy=energy,
                           solver=stats, converged=converged, x=x, lam_g=lam,
                           quadrature=(gf["s"], gf["weight"] * gf["ds"], gf["L"], d.stages))

@dataclass(frozen=True, eq=False)
class Sensitivities:
    """Derivatives of a direct solution with respect to the parameters.

    Columns follow ``names`` = (h, cut, opening, family parameters...).

    Attributes
    ----------
    dx : ndarray (unknowns, parameters)
        Of the NLP vector x.
    dr, dpsi : ndarray (points, parameters)
        Of r and ψ at the *material* points (whose s moves with Σ and P, see
        ``ds``); the pole values are fixed (zero derivative).
    ds : ndarray (points, parameters)
        Of the points' arclength s.
    denergy : ndarray (parameters,)
        Of the total energy 𝓔 (units of C R²).
    """

    names: tuple[str, ...]
    dx: np.ndarray
    dr: np.ndarray
    dpsi: np.ndarray
    ds: np.ndarray
    denergy: np.ndarray

    def column(self, name: str) -> dict[str, np.ndarray]:
        """Derivatives with respect to one parameter, by name."""
        if name not in self.names:
            raise ValueError(f"unknown parameter {name!r}; valid: {list(self.names)}")
        j = self.names.index(name)
        return {"r": self.dr[:, j], "psi": self.dpsi[:, j], "s": self.ds[:, j],
                "energy": float(self.denergy[j])}


def _converged(status: str, stats: Mapping[str, Any]) -> bool:
    """Whether Ipopt's result is a solution (see ``DirectSolver``, ``tol``)."""
    if status in ("Solve_Succeeded", "Solved_To_Acceptable_Level"):
        return True
    if status == "Search_Direction_Becomes_Too_Small":
        it = stats.get("iterations", {})
        if it.get("inf_pr") and it.get("inf_du"):
            return it["inf_pr"][-1] < 1e-9 and it["inf_du"][-1] < 1e-6
    return False


def _replace_converged(eq: Equilibrium) -> Equilibrium:
    kw = {f.name: getattr(eq, f.name) for f in fields(eq)}
    kw["converged"] = False
    return Equilibrium(**kw)


_SOLVERS: dict[tuple, DirectSolver] = {}


def direct_solver(problem: Problem, nodes: int = 200, **options) -> DirectSolver:
    """A cached :class:`DirectSolver` suited to ``problem`` (grading from its h)."""
    width = float(f"{boundary_layer_width(problem.h):.3g}")
    # A free edge near the axis also varies on the scale of its distance from it.
    edges = [v for v in (problem.cut, problem.opening) if v > 0]
    scale = float(f"{min(edges):.2g}") if edges else None
    if scale is not None and scale >= width:
        scale = None
    length = round(problem.end - problem.cut, 2)
    key = (problem.structure, int(nodes), width, scale, length, tuple(sorted(options.items())))
    if key not in _SOLVERS:
        _SOLVERS[key] = DirectSolver(problem.structure, nodes, grading_width=width,
                                     domain_length=length, edge_scale=scale, **options)
    return _SOLVERS[key]


def solve(problem: Problem, nodes: int = 200, method: str = "direct",
          warm_start: Equilibrium | None = None, **options) -> Equilibrium:
    """Equilibrium of ``problem``.

    Parameters
    ----------
    problem : Problem
    nodes : int
        Mesh nodes (direct) or initial mesh nodes (bvp).
    method : {"direct", "bvp"}
        Direct energy minimisation (default) or the boundary-value reference
        of :mod:`morphoshell.reference`.
    warm_start : Equilibrium, optional
        A previous solution (same method and mesh) to start from.
    **options
        Passed to :class:`DirectSolver` or :func:`morphoshell.reference.solve_bvp`.
    """
    if method == "direct":
        return direct_solver(problem, nodes, **options).solve(problem, warm_start=warm_start)
    if method == "bvp":
        from .reference import solve_bvp
        return solve_bvp(problem, nodes=nodes, guess=warm_start, **options)
    raise ValueError(f"unknown method {method!r}; choose 'direct' or 'bvp'")
