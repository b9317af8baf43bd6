"""Fitted shapes of a campaign, and their numerical ablation.

A campaign record (:func:`morphoshell.workflows.campaigns.campaign`) holds the
fitted parameters and the fitted equilibrium's fields: :func:`fitted_problem`
and :func:`fitted_state` turn them back into a problem and a start.  The paper
ablates the fitted shapes numerically (Materials and Methods: "the value of Σ
was increased from Σ = 0 in these fitted shapes"; main text, Fig. 3 M):
:func:`numerical_ablation` continues in the cut Σ from 0 (the fitted, intact
shell) to the cut size, with the adaptive, jump-rejecting steps of
:func:`morphoshell.solvers.continuation.continue_between`, the observables of
:func:`morphoshell.mechanics.ablation.ablate`, and a check against a cold solve
at the final Σ on the same mesh, and a look for walls that pass through each
other before and after the cut (the model has no self-contact: a fit that
stopped near a fold, or a cut that sends the shell to another branch, can end
in such a shape, which :func:`~morphoshell.solvers.routes.solve` would warn
of); :func:`ablation_errors` propagates the fit's covariance to the recoil
observables.  Lengths in units of R, energies in C R².
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, replace
from types import SimpleNamespace

import numpy as np

from .._runtime.validate import flag, integer, real, short
from ..fitting.bilevel import FIT_NODES
from ..io.problem_files import fit_source, problem_of_record
from ..mechanics.ablation import Ablation, ablation_of, intact_problem, recoil_jacobian
from ..model.problem import Problem
from ..numerics.mesh import mesh_spec
from ..solvers.contact import WallContact, warn_if_walls_overlap
from ..solvers.continuation import continue_between
from ..solvers.direct import DirectSolver
from ..solvers.observables import RECOIL
from ..solvers.options import check_problem
from ..solvers.refinement import refine, solve_from
from ..solvers.results import Equilibrium, SolverError
from ..solvers.routes import direct_solver, solve

__all__ = ["NumericalAblation", "numerical_ablation", "ablation_errors", "fitted_problem",
           "TracesNoise",
           "off_the_fit", "OFF_THE_FIT", "FitUncertainty", "fit_uncertainty", "PROFILE_WIDER",
           "fitted_state", "CUT"]

log = logging.getLogger(__name__)

#: Default cut Σ of numerical ablations (units of R): the experiments removed cells
#: within 3–6 µm of the pole of embryos of posterior radius ≈ 40 µm (Materials and Methods).
CUT = 0.15
#: First cut of the Σ continuation, as a fraction of the final one (the cap removed
#: from the intact shell in one step; continue_between then grows it adaptively):
#: the smallest of these that the final mesh holds.
_FIRST_CUTS = (0.125, 0.25, 0.5, 0.75, 0.875, 1.0)
#: The fields of a fitted equilibrium that a record stores (its ``state``).
_FIELDS = ("s", "r", "psi", "f_s")


def fitted_problem(record: dict, where: str | None = None) -> Problem:
    """The problem of a fit: a record of ``morphoshell fit --json`` or of a campaign.

    Parameters
    ----------
    record : dict
        A successful fit's record, e.g. ``json.load(open("fit.json"))``: its
        ``problem`` and ``parameters``, which must agree
        (:func:`morphoshell.io.problem_files.problem_of_record`).
    where : str, optional
        The file, for messages; default: ``<timepoint>_<variant>``
        of a campaign's record, else "the fit's record" (a warning about one
        of a campaign's fits must say which).

    Returns
    -------
    Problem
        The fitted shell, named ``<timepoint>_<variant>`` for a campaign's
        record (else as the fit named it).

    Raises
    ------
    ValueError
        A failed fit's record, or one whose two copies of the parameters
        disagree (the entry named).

    Notes
    -----
    A fit that did not converge is read with a warning
    (:func:`morphoshell.io.problem_files.fit_source`): its shell is where the
    fit stopped.
    """
    named = "timepoint" in record and "variant" in record
    if where is None:
        where = (f"{record['timepoint']}_{record['variant']}" if named
                 else "the fit's record")
    if record.get("status", "ok") != "ok":
        raise ValueError(f"{where}: the fit failed ({record.get('message', 'no message')}): "
                         f"it has no fitted shell")
    problem = problem_of_record(record, where)
    fit_source(record, where)       # (a warning if the fit did not converge)
    if named:
        problem = replace(problem, name=f"{record['timepoint']}_{record['variant']}")
    return problem


#: A re-solved fit whose fit points lie farther than this (units of R) from the record's
#: fitted midline is another equilibrium of the fitted parameters: the continuation from the
#: stress-free shell took another branch than the fit's (audit 24: a campaign's t08 free fit
#: re-solved 1.02 R away; re-solves on the fit's branch agreed to 7e-5 R at 100 and 200 nodes).
OFF_THE_FIT = 0.01


def off_the_fit(eq: Equilibrium, record: dict, where: str) -> float:
    """How far (units of R) the fit points of ``eq``, the fitted shell solved again, lie from
    the record's ``fitted_midline``; a warning above :data:`OFF_THE_FIT`.

    ``morphoshell solve FIT.json`` and ``ablate FIT.json`` solve the fitted parameters from
    the stress-free shell, which can end on another branch than the fit's; a campaign's
    record keeps the fitted state to stay on it (``numerical_ablation(...,
    pre=fitted_state(record))``).

    Parameters
    ----------
    eq : Equilibrium
        A direct solution of the record's problem (intact: no cut).
    record : dict
        The fit's record, with its ``fitted_midline``.
    where : str
        The record's file, for the warning.
    """
    from ..fitting.inner import model_midline

    fitted = np.column_stack([record["fitted_midline"][c] for c in "rz"]).astype(float)
    distance = float(np.max(np.hypot(*(model_midline(eq, len(fitted)) - fitted).T)))
    if distance > OFF_THE_FIT:
        log.warning("%s: the shell solved from the fitted parameters is not the fitted one: its "
                    "midline lies up to %.3g R from the fit's (another equilibrium of the same "
                    "parameters, reached from the stress-free shell); its numbers are not the "
                    "fit's%s", where, distance,
                    "; start from the record's state: numerical_ablation(..., "
                    "pre=fitted_state(record))" if "state" in record else "")
    return distance


def fitted_state(record: dict) -> SimpleNamespace:
    """The fitted equilibrium's fields s, r, ψ, f_s at its points (units of R, rad).

    Enough to start a solve on any mesh on the fit's branch
    (:func:`~morphoshell.solvers.refinement.solve_from`, ``numerical_ablation(pre=...)``).

    Parameters
    ----------
    record : dict
        A campaign record with its ``state``.

    Returns
    -------
    types.SimpleNamespace
        Attributes ``s``, ``r``, ``psi``, ``f_s`` : ndarray, shape (N,), at
        the N points of the fit's equilibrium.
    """
    return SimpleNamespace(**{k: np.asarray(record["state"][k], dtype=float) for k in _FIELDS})


@dataclass(frozen=True, eq=False)
class NumericalAblation:
    """A numerical ablation reached by continuation in Σ, and its check.

    Attributes
    ----------
    ablation : Ablation
        Pre-ablation (the intact, fitted shell), post-ablation (at the final
        Σ) and the observables of :func:`morphoshell.mechanics.ablation.ablate`.
    steps, rejected : int
        Accepted and retried steps of the continuation in Σ (after the first
        cut, the smallest of :data:`_FIRST_CUTS` of the final one that its mesh holds).
    cold : Equilibrium or None
        A cold solve at the final Σ on the same mesh (None if it failed).
    cold_difference : float
        max |x_continuation − x_cold| over the unknowns (NaN without a cold
        solution): a few 1e-8 when both reach the same equilibrium.
    contacts : dict
        ``"pre"`` and ``"post"``: where that shell's walls pass through each
        other (:func:`~morphoshell.solvers.contact.wall_contact`), or None.
        Such a shape is a minimum of the model, not a physical one (warned of,
        naming the problem).
    """

    ablation: Ablation
    steps: int
    rejected: int
    cold: Equilibrium | None
    cold_difference: float
    contacts: dict[str, WallContact | None]

    @property
    def walls_cross(self) -> bool:
        """Whether the walls of the pre- or the post-ablation shell pass through each other."""
        return any(c is not None for c in self.contacts.values())

    def observables(self) -> dict[str, float]:
        """The recoil observables (units: :data:`morphoshell.mechanics.ablation.UNITS`)."""
        return self.ablation.observables()

    def checks(self) -> dict[str, float | int | bool]:
        """How it was reached and checked: ``steps``, ``rejected``, ``cold_difference`` and
        ``walls_cross`` (the attributes of the same names)."""
        return {"steps": int(self.steps), "rejected": int(self.rejected),
                "cold_difference": float(self.cold_difference), "walls_cross": self.walls_cross}

    def to_dataframe(self):
        """The ablation as a one-row table
        (:meth:`~morphoshell.mechanics.ablation.Ablation.to_dataframe`: the problem, the
        observables and their ``<observable>_error``, as ``morphoshell ablate --csv``
        writes them), then the columns of :meth:`checks`; units in ``df.attrs["units"]``."""
        df = self.ablation.to_dataframe()
        for k, v in self.checks().items():
            df[k] = [v]
        return df

    def to_xarray(self):
        """The ablation as an xarray Dataset
        (:meth:`~morphoshell.mechanics.ablation.Ablation.to_xarray`: the observables, their
        errors and both equilibria), :meth:`checks` among its attributes (``walls_cross`` 0
        or 1).

        Needs the optional extra ``xarray`` (``pip install 'morphoshell[xarray]'``).
        """
        ds = self.ablation.to_xarray()
        ds.attrs.update({k: int(v) if isinstance(v, bool) else v
                         for k, v in self.checks().items()})
        return ds


def numerical_ablation(problem: Problem, cut: float = CUT, *, nodes: int = 200,
                       pre: Equilibrium | None = None, cold: bool = True) -> NumericalAblation:
    """Ablate a (fitted) shell by continuation in Σ from 0 to ``cut``.

    Materials and Methods ("For numerical ablations, the value of Σ was
    increased from Σ = 0 in these fitted shapes"): the intact shell (Σ = 0)
    is solved on a mesh with a node at s = Σ; its state starts the cut shell
    at Σ₀ = Σ/8 (or Σ/4, Σ/2, 3Σ/4 where the mesh needs it; interpolated,
    :func:`~morphoshell.solvers.refinement.solve_from`), which
    :func:`~morphoshell.solvers.continuation.continue_between` grows to Σ with
    adaptive steps that are retried smaller when they fail or jump.

    Parameters
    ----------
    problem : Problem
        The fitted shell (its cut is ignored: Σ = 0 before, ``cut`` after).
    cut : float
        The final Σ (units of R).
    nodes : int
        Mesh nodes of both states, within :data:`~morphoshell.fitting.bilevel.FIT_NODES`
        (20 to 3200), the fits' range.
    pre : Equilibrium or fields, optional
        The intact shell to carry onto the anchored mesh (an Equilibrium, or
        :func:`fitted_state` of a campaign record: the fit's branch); by
        default solved by continuation from the stress-free parameters.
    cold : bool
        Also solve the final Σ cold (from the solver's initial guess) on the
        same mesh, for :attr:`NumericalAblation.cold_difference`.

    Returns
    -------
    NumericalAblation
        Its ablation with the error estimates of :func:`~morphoshell.mechanics.ablation.ablate`
        (both final states solved again on the half and quarter meshes, as ``solve()`` does)
        and its warning where they exceed 0.1 of their values
        (:func:`~morphoshell.mechanics.ablation.ablation_of`: one rule for both routes).

    Raises
    ------
    TypeError
        ``problem`` is not a :class:`~morphoshell.model.problem.Problem`, ``pre`` neither
        an Equilibrium nor fields, ``cold`` not a bool.
    ValueError
        ``cut`` not a number or outside the shell, ``nodes`` not an integer in
        :data:`~morphoshell.fitting.bilevel.FIT_NODES`.

    Notes
    -----
    Both shells are looked at for walls that pass through each other, with a
    warning naming the problem (:attr:`NumericalAblation.contacts`): the
    continuation does not go through :func:`~morphoshell.solvers.routes.solve`,
    whose check it was (the unconverged flat fit of synthetic t07, ablated on
    200 nodes, jumped to a shape whose walls are 0.003 R apart against a
    thickness of 0.13 R, unwarned).
    """
    cut, nodes, cold = _checked(problem, cut, nodes, pre, cold)
    target = problem.with_updates(cut=cut)
    intact = intact_problem(target)
    if pre is None:
        pre = solve(intact, nodes=nodes, anchors=(cut,))
    else:
        anchored = DirectSolver(intact.structure, mesh=mesh_spec(intact, nodes, 2, (cut,)))
        pre = solve_from(anchored, intact, pre, anchors=(cut,))
    solver = DirectSolver(target.structure, mesh=mesh_spec(target, nodes, 2))
    post = continue_between(solver, _first_cut(solver, target, pre, cut), target, first_step=0.25)
    steps = int(post.solver.details.get("continuation_steps", 0))
    rejected = _rejected(post)
    cold_eq, diff = None, float("nan")
    if cold:
        try:
            cold_eq = solver.solve(target)
            diff = float(np.max(np.abs(cold_eq.x - post.x)))
        except SolverError:
            cold_eq = None
    pre, post = _estimated(pre, intact, (cut,)), _estimated(post, target, ())
    ab = ablation_of(target, pre, post)
    return NumericalAblation(ab, steps, rejected, cold_eq, diff, _contacts(problem.name, ab))


def _checked(problem, cut, nodes, pre, cold) -> tuple[float, int, bool]:
    """:func:`numerical_ablation`'s ``cut``, ``nodes`` and ``cold``, checked with ``problem``
    and ``pre`` before any work, each refused in one line naming it (audit 23: a string cut
    raised "'<' not supported", a string pre "'str' object has no attribute 's'", cold='no'
    solved cold, and nodes=99999, which solve()'s [5, 102400] let through, died of
    std::bad_alloc after 89 s).  ``nodes`` is held to the fits' range: the shells ablated
    are fits' (a campaign's, on at most 3200 nodes; memory and time by nodes in
    docs/benchmarks.md)."""
    check_problem(problem)      # (a string raised "'str' object has no attribute 'end'")
    cut = real("cut", cut)
    if not 0 < cut < problem.end:
        raise ValueError(f"cut = {cut!r} must lie inside the shell (0, {problem.end:.6g})")
    nodes = integer("nodes", nodes, *FIT_NODES)
    if pre is not None and not isinstance(pre, Equilibrium) and \
            not all(hasattr(pre, key) for key in _FIELDS):
        raise TypeError(f"pre = {short(pre)} must be an Equilibrium or fitted_state(record) "
                        f"(fields {', '.join(_FIELDS)}), not {type(pre).__name__}")
    return cut, nodes, flag("cold", cold)


def _estimated(eq: Equilibrium, problem: Problem, anchors: tuple) -> Equilibrium:
    """``eq`` with the error estimate ``solve()`` gives its results (the same problem on the
    half and the quarter mesh, from ``eq``: :func:`~morphoshell.solvers.refinement.refine`
    without a tolerance), unless it has one: the continuation in Σ and a ``pre`` carried
    over solve no coarser levels, and without them the ablation's errors were NaN and it
    did not warn where :func:`~morphoshell.mechanics.ablation.ablate` did (audit 21)."""
    if eq.error is not None:
        return eq
    return refine(eq, lambda n: direct_solver(problem, n, anchors), None, anchors)


def _contacts(name: str, ab: Ablation) -> dict[str, WallContact | None]:
    """Where the walls of the pre- and post-ablation shells pass through each other (or
    None), each warned of, naming the problem and the state."""
    who = f"{name}, " if name else ""
    return {key: warn_if_walls_overlap(getattr(ab, key), f"{who}{state} shell")
            for key, state in (("pre", "intact (pre-ablation)"),
                               ("post", f"post-ablation (Σ = {ab.problem.cut:g})"))}


def _first_cut(solver: DirectSolver, target: Problem, pre, cut: float) -> Equilibrium:
    """The cut shell at the smallest first cut of :data:`_FIRST_CUTS` that the mesh holds.

    The mesh's knots follow the breakpoints at fixed fractions of [Σ, π − P]:
    far below the final Σ the map to s can fold, so the first cut is the
    smallest fraction of it that the final mesh holds.
    """
    for fraction in _FIRST_CUTS:
        try:
            return solve_from(solver, target.with_updates(cut=fraction * cut), pre)
        except ValueError:
            continue
    raise ValueError(f"the mesh of the cut shell at Σ = {cut:g} cannot hold a first cut "
                     f"of {_FIRST_CUTS[-1]:g} Σ")


def _rejected(eq: Equilibrium) -> int:
    """Retried steps of a continuation, from its ``path`` ("... (n retried ...)"), else 0."""
    path = str(eq.solver.details.get("path", ""))
    try:
        return int(path.split("(")[1].split(" retried")[0])
    except (IndexError, ValueError):
        return 0


def ablation_errors(record: dict, ablation: Ablation) -> dict[str, float]:
    """Standard errors of the recoil observables of a fitted shape's ablation.

    The record's covariance C of the fitted parameters θ (its standard errors and
    correlations: Gauss–Newton's, or for a fit of one image trace its re-tracings', as its
    ``standard_errors_source`` says; lower bounds either way, the first as the residuals of
    a traced midline are correlated, the second as they hold the pixel noise only) propagated
    linearly, σ_y² = (J C Jᵀ)_yy, with J = dy/dθ the exact derivatives of the
    observables (:func:`~morphoshell.mechanics.ablation.recoil_jacobian`, through both
    equilibria) and the ``unstressed`` tie κ₁ = 1/f₁ (dκ₁/df₁ = −1/f₁²).
    Parameters pinned on a constraint or bound (no standard error in the
    record: :attr:`morphoshell.fitting.results.FitResult.pinned`) are held
    there: the errors are those of the fit given its active constraints, not
    NaN (the synthetic campaign ends 15 of 24 fits on one).

    Parameters
    ----------
    record : dict
        A successful fit's record, of a campaign or of ``morphoshell fit --json``
        (``fitted``, ``standard_errors``, ``correlation``, ``parameters``, ``variant``).
    ablation : Ablation
        The numerical ablation of its fitted shell (direct method, e.g.
        :func:`numerical_ablation` of :func:`fitted_problem`, or
        :func:`~morphoshell.mechanics.ablation.ablate`).

    Returns
    -------
    dict
        Observable name (:data:`morphoshell.solvers.observables.RECOIL`) → standard
        error (units of :data:`morphoshell.mechanics.ablation.UNITS`).

    Raises
    ------
    ValueError
        The record lacks an entry above or has no standard error at all; the ablated
        shell is not the record's (a parameter, h or the opening changed: the fit's
        covariance is that of its own shell); an ablation not solved by the direct method.
    """
    _check_error_inputs(record, ablation)
    names = list(record["fitted"])
    se = np.array([record["standard_errors"][n] for n in names], dtype=float)
    se = np.nan_to_num(se)                  # (None/NaN: pinned, held on its constraint)
    corr = np.nan_to_num(np.array(record["correlation"], dtype=float))
    np.fill_diagonal(corr, 1.0)
    cov = corr * np.outer(se, se)
    tied = record["variant"] == "unstressed"
    wrt = names + (["kappa1"] if tied else [])
    _, J = recoil_jacobian(ablation, wrt)
    if tied:
        f1 = record["parameters"]["f1"]
        J = J[:, :-1] + np.outer(J[:, -1], [(-1 / f1 ** 2) if n == "f1" else 0.0 for n in names])
    var = np.einsum("ij,jk,ik->i", J, cov, J)
    return {k: float(np.sqrt(max(v, 0.0))) for k, v in zip(RECOIL, var)}


#: Entries of a fit's record that :func:`ablation_errors` needs.
_ERROR_ENTRIES = ("fitted", "standard_errors", "correlation", "parameters", "variant")


def _check_error_inputs(record: dict, ablation: Ablation) -> None:
    """:func:`ablation_errors`' record and ablation, refused in one line where they cannot give
    the fit's errors (a problem's JSON or an old record lacked them: KeyError 'standard_errors';
    an ablation of another shell gave errors of the wrong one)."""
    missing = [k for k in _ERROR_ENTRIES if record.get(k) is None]
    if missing:
        raise ValueError(f"the record has no {', '.join(missing)}: the fit's errors need its "
                         f"standard errors and correlations (a record of `morphoshell fit "
                         f"--json` or of a campaign)")
    se = [record["standard_errors"].get(n) for n in record["fitted"]]
    if not any(v is not None and np.isfinite(v) for v in se):
        raise ValueError("the record has no standard error of a fitted parameter (all on "
                         "constraints, or none given)")
    p = ablation.problem
    values = {"h": p.h, "opening": p.opening, **p.params}
    for name, fitted in record["parameters"].items():
        # (the cut is the ablation's own; the record's floats are those of its shell, bit
        # for bit, so a relative 1e-12 only forgives a rewritten number's round-off)
        if name in values and not np.isclose(values[name], fitted, rtol=1e-12, atol=0):
            raise ValueError(f"the ablated shell is not the fitted one ({name} = "
                             f"{values[name]:.6g}, fitted {fitted:.6g}): the fit's errors are "
                             f"those of its own shell")


#: A profiled parameter whose interval is more than this many times as wide as its standard
#: error's (± z SE at the profile's confidence) is named beside the fit's errors of an
#: ablation: they are linear in those standard errors and miss that spread (audit 25: a free
#: fit's κ₁ interval [−0.95, 2.03] against ±0.11, 13 times as wide).  Up to 2 is the slack of
#: lower bounds (one trace's re-tracing errors were 1.3–1.8 times the Gauss–Newton ones; on
#: five-trace averages the recoil's spread was 1.9–3.7 times ± (fit), audit 28, most of it
#: the residual's σ²: :class:`TracesNoise`).
PROFILE_WIDER = 2.0

#: What :func:`fit_uncertainty`'s errors are.  Not the record's own ``note``: a fit of one
#: image trace records "Gauss-Newton lower bounds" beside the errors of its re-tracings.
_CARRIED = ("the fit's standard errors and correlations carried linearly into the recoil "
            "(sigma^2 = J C J^T, J the exact derivatives through both equilibria, the "
            "parameters on a constraint held there; none for the energies): lower bounds, as "
            "the fit's errors of a traced midline are")


@dataclass(frozen=True, eq=False)
class FitUncertainty:
    """A fit's uncertainty carried into its shell's ablation (:func:`fit_uncertainty`).

    Attributes
    ----------
    errors : dict
        Recoil observable → standard error (:func:`ablation_errors`; units
        :data:`~morphoshell.mechanics.ablation.UNITS`), {} where none could be carried.
    note : str
        What they are (linearised, from the record's standard errors and correlations: lower
        bounds, as these are), or why there are none.
    wider : dict
        Profiled parameter (the record's ``profile_intervals``) → its interval's width over
        that of ± z SE at the profile's confidence (inf where the interval is open), for those
        wider than :data:`PROFILE_WIDER`: where the recoil depends on them it is less
        determined than ``errors`` say.
    traces : TracesNoise or None
        ``errors`` at σ² from the spread of the traces of the averaged midline the fit was
        made to (:func:`fit_uncertainty` with ``data``), or None (no such data, or the
        record's errors are a single trace's re-tracings').
    """

    errors: dict[str, float]
    note: str
    wider: dict[str, float]
    traces: "TracesNoise | None" = None

    def columns(self) -> dict[str, float]:
        """``se_<observable>`` → :attr:`errors`: the names of ``ablate --csv``/``--json`` and of
        ``scripts/fig3_fits.py``'s ``fig3_ablations.json`` (as ``se_<parameter>`` of a
        campaign's summary); {} without errors."""
        out = {f"se_{k}": float(v) for k, v in self.errors.items()}
        if self.traces is not None:
            out.update({f"se_traces_{k}": v for k, v in self.traces.errors.items()},
                       t95_traces=self.traces.t95)
        return out


@dataclass(frozen=True)
class TracesNoise:
    """A fit's errors carried into an ablation at σ² from the traces' spread.

    The Gauss–Newton covariance takes σ² from the residual, E_fit²/(2N − k); on an average
    of n traces the profiles and the hypothesis test take it from the traces' spread
    (:func:`~morphoshell.fitting.profile_noise.traces_and_residual`), typically 3 times as
    large, with n − 1 degrees of freedom.  On 40 + 26 synthetic five-trace averages (audit
    28) ± 1.96 (fit) covered the true recoil 0.45–0.81 of the time; these errors with
    ± t₀.₉₇₅(n − 1) covered it 0.88–1.00.

    Attributes
    ----------
    sigma2_traces, sigma2_residual : float
        The two σ² (units of R²).
    dof : float
        n − 1, the traces' degrees of freedom.
    errors : dict
        Recoil observable → standard error: the record's carried errors times
        √(σ²_traces/σ²_residual).
    """

    sigma2_traces: float
    sigma2_residual: float
    dof: float
    errors: dict[str, float]

    @property
    def t95(self) -> float:
        """t₀.₉₇₅(dof): a 95 % interval is ± this many of :attr:`errors`."""
        from ..inverse.summaries import t_quantile

        return t_quantile(self.dof + 1)

    def text(self) -> str:
        """What the errors are, in one line."""
        ratio = self.sigma2_traces / self.sigma2_residual
        return (f"+- (traces): the (fit) errors at sigma^2 from the spread of {self.dof + 1:g} "
                f"traces, as the profiles and compare take it: {ratio:.3g} times the "
                f"residual's sigma^2 of the Gauss-Newton errors, so {np.sqrt(ratio):.3g} times "
                f"(fit); a 95% interval is +- t(0.975, {self.dof:g}) = {self.t95:.4g} of "
                f"these (on synthetic averages of 5 traces they covered the truth 0.88-1.00 "
                f"of the time, +- 1.96 (fit) 0.45-0.81)")

    def to_dict(self) -> dict:
        """JSON-ready: both σ², the dof, the t factor and the errors."""
        return {"sigma2_traces": self.sigma2_traces, "sigma2_residual": self.sigma2_residual,
                "sigma2_units": "R^2", "dof": self.dof, "t95": self.t95,
                "errors": dict(self.errors), "note": self.text()}


def fit_uncertainty(record: dict, ablation: Ablation, data=None) -> FitUncertainty:
    """The fit's uncertainty in the observables of its shell's ablation, with what it is.

    :func:`ablation_errors`, or where it cannot give them (a record without standard errors,
    another shell than the fitted one, not the direct method, a singular derivative) no
    errors and a note saying why; never raises for those: the ablation stands without them.
    ``morphoshell ablate FIT.json`` prints and writes it.

    Parameters
    ----------
    record : dict
        A fit's record (``morphoshell fit --json``, a campaign's).
    ablation : Ablation
        The ablation of its fitted shell.
    data : Midline, optional
        The averaged midline the fit was made to
        (:func:`~morphoshell.io.problem_files.record_midline`): with its traces' spread the
        errors are also given at their σ² (:attr:`FitUncertainty.traces`).

    Returns
    -------
    FitUncertainty
    """
    try:
        errors = ablation_errors(record, ablation)
    except (ValueError, RuntimeError) as exc:   # (RuntimeError: SuperLU's singular KKT matrix)
        return FitUncertainty({}, f"no errors of the fit carried into the observables: {exc}", {})
    return FitUncertainty(errors, _CARRIED, _wider(record), _traces(record, errors, data))


def _traces(record: dict, errors: dict[str, float], data) -> TracesNoise | None:
    """:attr:`FitUncertainty.traces`: None without the traces' spread of the record's own
    points, or where its errors are a single trace's re-tracings' (not the residual's σ²)."""
    from ..fitting.hypotheses import SAME_POINTS
    from ..fitting.midline_checks import as_points
    from ..fitting.profile_noise import traces_and_residual, traces_missing
    from ..fitting.results import GAUSS_NEWTON

    if data is None or traces_missing(data) or \
            record.get("standard_errors_source", GAUSS_NEWTON) != GAUSS_NEWTON:
        return None
    fitted = record.get("data_midline") or {}
    points = np.column_stack([fitted.get("r", []), fitted.get("z", [])])
    mine = as_points(data)
    if points.shape != mine.shape or not np.max(np.abs(points - mine)) <= SAME_POINTS:
        return None                 # (not the midline the fit was made to)
    traces, residual, dof = traces_and_residual(data, record["E_fit"] ** 2,
                                                len(record["fitted"]))
    scale = np.sqrt(traces / residual)
    return TracesNoise(traces, residual, dof, {k: float(v * scale) for k, v in errors.items()})


def _wider(record: dict) -> dict[str, float]:
    """:attr:`FitUncertainty.wider` of a record."""
    from scipy.stats import norm

    out = {}
    for name, interval in (record.get("profile_intervals") or {}).items():
        se = record["standard_errors"].get(name)
        if se is None or not np.isfinite(se) or se <= 0:
            continue
        confidence = (record.get("profiles") or {}).get(name, {}).get("confidence", 0.95)
        lo, hi = interval
        width = np.inf if lo is None or hi is None else hi - lo
        ratio = float(width / (2 * norm.ppf(0.5 + confidence / 2) * se))
        if ratio > PROFILE_WIDER:
            out[name] = ratio
    return out
