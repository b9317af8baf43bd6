"""The KKT fit's NLP: fit points blended over cell windows, exact derivatives, Ipopt.

One NLP in (parameters, shape, multipliers): minimise ½E_fit² subject to the
inner KKT conditions F(x, λ; p) = 0
(:attr:`morphoshell.solvers.parametric.Parametric.kkt_residual`), parameter
bounds, the ordering of the breakpoints and |η| < 1 as constraints.  Each fit
point is evaluated on a window of cells around its assigned one, blended
smoothly across cell boundaries; the Hessian of the Lagrangian and the
Jacobian of the constraints are assembled exactly from per-point and per-cell
kernels.
"""
from __future__ import annotations

from functools import lru_cache

import casadi as ca
import numpy as np

from .._runtime.compiled import LARGE, compiled_point_function
from ..numerics.gathers import scatter
from ..numerics.ipopt import ipopt_status, load_ipopt
from ..numerics.status import SOLVE_SUCCEEDED, SOLVED_TO_ACCEPTABLE_LEVEL
from ..solvers.parametric import parametric
from .results import FitError

__all__ = ["KKTProblem", "WINDOW", "BLEND", "KKT_ITERATIONS", "KKT_MAX_PERTURBATION",
           "ETA_MAX", "PRINT_LEVEL"]

#: The KKT fit lets a fit point move this many cells either way within one NLP.
WINDOW = 2
#: Overlap (in cell widths) over which the KKT fit blends neighbouring cells.
BLEND = 0.05
#: Ipopt iterations of each of the KKT fit's NLPs (tuned by scripts/bench_fit.py and the
#: synthetic campaign: what converging NLPs need, before a failing one costs much).
KKT_ITERATIONS = 60
#: Largest Hessian perturbation (inertia correction) of the KKT fit's NLPs: beyond it an
#: NLP has gone wild and fails fast (tuned on the synthetic campaign's NLPs).
KKT_MAX_PERTURBATION = 1e6
#: |η| stays below this in the KKT fit (the theory needs |η| < 1).
ETA_MAX = 0.98
#: Ipopt's print level in the KKT fit's NLPs (0: silent).
PRINT_LEVEL = 0


def _ramp(x):
    """C¹ smoothstep: 0 for x ≤ 0, 3x² − 2x³ between, 1 for x ≥ 1 (CasADi)."""
    x = ca.fmin(ca.fmax(x, 0), 1)
    return x * x * (3 - 2 * x)


@lru_cache(maxsize=4)
def _blended_point(stages: int) -> ca.Function:
    """``(u, t, first, last, keep) -> (r, z)``: one fit point blended over its window (SX).

    u holds, for the 2 WINDOW + 1 cells of the window, their unknowns
    (``cell_unknowns``), then their first and last nodes in s, z and the
    deformed arclength S at their first nodes, then the shell's total S; the
    point sits at S = t S_total.  Each cell's evaluation has a C¹ weight that
    is 1 inside the cell and falls to 0 across an overlap of BLEND cell widths
    around its boundaries: the midline is only continuous across cell
    boundaries (the cell polynomials agree in value, to O(Δs^(S+1)), not in
    slope), and a fit point resting on a node would make E_fit(θ) kinked
    there, where stationarity stalls.  Cells
    flagged ``first`` (``last``) keep their weight below (above) themselves:
    the shell's first and last cells, for targets beyond its ends, and the
    window's outermost ones (:meth:`KKTProblem._window_indices`).  A clipped
    window repeats a cell, counted once (``keep``).
    """
    from ..numerics import arclength_point, collocation

    n_w, n_z = 2 * WINDOW + 1, 3 * stages + 2
    u = ca.SX.sym("u", n_w * (n_z + 4) + 1)
    t, first, last, keep = (ca.SX.sym(nm, n) for nm, n in
                            (("t", 1), ("first", n_w), ("last", n_w), ("keep", n_w)))
    Z = ca.reshape(u[:n_w * n_z], n_z, n_w)
    lo, hi, z0, S0 = (u[n_w * (n_z + i):n_w * (n_z + i + 1)] for i in range(4))
    target = u[-1] * t
    point = arclength_point(stages)
    gauss = ca.DM(collocation(stages)[1])
    num_r = num_z = den = 0
    for o in range(n_w):
        _, r_o, _, z_o = point(Z[:, o], lo[o], hi[o] - lo[o], z0[o], S0[o], target)
        # where the point lies in the cell, from the linear interpolant of S:
        # for a target cells away, Newton's iteration can end inside the cell
        # on a wrong root, which must get no weight
        S1 = S0[o] + (hi[o] - lo[o]) * ca.dot(gauss, Z[2 * stages + 2:, o])
        tau = (target - S0[o]) / (S1 - S0[o])
        weight = (ca.fmax(_ramp((tau + BLEND) / (2 * BLEND)), first[o])
                  * ca.fmax(_ramp((1 + BLEND - tau) / (2 * BLEND)), last[o]) * keep[o])
        num_r, num_z, den = num_r + weight * r_o, num_z + weight * z_o, den + weight
    return ca.Function("blended_point", [u, t, first, last, keep],
                       [ca.vertcat(num_r / den, num_z / den)])


@lru_cache(maxsize=4)
def _point_misfit(stages: int) -> ca.Function:
    """``(u, t, first, last, keep, (R, Z)) -> (∂e/∂u, triu ∂²e/∂u²)`` (SX).

    e = ½|(r, z) − (R, Z)|² for one fit point: the exact Hessian of its
    squared misfit in its local unknowns (:func:`_blended_point`), far
    cheaper to evaluate than the MX Hessian of the assembled misfit.
    """
    f = _blended_point(stages)
    args = [f.sx_in(i) for i in range(f.n_in())]
    data = ca.SX.sym("data", 2)
    e = 0.5 * ca.sumsqr(f(*args) - data)
    u = args[0]
    H = ca.hessian(e, u)[0]
    ku, lu = np.triu_indices(u.shape[0])
    return ca.Function("point_misfit", [*args, data],
                       [ca.gradient(e, u), ca.vertcat(*[H[int(i), int(j)]
                                                        for i, j in zip(ku, lu)])])


@lru_cache(maxsize=4)
def _compiled_misfit(stages: int) -> ca.Function:
    """:func:`_point_misfit` compiled for evaluation (at ``-O1``: -O2 compiles too slowly)."""
    return compiled_point_function(_point_misfit(stages), LARGE)


class KKTProblem:
    """The fit as one NLP, solved by Newton's method (Ipopt, exact Hessian).

    Unknowns w = (θ, x, λ, Z, Σ): the fitted parameters, the inner unknowns
    and multipliers, and z and the deformed arclength at the cell boundaries,
    lifted into variables with one constraint per cell (so that each fit
    point depends on its own cell only and every matrix stays sparse).
    Constraints: the inner KKT conditions F(x, λ; p(θ)) = 0, the cell
    integrals of z' = f_s sin ψ and S' = f_s, the breakpoints ordered at least
    σ apart inside the shell, |η| ≤ ETA_MAX; bounds on θ.  The Hessian of
    the Lagrangian is exact (:meth:`_hessian`: Gauss–Newton approximations
    of it made the reduced Hessian indefinite or its steps diverge).  Which
    cell holds each fit point is structural: the NLP is rebuilt (cheaply)
    when points change cells.

    Parameters
    ----------
    spec : FitSpec
        What is fitted.
    inner : InnerProblem
        The fit's inner problem (its solver, mesh, data and current state).
    tol : float
        Ipopt's tolerance.
    max_iterations : int or None
        Ipopt iterations of each NLP (default :data:`KKT_ITERATIONS`).
    mu_init : float
        Ipopt's initial barrier parameter.
    adjoint_duals : bool
        Start the first NLP from the reduced problem's adjoints
        (:meth:`_adjoint_duals`) instead of zero multipliers.
    """

    def __init__(self, spec, inner, tol, max_iterations, mu_init: float = 1e-6,
                 adjoint_duals: bool = False):
        self.spec, self.inner, self.tol = spec, inner, tol
        self.max_iter = max_iterations or KKT_ITERATIONS
        self.mu_init = mu_init
        # The first NLP starts from zero multipliers, or from the reduced
        # problem's adjoints (``adjoint_duals``; later NLPs carry theirs over).
        self.from_adjoints = adjoint_duals
        self.scale = 1.0
        self.cells: tuple | None = None
        self._duals: tuple | None = None

    def _build(self, cells: tuple, scale: float = 1.0) -> None:
        """The NLP with the fit points in ``cells``: unknowns, constraints and their bounds,
        the exact constraint Jacobian and Hessian of the Lagrangian, and its Ipopt solver."""
        from ..model.layouts import CELL_DATA

        spec, inner = self.spec, self.inner
        solver = inner.solver
        d = solver.disc
        k, nc, n = len(spec.fitted), d.layout.cells, inner.n
        th = ca.MX.sym("theta", k)
        x = ca.MX.sym("x", d.layout.size)
        lam = ca.MX.sym("lam", d.g.shape[0])
        zc, sc = ca.MX.sym("z_cells", nc + 1), ca.MX.sym("S_cells", nc + 1)
        values = spec.params(th)
        layout = spec.base.parameter_layout
        base = spec.base.parameter_vector()
        p = ca.vertcat(*[values[nm] if nm in values else float(base[i])
                         for i, nm in enumerate(layout.names)])
        q = ca.DM.zeros(0, 1)
        P = parametric(solver)
        F = P.kkt_residual(x, lam, p, q)
        sh = d.shape(x, p, q)
        dz, dS = sh.increments()
        lifted = ca.vertcat(zc[0], zc[1:] - zc[:nc] - dz, sc[0], sc[1:] - sc[:nc] - dS)
        # Each point may lie in a window of cells around its assigned one, the
        # cells' evaluations blended (:func:`_blended_point`).
        t_fit = np.linspace(0, 1, n)
        u_idx, flags = self._window_indices(cells, nc, d.layout.size, d.cell_index)
        U = ca.vertcat(sh.s_nodes, x, zc, sc)           # what the residuals depend on
        Uext = ca.vertcat(U, ca.DM([0.0, 0.0, np.pi]))   # the pole's constant r, ψ
        local = ca.reshape(Uext[u_idx.ravel(order="F").tolist()], u_idx.shape[0], n)
        blended = _blended_point(d.stages).map(n)
        rz = blended(local, ca.DM(t_fit).T, *(ca.DM(f) for f in flags))
        # the data are the NLP's parameter, not constants in its graph
        target = ca.MX.sym("data", 2 * n)         # (r, z) point by point
        res = ca.vec((rz - ca.reshape(target, 2, n)).T)
        ineq, glo, ghi = [], [], []
        if spec.base.family == "volvox":
            named = layout.unpack(p)
            s = [named[f"s{i}"] for i in range(1, 5)]
            for a, b in zip([0.0, *s], [*s, spec.base.end]):
                ineq.append(b - a)
                glo.append(float(spec.base.params["sigma"])), ghi.append(np.inf)
        eta = ca.reshape(d.pre(p, q), len(CELL_DATA), -1)[CELL_DATA.index("eta"), :].T
        g = ca.vertcat(F, lifted, *ineq, eta)
        self.lbg = np.concatenate([np.zeros(F.shape[0] + lifted.shape[0]), glo,
                                   -ETA_MAX * np.ones(eta.shape[0])])
        self.ubg = np.concatenate([np.zeros(F.shape[0] + lifted.shape[0]), ghi,
                                   ETA_MAX * np.ones(eta.shape[0])])
        w = ca.vertcat(th, x, lam, zc, sc)
        jac_g = ca.Function("jac_g", [w, target],
                            [g, self._constraint_jacobian(d, th, x, lam, p, q, w, lifted, ineq)],
                            ["x", "p"], ["g", "jac_g_x"])
        box_lo, box_hi = spec.box()
        free = np.inf * np.ones(w.shape[0] - k)
        self.lbw, self.ubw = np.concatenate([box_lo, -free]), np.concatenate([box_hi, free])
        sigma, mult = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", g.shape[0])
        H = self._hessian(d, P, th, x, lam, p, q, sh, local, t_fit, flags, u_idx, w, sigma, mult,
                          F.shape[0], ineq, target)
        hess = ca.Function("hess_lag", [w, target, sigma, mult], [H],
                           ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])
        problem = {"x": w, "p": target, "f": 0.5 * ca.sumsqr(res), "g": g}
        self.lagrangian = (w, target, sigma, mult, problem["f"], g, hess, jac_g)  # (for tests)
        self._jac_g, self._n_eq = jac_g, F.shape[0] + lifted.shape[0]     # (rows of g first)
        self.nlp = self._ipopt(problem, hess, jac_g)
        self.sizes = (k, d.layout.size, d.g.shape[0])
        self.cells = cells

    def _ipopt(self, problem: dict, hess: ca.Function, jac_g: ca.Function) -> ca.Function:
        """The NLP ``problem`` as an Ipopt solver with the exact ``hess`` and ``jac_g``."""
        load_ipopt()      # (solvers no longer load it on construction: Newton may do without)
        return ca.nlpsol("kkt_fit", "ipopt", problem, {
            # the start is an equilibrium, feasible and usually close: a small
            # initial barrier keeps the inactive |eta| bounds from slowing it
            # down (the adaptive update raised it again after warm starts)
            # The midline is only continuous across cell boundaries (the cell
            # polynomials agree in value, not slope): a fit point resting on a
            # node sits on a kink of E_fit(θ), where stationarity stalls.  Stop
            # when the misfit no longer changes (relative to the start's: the
            # objective is scaled to 1 there) over 3 iterations while the
            # equilibrium holds to 1e-9 (both tuned by scripts/bench_fit.py and the
            # KKT campaign: a looser violation lost campaign fits, more iterations
            # cost time).
            "ipopt": {"print_level": PRINT_LEVEL, "sb": "yes", "tol": self.tol,
                      "max_iter": self.max_iter, "mu_init": self.mu_init,
                      "acceptable_tol": 1e-2, "acceptable_iter": 3,
                      "acceptable_obj_change_tol": 1e-9, "obj_scaling_factor": self.scale,
                      "acceptable_constr_viol_tol": 1e-9,
                      "warm_start_init_point": "yes",
                      # A start on a bound of θ (Gauss-Newton steps that ended on a
                      # breakpoint's box) stays there: pushed inside, it would leave
                      # the equilibrium, and restoration phases follow.  Starts
                      # farther inside are not moved either way.
                      "warm_start_bound_push": 1e-9, "warm_start_bound_frac": 1e-9,
                      "mumps_scaling": 0, "mumps_permuting_scaling": 0, "mumps_pivot_order": 0,
                      # An NLP that needs a large Hessian perturbation has gone wild
                      # (converging ones need at most 1): fail, and let kkt_fit start
                      # again from the reduced optimum.
                      "max_hessian_perturbation": KKT_MAX_PERTURBATION},
            "hess_lag": hess, "jac_g": jac_g, "print_time": False, "error_on_fail": False,
            # (the data's multipliers are never used: CasADi computed them after
            # every solve through the whole graph, and on the KKT campaign warned
            # "Failed to calculate multipliers" where that evaluation failed)
            "calc_lam_p": False,
            # a trial point outside the energy's domain evaluates to NaN and
            # Ipopt backtracks: CasADi's "NaN detected" lines said nothing to act on
            "show_eval_warnings": False})

    @staticmethod
    def _window_indices(cells, nc: int, n: int, idx: np.ndarray) -> tuple:
        """Where each fit point's local unknowns (:func:`_blended_point`) sit in U.

        U = (s at the nodes, x, z and S at the cell boundaries) then the
        pole's three constants; returns the (local × points) indices and the
        points' first/last/keep flags (windows × points).  A point that moves
        beyond its window is evaluated on the window's outermost cell (flagged
        first/last), not on weights that vanish there: with the exact Hessian
        the fine stage would stall at that edge.  It is then rebuilt with the
        point's new cell, as whenever a point leaves its window.
        """
        n_U = (nc + 1) + n + 2 * (nc + 1)
        x_at = np.where(idx < n, (nc + 1) + idx, n_U + idx - n)     # constants after U
        cols, first, last, keep = [], [], [], []
        offsets = range(-WINDOW, WINDOW + 1)
        for c in cells:
            window = [min(max(c + o, 0), nc - 1) for o in offsets]
            cols.append(np.concatenate([x_at[:, window].ravel(order="F"), window,
                                        [i + 1 for i in window],
                                        [(nc + 1) + n + i for i in window],
                                        [2 * (nc + 1) + n + i for i in window],
                                        [2 * (nc + 1) + n + nc]]))
            first.append([float(i == 0 or o == -WINDOW) for o, i in zip(offsets, window)])
            last.append([float(i == nc - 1 or o == WINDOW) for o, i in zip(offsets, window)])
            keep.append([float(o == 0 or i != min(max(c, 0), nc - 1))
                         for o, i in zip(offsets, window)])
        return (np.array(cols, dtype=np.int64).T,
                tuple(np.array(f).T for f in (first, last, keep)))

    def _hessian(self, d, P, th, x, lam, p, q, sh, local, t_fit, flags, u_idx, w, sigma, mult,
                 nF: int, ineq, target) -> ca.MX:
        """Upper triangle of the exact Hessian of the Lagrangian σ ½|res|² + μ·g.

        Exact, not Gauss–Newton: near the optimum the misfit's and the
        constraints' second-order terms, each large, cancel, so that
        Gauss–Newton for the misfit (with or without the inner KKT
        conditions' curvature in (x, λ)) gets the reduced Hessian's weak
        directions wrong, even its sign, and its steps crawl or diverge.
        Assembled from per-point and per-cell kernels and the chain rule
        through s_nodes(θ) and D(θ), the kernels compiled (the misfit's, the
        cells' second derivatives in D, and D's in p): several times faster
        than the same kernels in CasADi's virtual machine, and far faster
        than the MX Hessian of the whole Lagrangian.
        """
        from ..model.layouts import CELL_DATA

        k, n, m = th.shape[0], x.shape[0], lam.shape[0]
        nc = d.layout.cells
        n_w, n_U, n_pt = w.shape[0], (nc + 1) + n + 2 * (nc + 1), local.shape[1]
        grad, tri = _compiled_misfit(d.stages).map(n_pt)(
            local, ca.DM(t_fit).T, *(ca.DM(f) for f in flags), ca.reshape(target, 2, n_pt))
        # the misfit's Hessian in U (local duplicates of one unknown: a local
        # off-diagonal pair on U's diagonal counts twice)
        n_loc = u_idx.shape[0]
        ku, lu = np.triu_indices(n_loc)
        I, J = np.minimum(u_idx[ku], u_idx[lu]), np.maximum(u_idx[ku], u_idx[lu])
        src = np.arange(len(ku))[:, None] + len(ku) * np.arange(n_pt)[None, :]
        ok = J < n_U
        twice = (I == J) & (ku != lu)[:, None]
        sp, B = scatter((n_U, n_U), I[ok], J[ok], src[ok], len(ku) * n_pt,
                           np.where(twice, 2.0, 1.0)[ok])
        Hu = ca.MX(sp, ca.mtimes(B, ca.vec(tri)))
        Hu = Hu + Hu.T - ca.diag(ca.diag(Hu))
        # U in terms of w = (θ, x, λ, z, S): s_nodes(θ), the rest selected
        E = ca.vertcat(ca.horzcat(ca.jacobian(sh.s_nodes, th), ca.MX(nc + 1, n_w - k)),
                       ca.horzcat(ca.MX(n, k), ca.MX.eye(n), ca.MX(n, n_w - k - n)),
                       ca.horzcat(ca.MX(2 * nc + 2, k + n + m), ca.MX.eye(2 * nc + 2)))
        on_s = u_idx < nc + 1
        sp_s, Bs = scatter((nc + 1, 1), u_idx[on_s], np.zeros(on_s.sum()),
                              (np.arange(n_loc)[:, None] + n_loc * np.arange(n_pt))[on_s],
                              n_loc * n_pt)
        g_nodes = ca.densify(ca.MX(sp_s, ca.mtimes(Bs, ca.vec(grad))))
        # the constraints: F and the lifted integrals through D(θ) per cell
        D, T, Jp, D_p = self._cell_data_theta(d, th, p, q)
        C, tt, gD = d.kkt_curvature_theta(x, lam, D, T, mult[:nF], mult[nF + 1:nF + 1 + nc],
                                          mult[nF + nc + 2:nF + 2 * nc + 2])
        H_xl = d.kkt_curvature(x, lam, D, mult[:nF], mult[nF + 1:nF + 1 + nc],
                               mult[nF + nc + 2:nF + 2 * nc + 2],
                               sh.s_nodes[1:] - sh.s_nodes[:nc])
        n_eta, n_D = D.shape[0] // len(CELL_DATA), len(CELL_DATA)
        eta_at = CELL_DATA.index("eta") + n_D * np.arange(n_eta)
        mu_ineq = mult[nF + 2 * nc + 2:mult.shape[0] - n_eta]
        # ... and the second derivatives of D, s_nodes and the breakpoint gaps
        # in θ: D's through p (Discretisation.pre_hessian), p's, s_nodes' and
        # the gaps' by an MX Hessian with D's gradient in p (g_p) held fixed
        ci, cs, g_p = (ca.MX.sym(nm, size) for nm, size in
                       (("c_i", len(ineq)), ("c_s", nc + 1), ("g_p", p.shape[0])))
        omega = (ca.dot(g_p, p) + ca.dot(cs, sh.s_nodes)
                 + (ca.dot(ci, ca.vertcat(*ineq)) if ineq else 0))
        rest = ca.Function("theta_curvature", [th, g_p, ci, cs], [ca.hessian(omega, th)[0]])
        c_D = gD + ca.MX(ca.Sparsity.triplet(D.shape[0], 1, eta_at.tolist(), [0] * n_eta),
                         mult[mult.shape[0] - n_eta:])
        H_tt = (tt + ca.mtimes(Jp.T, ca.mtimes(d.pre_hessian(p, q, c_D), Jp))
                + rest(th, ca.mtimes(D_p.T, c_D), mu_ineq, sigma * g_nodes))
        Hw = sigma * ca.mtimes(E.T, ca.mtimes(Hu, E))
        top = ca.horzcat(ca.triu(H_tt), C.T, ca.MX(k, n_w - k - n - m))
        rest = ca.diagcat(H_xl, ca.MX(n_w - k - n - m, n_w - k - n - m))
        return ca.triu(Hw) + ca.vertcat(top, ca.horzcat(ca.MX(n_w - k, k), rest))

    @staticmethod
    def _constraint_jacobian(d, th, x, lam, p, q, w, lifted, ineq):
        """∂g/∂w for g = (F, lifted integrals, breakpoint gaps, η), from local pieces.

        The inner KKT block K = ∂F/∂(x, λ) and ∂F/∂θ = (∂F/∂D) T come from the
        cell kernels, η's rows from T = ∂D/∂θ (computed once); the lifted
        integrals and the gaps are differentiated as they are, each on its own
        (a slice of the assembled g drags all of g into its derivative, and
        differentiating F through its graph is slower still).
        """
        from ..model.layouts import CELL_DATA

        D, T, *_ = KKTProblem._cell_data_theta(d, th, p, q)
        Ht = d.hess_lag(x, D, 1, lam)
        J = d.jac_g(x, D)[1]
        K = ca.blockcat([[Ht + Ht.T - ca.diag(ca.diag(Ht)), J.T],
                         [J, ca.MX(J.shape[0], J.shape[0])]])
        k, nxl = th.shape[0], x.shape[0] + lam.shape[0]
        n_rest = w.shape[0] - k - nxl
        top = ca.horzcat(d.kkt_residual_theta(x, lam, D, T), K, ca.MX(nxl, n_rest))
        n_D = len(CELL_DATA)
        eta_rows = (CELL_DATA.index("eta") + n_D * np.arange(D.shape[0] // n_D)).tolist()
        eta = ca.horzcat(T[eta_rows, :], ca.MX(len(eta_rows), w.shape[0] - k))
        return ca.vertcat(top, ca.jacobian(ca.vertcat(lifted, *ineq), w), eta)

    @staticmethod
    def _cell_data_theta(d, th, p, q) -> tuple:
        """D(p(θ)), T = ∂D/∂θ, ∂p/∂θ and ∂D/∂p, for evaluation (no derivatives).

        D and ∂D/∂p from compiled per-point kernels (Discretisation.pre_numeric
        and pre_jacobian), not the MX Jacobian of D in θ: it is evaluated twice
        per iteration (Hessian and constraint Jacobian).
        """
        Jp, D_p = ca.jacobian(p, th), d.pre_jacobian(p, q)
        return d.pre_numeric(p, q), ca.mtimes(D_p, Jp), Jp, D_p

    def _lifted_start(self, theta, x) -> np.ndarray:
        """z and S at the cell boundaries of the state x (gauge: 0 at the first node)."""
        d = self.inner.solver.disc
        p = self.spec.problem(theta).parameter_vector()
        if not hasattr(self, "_points"):
            pts = d.symbolic_points(d.x, d.p, d.q)
            self._points = ca.Function("zS", [d.x, d.p, d.q], [pts["z"], pts["S"]])
        z, S = (np.asarray(v).ravel()[::d.stages] for v in self._points(x, p, np.zeros(0)))
        return np.concatenate([z - z[0], S])

    def _adjoint_duals(self, w0, data) -> tuple | None:
        """The multipliers at w₀ of the reduced problem: its adjoints, (λ_g, λ_x).

        At an equilibrium the equality constraints (F and the lifted
        integrals) are square in the unknowns other than θ: their multipliers
        make the Lagrangian stationary there, ∂f/∂u + (∂g/∂u)ᵀλ = 0, which
        leaves the reduced gradient in θ as the only dual infeasibility.  The
        inequalities (breakpoint gaps, |η|) and θ's bounds start inactive.
        Ipopt's least-squares estimate instead spreads the misfit's gradient
        over all rows: from the Gauss–Newton end its first step leaves the
        equilibrium, and backtracks and the restoration phase follow.
        """
        from scipy.sparse.linalg import splu

        k, n_eq = self.sizes[0], self._n_eq
        _, grad = self.nlp.get_function("nlp_grad_f")(w0, data)
        J = self._jac_g(w0, data)[1].sparse().tocsc()
        lam_g = np.zeros(J.shape[0])
        try:
            lam_g[:n_eq] = splu(J[:n_eq, k:].T.tocsc()).solve(-np.asarray(grad).ravel()[k:])
        except RuntimeError:        # singular (a fold of the branch): from zero multipliers
            return None
        return (lam_g, np.zeros(J.shape[1])) if np.all(np.isfinite(lam_g)) else None

    def solve(self, cells, theta, x, lam, data=None):
        """One NLP from (θ, x, λ) with the fit points in ``cells``, to ``data``.

        Rebuilt when the cells changed; the multipliers carry over from the
        last NLP (the first starts from the adjoints or from zero).

        Parameters
        ----------
        cells : tuple of int, length N
            The cell of each fit point (the centre of its window).
        theta : ndarray, shape (k,)
            The fitted parameters to start from.
        x, lam : ndarray
            The inner unknowns and multipliers to start from (an equilibrium
            at θ).
        data : ndarray, shape (N, 2), optional
            The target midline (default: the fit's).

        Returns
        -------
        theta : ndarray, shape (k,)
        x : ndarray, shape (n_x,)
        lam : ndarray, shape (n_λ,)
            The NLP's end.
        iterations : int
            Ipopt's iterations.
        status : str
            Ipopt's return status.

        Raises
        ------
        FitError
            Ipopt did not succeed (status and the inner state attached).
        """
        warm = {}
        if cells != self.cells:
            if self.cells is None:       # the misfit at the start sets the objective's scale
                res = self.inner.residuals(self.inner.eq)
                # (floored: after the Gauss-Newton steps' exact fit of noiseless data
                # the NLP so scaled fails in restoration)
                self.scale = 1.0 / max(0.5 * float(res @ res), 1e-8)
            self._build(cells)
        w0 = np.concatenate([theta, x, lam, self._lifted_start(theta, x)])
        data = np.asarray(self.inner.data if data is None else data, dtype=float).ravel()
        if self._duals is None and self.from_adjoints:
            self._duals = self._adjoint_duals(w0, data)
        if self._duals is not None:
            # the constraints do not depend on the cells: their multipliers
            # carry over (a cold dual start takes wild first steps)
            warm = {"lam_g0": self._duals[0], "lam_x0": self._duals[1]}
        sol = self.nlp(x0=w0, p=data, lbx=self.lbw,
                       ubx=self.ubw, lbg=self.lbg, ubg=self.ubg, **warm)
        self._duals = (np.asarray(sol["lam_g"]).ravel(), np.asarray(sol["lam_x"]).ravel())
        stats = self.nlp.stats()
        status = ipopt_status(stats)
        if status not in (SOLVE_SUCCEEDED, SOLVED_TO_ACCEPTABLE_LEVEL):
            raise FitError(f"the KKT fit's NLP failed with Ipopt status {status!r} after "
                           f"{stats.get('iter_count')} iterations", status, self.inner.eq)
        w = np.asarray(sol["x"]).ravel()
        k, nx, nl = self.sizes
        return (w[:k], w[k:k + nx], w[k + nx:k + nx + nl], int(stats.get("iter_count", 0)),
                status)
