"""Boundary-value reference: the Euler–Lagrange equations solved with ``solve_bvp``.

This is the verification route of the paper (Materials and Methods: the
authors solved the shell equations with MATLAB's ``bvp4c``).  The equations
are *derived*, not typed: Pontryagin's principle is applied to the optimal
control form of the same energy (:func:`morphoshell.model.energy.local_function`),

    minimise ∫ L(s, r, ψ, f_s, ψ') ds,  L = 2πρe,  subject to r' = f_s cos ψ,

with states (r, ψ), controls (f_s, u = ψ') and costates (λ_r, λ_ψ):

    H = L + λ_r f_s cos ψ + λ_ψ u,    ∂H/∂(f_s, u) = 0,
    r' = f_s cos ψ,  ψ' = u,  λ_r' = −∂H/∂r,  λ_ψ' = −∂H/∂ψ.

H is quadratic in the controls, so they follow from a 2×2 linear solve.  λ_r
is 2π times the radial force per radian and λ_ψ = −∂L/∂ψ' is 2π times minus the
bending moment (documentation: "Theory", governing equations).  z' = f_s sin ψ and
the energy density are integrated alongside.

Boundary conditions
-------------------
Free edge: λ_r = λ_ψ = 0 (no force, no torque; transversality).
Pole: the equations are singular at ρ = 0, so the solution starts a distance
ε from it on the local solution.  Near a pole the strains are affine in
w = (r', r/s, ψ', ψ/s) up to O(s²), so the energy is locally the quadratic
form ½ εᵀQε of an Euler-type problem.  Its bounded solutions are

    (r, ψ) = c_p s + C₁ c₁ s^β₁ + C₂ c₂ s^β₂,

where β₁, β₂ > 0 are the positive roots of det M(β) = 0 with
M(β) = (βP̃ − R̃)ᵀ Q (βP̃ + R̃) and c_p solves M(1) c_p = −(P̃ − R̃)ᵀ Q ε₀.
The exponents are 1 only for an isotropic quadratic form: with anisotropic
intrinsic stretch (toy problem 3, β = (1 + f0)² classically) or with η ≠ 0
in the large-bending theory the pole is weakly singular, and the naive
expansion r = Aρ, ψ = Bs would be wrong at O(ε^β).  C₁, C₂ are unknowns of
the boundary-value problem; the costates follow from ∂H/∂(f_s, u) = 0.  Q,
P̃, R̃ and ε₀ are obtained by differentiating the same energy density.
"""
from __future__ import annotations

import time
from functools import lru_cache

import casadi as ca
import numpy as np
import scipy.integrate

from ..model.energy import (CACHE_SIZE, LOCAL_OUTPUTS, boundary_layer_width, local_function,
                            optimal_controls)
from ..model.layouts import BVP_STATE
from ..model.problem import Problem, Structure
from ..numerics.mesh import graded_mesh
from ..numerics.status import BVP_STATUSES, TIME_LIMIT_EXCEEDED, explain
from .options import check_bvp_options
from .poles import PoleSolution, pole_solutions
from .results import FIELDS, Equilibrium, SolverError, SolverStats, unconverged

__all__ = ["solve_bvp", "pontryagin_functions", "pole_solutions", "pole_state",
           "pole_costates", "pole_caps", "initial_state", "to_equilibrium", "neutral_path"]

_Y = {n: i for i, n in enumerate(BVP_STATE.names)}


@lru_cache(maxsize=CACHE_SIZE)
def pontryagin_functions(structure: Structure) -> dict[str, ca.Function]:
    """CasADi functions of the Pontryagin system for ``structure``.

    Returns
    -------
    dict
        ``rhs(s, y, p) -> y'`` and ``jac(s, y, p) -> ∂y'/∂y`` for
        y = (r, ψ, λ_r, λ_ψ, z, 𝓔) (:data:`~morphoshell.model.layouts.BVP_STATE`);
        ``controls(s, y, p) -> (f_s, ψ')``;
        ``costates(s, r, psi, f_s, dpsi, p) -> (λ_r, λ_ψ)``;
        ``local`` the pointwise energy.
    """
    local = local_function(structure)
    s = ca.SX.sym("s")
    p = ca.SX.sym("p", len(structure.parameters))
    y = ca.SX.sym("y", len(BVP_STATE))
    r, psi, lr, lpsi = (y[_Y[n]] for n in ("r", "psi", "lam_r", "lam_psi"))
    f, u = ca.SX.sym("f_s"), ca.SX.sym("dpsi")
    L = local(s, r, psi, f, u, p)[LOCAL_OUTPUTS.index("L")]
    H, wstar = optimal_controls(L, f, u, psi, lr, lpsi)
    w = ca.vertcat(f, u)
    dH = ca.vertcat(ca.gradient(H, r), ca.gradient(H, psi))
    derivative = {"r": f * ca.cos(psi), "psi": u, "lam_r": -dH[0], "lam_psi": -dH[1],
                  "z": f * ca.sin(psi), "energy": L}
    rhs = ca.substitute(ca.vertcat(*[derivative[n] for n in BVP_STATE.names]), w, wstar)
    # Costates that make (f, u) optimal: ∂H/∂(f, u) = 0 solved for (λ_r, λ_ψ).
    Lw = ca.gradient(L, w)
    costates = ca.vertcat(-Lw[0] / ca.cos(psi), -Lw[1])
    out = {
        "rhs": ca.Function("rhs", [s, y, p], [rhs]),
        "jac": ca.Function("rhs_jac", [s, y, p], [ca.jacobian(rhs, y)]),
        "controls": ca.Function("controls", [s, y, p], [wstar]),
        "costates": ca.Function("costates", [s, r, psi, f, u, p], [costates]),
        "local": local,
    }
    # Pointwise functions evaluated on whole meshes, their maps cached by size.
    out.update({f"{k}_vec": _Vectorised(out[k]) for k in ("rhs", "jac", "controls")})
    return out


def pole_state(pole: PoleSolution, where: str, C, eps: float) -> tuple[float, float, float, float]:
    """(r, ψ, f_s, ψ') at distance ``eps`` from a pole on its local solution.

    Parameters
    ----------
    pole
        A local solution of :func:`pole_solutions`.
    where : {"start", "end"}
        Which end; the end pole is mirrored (ψ → π − ψ, the local solution
        being written in the distance from the pole).
    C : sequence of float
        The two mode amplitudes.
    eps : float
        Distance from the pole.

    Returns
    -------
    tuple of float
        (r, ψ, f_s, ψ').
    """
    v, dv = pole.evaluate(eps, C)
    psi = v[1] if where == "start" else np.pi - v[1]
    return v[0], psi, dv[0] / np.cos(v[1]), dv[1]


def pole_costates(problem: Problem, pole: PoleSolution, where: str, C, eps: float) -> np.ndarray:
    """(λ_r, λ_ψ) that make the local solution's (f_s, ψ') optimal, at ``eps`` from the pole.

    Arguments as for :func:`pole_state`.

    Returns
    -------
    ndarray, shape (2,)
    """
    s_e = problem.cut + eps if where == "start" else problem.end - eps
    costates = pontryagin_functions(problem.structure)["costates"]
    return np.asarray(costates(s_e, *pole_state(pole, where, C, eps),
                               problem.parameter_vector())).ravel()


_GAUSS_U, _GAUSS_W = np.polynomial.legendre.leggauss(16)
_GAUSS_U, _GAUSS_W = (_GAUSS_U + 1) / 2, _GAUSS_W / 2


def pole_caps(problem: Problem, pole: PoleSolution, where: str, C,
              eps: float) -> tuple[float, float]:
    """∫ L ds and ∫ f sin ψ ds over the ``eps`` next to a pole, on the local solution.

    The energy and the rise in z of the cap the integration leaves out
    (16-point Gauss rule in u, s = εu², which absorbs the s^β behaviour).
    Arguments as for :func:`pole_state`.

    Returns
    -------
    energy, rise : float
        Units of C R² and R.
    """
    local = pontryagin_functions(problem.structure)["local"]
    p = problem.parameter_vector()
    d = eps * _GAUSS_U**2
    jac = 2 * eps * _GAUSS_U * _GAUSS_W
    L = dz = 0.0
    for dk, wk in zip(d, jac):
        r_k, psi_k, f_k, u_k = pole_state(pole, where, C, dk)
        s_k = problem.cut + dk if where == "start" else problem.end - dk
        L += wk * float(local(s_k, r_k, psi_k, f_k, u_k, p)[LOCAL_OUTPUTS.index("L")])
        dz += wk * f_k * np.sin(psi_k)
    return L, dz


class _Vectorised:
    """Evaluate a pointwise CasADi function on many points (maps cached by size)."""

    def __init__(self, f: ca.Function):
        self.f = f
        self.maps: dict[int, ca.Function] = {}

    def __call__(self, s, y, p):
        m = len(s)
        if m not in self.maps:
            self.maps[m] = self.f.map(m)
        return np.asarray(self.maps[m](s.reshape(1, -1), y, p))


def neutral_path(problem: Problem, steps: int) -> list[Problem]:
    """Homotopy from the family's stress-free parameters to the problem's.

    Returns
    -------
    list of Problem
        ``steps`` problems, the family's parameters moved linearly, the last
        one ``problem``'s (``[problem]`` for one step or a family without
        neutral values).
    """
    fam = problem.family_obj
    if steps <= 1 or not fam.neutral:
        return [problem]
    seq = []
    for tau in np.linspace(0, 1, steps + 1)[1:]:
        params = {n: fam.neutral.get(n, v) + tau * (v - fam.neutral.get(n, v))
                  for n, v in problem.params.items()}
        seq.append(problem.with_updates(**params))
    return seq


#: Default wall-clock budget of :func:`solve_bvp` (seconds).
MAX_SECONDS = 30.0


class _OutOfTime(Exception):
    """Raised inside ``solve_bvp``'s callback; carries the last iterate (or None)."""

    def __init__(self, last: Equilibrium | None = None):
        super().__init__()
        self.last = last


def solve_bvp(problem: Problem, nodes: int = 400, *, tol: float = 1e-8, bc_tol: float | None = None,
              guess: Equilibrium | None = None, pole_offset: float = 1e-4,
              max_nodes: int = 100000, homotopy_steps: int = 1,
              max_seconds: float = MAX_SECONDS) -> Equilibrium:
    """Equilibrium of ``problem`` from the boundary-value reference.

    Parameters
    ----------
    problem : Problem
    nodes : int
        Initial mesh nodes (``solve_bvp`` refines adaptively); with a
        ``guess``, its points are the initial mesh instead.
    tol, bc_tol : float
        ``scipy.integrate.solve_bvp`` tolerances (relative collocation
        residual, boundary residual; ``bc_tol`` defaults to ``tol``).
    guess : Equilibrium, optional
        Initial guess (any method).  Default: the undeformed shell, reached
        through ``homotopy_steps`` solves from the family's stress-free
        parameters (each warm-started from the previous one).
    pole_offset : float
        ε, the distance from a pole at which the solution starts.
    max_nodes : int
        Passed to ``solve_bvp``.
    max_seconds : float
        Wall-clock budget: ``solve_bvp`` refines its mesh for minutes on a
        problem it cannot resolve (thin shells, profile kinks); past the
        budget it stops with status ``"Time_Limit_Exceeded"``.

    Returns
    -------
    Equilibrium
        On ``solve_bvp``'s final mesh, s ∈ [a, b] (a pole's ε excluded);
        ``energy`` includes the caps next to the poles.

    Raises
    ------
    SolverError
        ``solve_bvp`` did not converge (``.status`` names its outcome, a key of
        :data:`morphoshell.numerics.status.STATUSES`), ran out of time
        (``"Time_Limit_Exceeded"``; ``.last_iterate`` is the last iterate
        on a whole mesh, or the previous homotopy step's solution), or a
        pole is not regular
        (``"Pole_Analysis_Failed"``).
    ValueError
        An option out of its range (``tol`` and ``bc_tol`` in [1e-11, 1e-3],
        ``pole_offset`` in [1e-6, 0.1]: :mod:`morphoshell.solvers.options`), before any work.
    """
    check_bvp_options(problem, nodes, tol=tol, bc_tol=bc_tol, guess=guess, pole_offset=pole_offset,
                      max_nodes=max_nodes, homotopy_steps=homotopy_steps, max_seconds=max_seconds)
    t0 = time.perf_counter()
    steps = 1 if guess is not None else max(1, int(homotopy_steps))
    current = guess
    total_iters = 0
    deadline = t0 + float(max_seconds)
    for sub in neutral_path(problem, steps):
        try:
            current, iters = _solve_one(sub, nodes, tol, bc_tol if bc_tol is not None else tol,
                                        current, pole_offset, max_nodes, deadline)
        except _OutOfTime as out:
            last = out.last if out.last is not None else current
            raise SolverError(
                f"solve_bvp on {problem.name or problem.family!r} ran out of its time budget "
                f"({max_seconds:g} s; max_seconds=...): {explain(TIME_LIMIT_EXCEEDED)}"
                + ("; the last iterate is attached (.last_iterate)" if last is not None else ""),
                TIME_LIMIT_EXCEEDED, None if last is None else unconverged(last)) from None
        total_iters += iters
    seconds = time.perf_counter() - t0
    st = current.solver
    stats = SolverStats("bvp", total_iters, seconds, st.status, len(current.s), 0.0, st.details)
    return Equilibrium(**{**{k: getattr(current, k) for k in FIELDS}, "problem": problem,
                          "energy": current.energy, "solver": stats, "converged": True})


def _solve_one(problem: Problem, nodes: int, tol: float, bc_tol: float,
               guess: Equilibrium | None, eps: float, max_nodes: int,
               deadline: float = np.inf) -> tuple[Equilibrium, int]:
    st = problem.structure
    F = pontryagin_functions(st)
    geo = problem.geometry_obj
    p = problem.parameter_vector()
    start_pole, end_pole = st.start == "pole", st.end == "pole"
    a = problem.cut + (eps if start_pole else 0.0)
    b = problem.end - (eps if end_pole else 0.0)
    rhs, jac, controls = F["rhs_vec"], F["jac_vec"], F["controls_vec"]
    costates, local = F["costates"], F["local"]

    # Initial mesh: graded toward free edges as for the direct solver, and
    # geometric toward poles, where the solution varies on the scale s.
    if guess is not None and len(guess.s) > 10:
        # Continuation: start from the guess's own mesh, as bvp4c users do.
        inner = guess.s[(guess.s > a) & (guess.s < b)]
        inner = inner[::max(1, len(inner) // 2000)]
        s = np.unique(np.concatenate([[a], inner, [b]]))
    else:
        t = graded_mesh(max(nodes, 10) - 1, b - a, st.start, st.end,
                        boundary_layer_width(problem.h))
        s = a + (b - a) * t
    s = _refine_near_poles(s, problem.cut if start_pole else None,
                           problem.end if end_pole else None, eps)

    y0 = initial_state(s, geo, guess, costates, p)
    n_unknown = 2 * (start_pole + end_pole)

    # solve_bvp passes the unknowns q only when there are some (poles).  Its
    # iterates are not returned on a time-out, so the last one seen on a whole
    # mesh (a call from a to b; the others are at collocation points) is kept.
    seen = {}

    def fun(x, y, *q):
        if time.perf_counter() > deadline:
            raise _OutOfTime(equilibrium(**seen, status=TIME_LIMIT_EXCEEDED) if seen else None)
        if x[0] == a and x[-1] == b:
            seen.update(x=x.copy(), y=y.copy(), q=np.array(q[0] if q else ()))
        return rhs(x, y, p)

    def fun_jac(x, y, *q):
        J = jac(x, y, p).reshape(6, len(x), 6)   # (rows, points, cols): column-major blocks
        dfdy = np.transpose(J, (0, 2, 1))
        return (dfdy, np.zeros((6, n_unknown, len(x)))) if q else dfdy

    z_start = float(geo.numeric(problem.cut)[1])
    poles = pole_solutions(problem)

    def pole_residual(yv, s_e, C):
        where = "start" if s_e == a else "end"
        lam = pole_costates(problem, poles[where], where, C, eps)
        r_e, psi_e = pole_state(poles[where], where, C, eps)[:2]
        return [yv[_Y["r"]] - r_e, yv[_Y["psi"]] - psi_e, yv[_Y["lam_r"]] - lam[0],
                yv[_Y["lam_psi"]] - lam[1]]

    def pole_integrals(where, C):
        return pole_caps(problem, poles[where], where, C, eps)

    iz, iE, free = _Y["z"], _Y["energy"], [_Y["lam_r"], _Y["lam_psi"]]

    def bc(ya, yb, q=()):
        res = []
        k = 0
        if start_pole:
            k = 2
            r4 = pole_residual(ya, a, q[:2])
            L0, dz0 = pole_integrals("start", q[:2])
            res += r4 + [ya[iz] - (z_start + dz0), ya[iE] - L0]
        else:   # free edge: no force, no torque; gauge of z; energy from 0
            res += [ya[free[0]], ya[free[1]], ya[iz] - z_start, ya[iE]]
        if end_pole:
            r4 = pole_residual(yb, b, q[k:k + 2])
            res += r4
        else:
            res += [yb[free[0]], yb[free[1]]]
        return np.array(res, dtype=float)

    q0 = []
    ir, ip = _Y["r"], _Y["psi"]
    if start_pole:
        q0 += list(poles["start"].fit(eps, y0[ir, 0], y0[ip, 0]))
    if end_pole:
        q0 += list(poles["end"].fit(eps, y0[ir, -1], np.pi - y0[ip, -1]))
    def equilibrium(x, y, q, status, niter=0, rms=None, converged=False):
        details = {"max_rms_residual": float(np.max(rms)) if rms is not None and rms.size else 0.0,
                   "pole_offset": eps}
        end_energy = pole_integrals("end", q[-2:])[0] if end_pole else 0.0
        stats = SolverStats("bvp", niter, time.perf_counter() - t0, status, len(x), 0.0, details)
        return to_equilibrium(problem, x, y, p, controls, local, end_energy, stats, converged)

    t0 = time.perf_counter()
    sol = scipy.integrate.solve_bvp(fun, bc, s, y0, p=np.array(q0) if q0 else None,
                                    fun_jac=fun_jac, tol=tol, bc_tol=bc_tol, max_nodes=max_nodes)
    status = BVP_STATUSES[sol.status]     # its name in the table (scipy's is an integer)
    eq = equilibrium(sol.x, sol.y, sol.p if sol.p is not None else np.zeros(0), status,
                     int(sol.niter), sol.rms_residuals, sol.status == 0)
    if sol.status != 0:
        raise SolverError(f"solve_bvp failed on {problem.name or problem.family!r} with status "
                          f"{status!r} ({sol.message.rstrip('.')}): {explain(status)}; the last "
                          f"iterate is attached (.last_iterate)", status, eq)
    return eq, int(sol.niter)


def _refine_near_poles(s, start_pole: float | None, end_pole: float | None, eps: float):
    """Add points at distances ε·1.6^k from poles, where the solution varies on the scale s."""
    extra = []
    if start_pole is not None:
        d = eps * 1.6 ** np.arange(1, 80)
        extra.append(start_pole + d[start_pole + d < s[1]])
    if end_pole is not None:
        d = eps * 1.6 ** np.arange(1, 80)
        extra.append(end_pole - d[end_pole - d > s[-2]])
    return np.unique(np.concatenate([s, *extra])) if extra else s


def initial_state(s, geo, guess, costates, p):
    """BVP states at ``s`` from a ``guess`` Equilibrium, or the undeformed shell.

    The costates of a guess follow from its controls (``costates``); the
    undeformed shell starts with zero costates.

    Parameters
    ----------
    s : ndarray, shape (M,)
    geo : Geometry
        The undeformed shell.
    guess : Equilibrium or None
    costates : casadi.Function
        ``pontryagin_functions(...)["costates"]``.
    p : ndarray
        The parameter vector.

    Returns
    -------
    ndarray, shape (6, M)
        Rows in the order of :data:`~morphoshell.model.layouts.BVP_STATE`.
    """
    m = len(s)
    if guess is not None:
        r = np.interp(s, guess.s, guess.r)
        psi = np.interp(s, guess.s, guess.psi)
        z = np.interp(s, guess.s, guess.z)
        f = np.interp(s, guess.s, guess.f_s)
        u = np.interp(s, guess.s, guess.kappa_s * guess.f_s)
    else:
        rho, z, psi = geo.numeric(s)
        r, f, u = rho.copy(), np.ones(m), np.gradient(psi, s)
    lam = np.asarray(costates.map(m)(s.reshape(1, -1), r.reshape(1, -1), psi.reshape(1, -1),
                                      f.reshape(1, -1), u.reshape(1, -1), p))
    # λ_r = −L_f / cos ψ is singular where the meridian is vertical: bridge
    # those points by interpolation (the BVP iterations correct the rest).
    good = np.abs(np.cos(psi)) > 0.3
    if guess is None:
        lam[:] = 0.0
    elif good.sum() >= 2 and not good.all():
        lam[0] = np.interp(s, s[good], lam[0][good])
    y = {"r": r, "psi": psi, "lam_r": lam[0], "lam_psi": lam[1], "z": z, "energy": np.zeros(m)}
    return np.vstack([y[n] for n in BVP_STATE.names])


def to_equilibrium(problem, s, Y, p, controls, local, end_energy, stats,
                    converged) -> Equilibrium:
    """The :class:`Equilibrium` of the BVP states ``Y`` on the points ``s``.

    The controls follow from the states, and every field from the pointwise
    energy (Materials and Methods, Eqs. 5-7).

    Parameters
    ----------
    problem : Problem
    s : ndarray, shape (M,)
    Y : ndarray, shape (6, M)
        States in the order of :data:`~morphoshell.model.layouts.BVP_STATE`.
    p : ndarray
        The parameter vector.
    controls, local : casadi.Function
        Of :func:`pontryagin_functions` (``controls_vec`` and ``local``).
    end_energy : float
        Added to the accumulated energy (the cap next to an end pole).
    stats : SolverStats
    converged : bool

    Returns
    -------
    Equilibrium
        On the M points ``s``.
    """
    W = controls(s, Y, p)
    f, u = W[0], W[1]
    y = BVP_STATE.unpack(Y)
    m = len(s)
    out = local.map(m)(s.reshape(1, -1), y["r"].reshape(1, -1), y["psi"].reshape(1, -1),
                       f.reshape(1, -1), u.reshape(1, -1), p)
    vals = {k: np.asarray(v).ravel() for k, v in zip(LOCAL_OUTPUTS, out)}
    fields = {"s": s, "r": y["r"], "z": y["z"], "psi": y["psi"], "f_s": f,
              **{k: vals[k] for k in FIELDS if k not in ("s", "r", "z", "psi", "f_s")}}
    return Equilibrium(problem=problem, **fields, energy=float(y["energy"][-1]) + end_energy,
                       solver=stats, converged=converged)
