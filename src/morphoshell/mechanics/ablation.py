"""Laser ablation: what a circular cut does to a shell.

Supplementary, toy problem 2 ("Cut opening", "Cut rotation and cut
displacement") and main text, Fig. 2B: a circular cut of angle 2Σ removes the
cap s < Σ of an intact shell (the *pre-ablation* state, the same problem with
Σ = 0) and the shell recoils into its *post-ablation* equilibrium.  All
observables compare the two states at the material point s = Σ
(:func:`morphoshell.solvers.observables.recoil`):

``opening``       o = 2 [r_post(Σ) − r_pre(Σ)], the change of the hole's diameter
                  (Supplementary, toy problem 2, "Cut opening": o = 2[u(0) − u(∞)]
                  across the boundary layer);
``rotation``      ϱ = ψ_post(Σ) − ψ_pre(Σ), positive when the rim curls outward
                  (radians);
``displacement``  d, the distance the rim moves, with the gauge of the
                  Supplementary: the far end of the shell (the pole opposite
                  the cut, or the opening's rim) keeps its undeformed position;
``energy_released``  ΔE = 𝓔_post − 𝓔_pre|[Σ, end]: the post-ablation energy
                  minus the pre-ablation energy of the part that remains
                  (≤ 0 for a passive shell: the paper's ΔE of "Recoil velocity:
                  scaling argument"; an active response to the cut, such as
                  ``local_relaxation``, whose intact shell has F0 = 0, can
                  change the energy either way).
                  ``energy_removed`` is the pre-ablation energy of the cap.

Lengths in units of R, energies in units of C R² (see :mod:`morphoshell.model.problem`).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, replace
from functools import lru_cache
from typing import Mapping, NamedTuple, Sequence

import casadi as ca
import numpy as np

from .._runtime.tables import html_table, problem_attrs, problem_rows, xarray_module
from ..model.problem import Problem
from ..solvers.direct import solver_of
from ..solvers.observables import RECOIL, recoil, state_at
from ..numerics.status import TOLERANCE_NOT_MET, explain
from ..solvers.direct import MAX_NODES
from ..solvers.options import check_guess, check_problem
from ..solvers.parametric import parametric
from ..solvers.paths import stress_free
from ..solvers.refinement import COARSE, derived_errors, refine_once
from ..solvers.results import (FIELD_NAMES, FIELD_UNITS, FIELDS, Equilibrium, SolverError,
                               energy_floor)
from ..solvers.routes import direct_solver, solve, thin_note_once

__all__ = ["Ablation", "ablate", "ablation_of", "edge_state", "intact_problem", "measure",
           "recoil_jacobian", "RecoilJacobian", "UNITS", "OBSERVABLES", "SCALE_FLOOR"]

log = logging.getLogger(__name__)

#: Units of the observables of an :class:`Ablation` (lengths in units of R).
UNITS = {"opening": "R", "rotation": "rad", "displacement": "R", "radial_displacement": "R",
         "axial_displacement": "R", "energy_released": "C R^2", "energy_removed": "C R^2"}

#: The observables of an :class:`Ablation`, in the order they are reported.
OBSERVABLES = tuple(UNITS)
#: Smallest scale (R and rad) of the observables' relative errors: the rim's state is
#: converged to about the solvers' tolerance, 1e-10 (``MIN_RTOL``), so a displacement or
#: rotation below it is round-off, whose relative error means nothing.
SCALE_FLOOR = 1e-10

_GAUGE = ("post- minus pre-ablation state at the material point s = cut; z in the far-end "
          "gauge (the far end keeps its undeformed height)")


@dataclass(frozen=True, eq=False)
class Ablation:
    """Pre- and post-ablation equilibria and the observables of the cut.

    Supplementary, toy problem 2: the observables compare the two states at
    the rim's material point s = Σ (module doc).

    Attributes
    ----------
    problem : Problem
        The shell after ablation (its ``cut`` = Σ > 0).
    pre, post : Equilibrium
        The intact shell (:func:`intact_problem`) and the cut one.
    opening, displacement, radial_displacement, axial_displacement : float
        Units of R.
    rotation : float
        Radians.
    energy_released, energy_removed : float
        Units of C R².
    errors : mapping or None
        The estimated absolute discretisation error of each observable (units as the
        observable, :data:`UNITS`), made as ``solve()`` makes its own: each observable
        measured again on the half and the quarter mesh of both states
        (:func:`morphoshell.solvers.refinement.derived_errors`); NaN without an estimate
        (``error_note`` says why), None for an ablation built without one.
        :meth:`relative_errors` divides them by their scales.
    error_note : str
        Why ``errors`` are NaN, if they are.
    """

    problem: Problem
    pre: Equilibrium
    post: Equilibrium
    opening: float
    rotation: float
    displacement: float
    radial_displacement: float
    axial_displacement: float
    energy_released: float
    energy_removed: float
    errors: Mapping[str, float] | None = None
    error_note: str = ""

    def __repr__(self) -> str:
        return (f"Ablation(cut={self.problem.cut:g} R, opening={self.opening:.6g} R, "
                f"rotation={self.rotation:.6g} rad, displacement={self.displacement:.6g} R, "
                f"energy_released={self.energy_released:.6g} C R^2)")

    def _repr_html_(self) -> str:
        """Jupyter's view: the problem, the observables with units, both states' solves."""
        names = {"opening": ("cut opening o", "R"), "rotation": ("rotation ϱ", "rad"),
                 "displacement": ("displacement d", "R"),
                 "radial_displacement": ("radial displacement", "R"),
                 "axial_displacement": ("axial displacement", "R"),
                 "energy_released": ("energy released ΔE", "C R²"),
                 "energy_removed": ("energy removed (cap)", "C R²")}
        errors = self.errors or {}
        rows = problem_rows(self.problem) + [
            (names[k][0], f"{v:.6g} {names[k][1]}"
             + (f" ± {errors[k]:.2g}" if k in errors else ""))
            for k, v in self.observables().items()]
        for label, eq in (("pre-ablation", self.pre), ("post-ablation", self.post)):
            rows += [(f"{label} {k}", v) for k, v in eq._repr_rows(edges=False)]
        return html_table(rows, "Ablation")

    def observables(self) -> dict[str, float]:
        """The recoil observables by name (units: :data:`UNITS`; lengths in R, rotation in rad)."""
        return {k: getattr(self, k) for k in OBSERVABLES}

    def relative_errors(self) -> dict[str, float]:
        """:attr:`errors` relative to each observable's scale (dimensionless; {} without).

        The lengths' scale is the rim's displacement d (the opening's 2d): Δr, Δz and
        o = 2Δr are its components, and one that passes through zero while d does not is
        not unresolved.  The rotation's is |ϱ|, the energies' their own size; none below
        :data:`SCALE_FLOOR` (R, rad) or the shell's energy floor
        (:func:`morphoshell.solvers.results.energy_floor`), where a value is round-off.
        Where both shells are stress-free (k = 1: nothing recoils) every value is the
        discretisation's error of 0, and the scales are those of ``solve()``'s edge values
        and stress-free energy: 1 R or rad, and h C R² (a thin sphere's "displacement" of
        3e-8 R on 200 nodes at h = 1e-4 would otherwise read as 33 times unresolved).
        """
        if self.errors is None:
            return {}
        return relative_errors(self.observables(), self.errors, self.pre.problem, self.problem)

    def to_dict(self, arrays: bool = True) -> dict:
        """JSON-ready: problem, observables, their units (:data:`UNITS`, the problem's lengths in
        R), their estimated errors (``errors``, in the observables' units; ``relative_errors``,
        dimensionless; ``error_note``) and both equilibria (optionally with arrays)."""
        return {"problem": self.problem.describe(), **self.observables(),
                "units": {"h": "R", "cut": "R", **UNITS},
                "errors": None if self.errors is None else dict(self.errors),
                "relative_errors": self.relative_errors(), "error_note": self.error_note,
                "pre": self.pre.to_dict(arrays), "post": self.post.to_dict(arrays)}

    def to_dataframe(self):
        """The ablation as a one-row table: the problem, then the observables.

        Returns
        -------
        pandas.DataFrame
            Columns ``name``, ``family``, ``theory``, ``geometry``, ``h``, ``cut``,
            ``opening_P`` (the far-end opening P; ``opening`` is the cut's
            opening o), the family's parameters, then :meth:`observables`.
            ``df.attrs`` holds ``units`` (column → unit, :data:`UNITS`: lengths
            in units of R, rotation in radians, energies in C R²), ``problem``
            and ``gauge``.  With an estimate, ``<observable>_error`` columns follow (the
            estimated absolute errors, :attr:`errors`; units as the observable's).
            Concatenate several (``pandas.concat``) for a sweep.
            The equilibria themselves: ``ab.pre.to_dataframe()``,
            ``ab.post.to_dataframe()``.
        """
        import pandas as pd

        d = self.problem.describe()
        row = {"name": d["name"], "family": d["family"], "theory": d["theory"],
               "geometry": d["geometry"], "h": d["h"], "cut": d["cut"],
               "opening_P": d["opening"], **d["params"], **self.observables(),
               **self.error_columns()}
        df = pd.DataFrame([row])
        units = {"h": "R", "cut": "R", "opening_P": "R", **UNITS,
                 **{k: UNITS[k.removesuffix("_error")] for k in self.error_columns()}}
        df.attrs.update(units=units, problem=d, gauge=_GAUGE)
        return df

    def error_columns(self) -> dict[str, float]:
        """``<observable>_error`` → :attr:`errors` (units :data:`UNITS`); {} without."""
        return {f"{k}_error": float(v) for k, v in (self.errors or {}).items()}

    def to_xarray(self):
        """The ablation as an xarray Dataset: the observables and both equilibria.

        Needs the optional extra ``xarray`` (``pip install 'morphoshell[xarray]'``).

        Returns
        -------
        xarray.Dataset
            Scalar variables :meth:`observables` (with ``units``) and, with an
            estimate, their ``<observable>_error`` (:attr:`errors`); the fields of
            the pre- and post-ablation equilibria as ``<field>_pre`` along the
            coordinate ``s_pre`` and ``<field>_post`` along ``s_post`` (the
            undeformed arclength, units of R; each state has its own points);
            attributes as :meth:`Equilibrium.to_xarray` (the problem, flat) and
            ``gauge``.
        """
        xr = xarray_module()
        data: dict = {k: ((), float(v), {"units": UNITS[k.removesuffix("_error")]})
                      for k, v in {**self.observables(), **self.error_columns()}.items()}
        coords = {}
        for label, eq in (("pre", self.pre), ("post", self.post)):
            dim = f"s_{label}"
            coords[dim] = (dim, np.asarray(eq.s, dtype=float),
                           {"units": "R", "long_name": f"undeformed arclength, {label}-ablation"})
            data.update({f"{k}_{label}": (dim, np.asarray(getattr(eq, k), dtype=float),
                                          {"units": FIELD_UNITS[k], "long_name": FIELD_NAMES[k]})
                         for k in FIELDS if k != "s"})
        attrs = {**problem_attrs(self.problem), "gauge": _GAUGE,
                 "energy_pre": float(self.pre.energy), "energy_post": float(self.post.energy),
                 "energy_units": "C R^2"}
        return xr.Dataset(data, coords=coords, attrs=attrs)


def edge_state(eq: Equilibrium, s: float) -> dict[str, float]:
    """(r, z, ψ) at the material point ``s``, in the far-end gauge.

    z is shifted so that the far end (the last point) sits at its undeformed
    height; r needs no gauge (the axis is fixed).  Direct solutions are
    evaluated exactly by their cell polynomials (the definition of
    :func:`morphoshell.solvers.observables.state_at`); other routes by a cubic spline
    through their points.

    Returns
    -------
    dict
        Floats ``r``, ``z`` (units of R) and ``psi`` (radians).
    """
    z0_end = float(eq.problem.geometry_obj.numeric(eq.s[-1:])[1][0])
    shift = z0_end - eq.z[-1]
    solver = solver_of(eq)
    if s == eq.s[0]:
        r, z, psi = eq.r[0], eq.z[0], eq.psi[0]
    elif solver is not None:
        st = solver.disc.state_at(eq.x, eq.problem.parameter_vector(), eq.anchors, eq.z, s)
        r, z, psi = st["r"], st["z"], st["psi"]
    else:
        from scipy.interpolate import CubicSpline   # on use: start-up time
        r, z, psi = (float(CubicSpline(eq.s, v)(s)) for v in (eq.r, eq.z, eq.psi))
    return {"r": float(r), "z": float(z + shift), "psi": float(psi)}


def intact_problem(problem: Problem) -> Problem:
    """The pre-ablation shell: ``problem`` with Σ = 0 and the family's ``pre_ablation`` values."""
    return problem.with_updates(cut=0.0, **problem.family_obj.pre_ablation)


def ablate(problem: Problem, nodes: int = 200, method: str = "direct",
           pre: Equilibrium | None = None, **options) -> Ablation:
    """Solve the pre- and post-ablation shells and measure the recoil.

    Parameters
    ----------
    problem : Problem
        The shell *after* ablation: ``problem.cut`` = Σ > 0 is the cut.
    nodes, method, **options
        Passed to :func:`morphoshell.solvers.routes.solve` for both states.  With
        ``rtol`` (direct method) each state is refined to it as ``solve()`` refines, and
        then both together (doubling their cells, up to ``max_nodes``) until every
        observable's relative error (:meth:`Ablation.relative_errors`) meets it too.
    pre : Equilibrium, optional
        The pre-ablation equilibrium (:func:`intact_problem`).  By default it
        is solved on a mesh with a node at s = Σ (an anchor), where its state
        is compared with the rim's; a ``pre`` given here is evaluated there by
        its cell polynomials (less accurate between nodes).

    Returns
    -------
    Ablation
        With the estimated error of each observable (:attr:`Ablation.errors`, direct
        method), from the half and quarter meshes of both states that ``solve()``'s own
        estimate solved.  Without ``rtol``, a relative error above
        :data:`~morphoshell.solvers.refinement.COARSE` is logged as a warning that names
        the observable and a finer mesh (a tiny cut's displacement, Σ = h = 1e-4: 27 %
        off on 200 nodes).

    Raises
    ------
    TypeError
        A ``problem`` that is not a Problem or a ``pre`` that is not an Equilibrium.
    SolverError
        Either state's, or ``"Tolerance_Not_Met"`` where ``rtol`` needs more than
        ``max_nodes`` nodes (the finest post-ablation state attached).
    """
    check_problem(problem)
    check_guess(pre, "pre")
    if not problem.cut > 0:
        raise ValueError(f"cut (Sigma) = {problem.cut!r}: an ablation needs a cut > 0")
    intact = intact_problem(problem)
    sigma = problem.cut
    if pre is not None and \
            pre.problem.describe() | {"name": ""} != intact.describe() | {"name": ""}:
        raise ValueError("pre must be the equilibrium of the same problem with cut = 0")
    with thin_note_once():      # (both states are one shell, of one thickness)
        if pre is None:
            # a node at the rim's material point, where the intact shell is compared
            anchors = {"anchors": (sigma,)} if method == "direct" else {}
            pre = solve(intact, nodes=nodes, method=method, **anchors, **options)
        post = solve(problem, nodes=nodes, method=method, **options)
    if options.get("rtol") is not None:
        return _refined(_measured(problem, pre, post), options)
    return ablation_of(problem, pre, post)


def ablation_of(problem: Problem, pre: Equilibrium, post: Equilibrium) -> Ablation:
    """The :class:`Ablation` of the intact shell ``pre`` and the cut one ``post``: its
    observables, their errors from both states' estimates (their levels, as :func:`ablate`
    makes them) and the one warning where they exceed
    :data:`~morphoshell.solvers.refinement.COARSE`.

    Every ablation that is not refined to a tolerance ends here, so that :func:`ablate` and
    :func:`morphoshell.workflows.numerical_ablation` warn by one rule (the latter once said
    nothing where the former warned, on the same numbers: audit 21).

    Parameters
    ----------
    problem : Problem
        The shell after ablation (its ``cut`` > 0).
    pre, post : Equilibrium
        Its pre- and post-ablation states; without estimates' levels the errors are NaN,
        ``error_note`` says why, and nothing is warned.

    Returns
    -------
    Ablation
    """
    ab = _measured(problem, pre, post)
    _warn_if_coarse(ab)
    return ab


def measure(sigma: float, pre: Equilibrium, post: Equilibrium) -> dict[str, float]:
    """The observables (:data:`OBSERVABLES`, units :data:`UNITS`) of a cut Σ = ``sigma``
    between the intact shell ``pre`` and the cut one ``post`` (module doc)."""
    obs = recoil(edge_state(pre, sigma), edge_state(post, sigma))
    removed = pre.energy_between(pre.s[0], sigma)
    return {**{k: float(obs[k]) for k in RECOIL},
            "energy_released": float(post.energy - (pre.energy - removed)),
            "energy_removed": float(removed)}


def _measured(problem: Problem, pre: Equilibrium, post: Equilibrium) -> Ablation:
    """The :class:`Ablation` of ``pre`` and ``post``, its errors from their estimates' levels."""
    errors, note = derived_errors(lambda a, b: measure(problem.cut, a, b), pre, post)
    return Ablation(problem=problem, pre=pre, post=post,
                    **measure(problem.cut, pre, post), errors=errors, error_note=note)


def relative_errors(values: Mapping[str, float], errors: Mapping[str, float], intact: Problem,
                    problem: Problem) -> dict[str, float]:
    """``errors`` of an ablation's observables ``values`` relative to their scales
    (:meth:`Ablation.relative_errors`, which says which; shared with sweeps).

    Parameters
    ----------
    values : mapping
        Every observable (:func:`measure`).
    errors : mapping
        Absolute errors of some of them.
    intact, problem : Problem
        The shell before and after the cut.

    Returns
    -------
    dict
        Dimensionless, by key of ``errors``.
    """
    neutral = stress_free(intact) and stress_free(problem)
    # the removed cap is a piece of the intact shell: a stress-free one's energy is the
    # discretisation of zero whether or not the cut shell is (a fast relaxation's cap,
    # 1e-15 C R^2, read as unresolved against the round-off floor)
    removed = energy_floor(problem.h, stress_free(intact))
    scales = _scales(values, 1.0 if neutral else SCALE_FLOOR, energy_floor(problem.h, neutral),
                     removed)
    return {k: float(v / scales[k]) for k, v in errors.items()}


def _scales(values: Mapping[str, float], floor: float, energy: float,
            removed: float) -> dict[str, float]:
    """The scale of each observable's relative error (:meth:`Ablation.relative_errors`), none
    below ``floor`` (R, rad), ``energy`` (C R²) or, for the removed cap's energy,
    ``removed`` (C R²)."""
    d = max(abs(values["displacement"]), floor)
    return {"opening": 2 * d, "rotation": max(abs(values["rotation"]), floor),
            "displacement": d, "radial_displacement": d, "axial_displacement": d,
            "energy_released": max(abs(values["energy_released"]), energy),
            "energy_removed": max(abs(values["energy_removed"]), removed)}


def _worst(ab: Ablation, tol: float) -> tuple[str, float] | None:
    """(the observable, its relative error) of the largest relative error above ``tol``
    (a missing estimate, NaN, counts as above), or None."""
    rel = ab.relative_errors()
    if not rel:
        return None
    key = max(rel, key=lambda k: rel[k] if np.isfinite(rel[k]) else np.inf)
    return None if rel[key] <= tol else (key, rel[key])


def _warn_if_coarse(ab: Ablation) -> None:
    """One warning where observables' relative errors exceed :data:`COARSE`, as ``solve()``
    warns of its own estimate: the mesh may not resolve the cut.  It names them, worst
    first, and the next finer mesh.  It says "may": the estimates bound the errors, about
    25-40 times them on a resolved mesh but some 800 times where the half and quarter meshes
    are not yet in the asymptotic range (a fitted shell's energy_released on 100 nodes,
    0.1 % off, estimated at 0.88 of its value: docs/observables.md); extrapolating with
    the order the levels show, the tighter estimate tried, fell short of the error."""
    if ab.error_note:
        return
    rel = ab.relative_errors()
    over = sorted((k for k in rel if not rel[k] <= COARSE), key=lambda k: -rel[k])
    if over:
        nodes = max(ab.pre.solver.nodes, ab.post.solver.nodes)
        finer = 2 * (nodes - 1) + 1
        log.warning("the error estimates of the ablation's %s exceed %g of their values on %d "
                    "nodes: the mesh may not resolve the cut (the estimates are bounds, tens "
                    "to hundreds of times the error); give it more nodes (nodes=%d, --nodes %d, or "
                    "more) or refine to a tolerance (rtol, --rtol)",
                    ", ".join(f"{k} ({rel[k]:.2g})" for k in over), COARSE, nodes, finer, finer)


def _refined(ab: Ablation, options: dict) -> Ablation:
    """``ab`` with both states refined together (doubling their cells, as ``solve()``'s
    ``rtol``) until every observable's relative error meets ``options["rtol"]``."""
    rtol, max_nodes = options["rtol"], min(options.get("max_nodes", MAX_NODES), MAX_NODES)
    direct = {k: v for k, v in options.items() if k not in ("rtol", "max_nodes", "continuation")}
    paths = {"pre": _path(ab.pre), "post": _path(ab.post)}
    while (worst := _worst(ab, rtol)) is not None:
        nodes = max(ab.pre.solver.nodes, ab.post.solver.nodes)
        if 2 * (nodes - 1) + 1 > max_nodes:
            raise SolverError(
                f"the error estimate {worst[1]:.3g} of the ablation's {worst[0]} (relative, at "
                f"{nodes} nodes) does not meet rtol = {rtol:g} within {max_nodes} nodes: "
                f"{explain(TOLERANCE_NOT_MET)}; the finest post-ablation solution is the "
                f"error's last_iterate", TOLERANCE_NOT_MET, ab.post)
        pre, post = (_finer_state(eq, key, direct, rtol, paths)
                     for eq, key in ((ab.pre, "pre"), (ab.post, "post")))
        ab = _measured(ab.problem, pre, post)
    return ab


def _path(eq: Equilibrium) -> str:
    return str(eq.solver.details.get("path", ""))


def _finer_state(eq: Equilibrium, key: str, direct: dict, rtol: float,
                 paths: dict) -> Equilibrium:
    """``eq`` on twice the cells (:func:`~morphoshell.solvers.refinement.refine_once`), its path
    (``paths[key]``, as ``solve()`` reached it, and notes of the refinements) saying why."""
    finer, how = refine_once(eq, lambda n: direct_solver(eq.problem, n, eq.anchors, **direct),
                             eq.anchors)
    paths[key] += how
    path = (f"{paths[key]}, then refined to {finer.solver.nodes} nodes for the "
            f"ablation's observables (rtol = {rtol:g})")
    return replace(finer, solver=replace(finer.solver, details={**finer.solver.details,
                                                                 "path": path}))


@lru_cache(maxsize=1)
def recoil_function() -> ca.Function:
    """(pre r, z, ψ; post r, z, ψ) -> RECOIL and its Jacobian, from :func:`recoil`."""
    pre, post = ca.SX.sym("pre", 3), ca.SX.sym("post", 3)
    out = recoil(dict(zip(("r", "z", "psi"), ca.vertsplit(pre))),
                 dict(zip(("r", "z", "psi"), ca.vertsplit(post))))
    y = ca.vertcat(*[out[k] for k in RECOIL])
    return ca.Function("recoil", [pre, post], [y, ca.jacobian(y, ca.vertcat(pre, post))])


class RecoilJacobian(NamedTuple):
    """The recoil observables of an ablation and their derivatives (:func:`recoil_jacobian`).

    Unpacks as ``values, jacobian``.  Row i of both is the observable ``rows[i]``
    (:data:`~morphoshell.solvers.observables.RECOIL`: opening, rotation, displacement,
    radial and axial displacement; ``energy_released`` is not among them); column j of
    ``jacobian`` is the j-th parameter of ``wrt``.
    """

    values: np.ndarray
    jacobian: np.ndarray

    rows = RECOIL      # (a class attribute, not a field: the pair still unpacks)

    def row(self, name: str) -> tuple[float, np.ndarray]:
        """The value of the observable ``name`` (of :attr:`rows`) and its gradient over ``wrt``."""
        if name not in self.rows:
            raise ValueError(f"row = {name!r}: choose one of {list(self.rows)}")
        i = self.rows.index(name)
        return float(self.values[i]), self.jacobian[i]


def recoil_jacobian(ablation: Ablation, wrt: Sequence[str]) -> RecoilJacobian:
    """Exact derivatives of the recoil observables of a direct ablation.

    Both equilibria depend on the parameters (through the implicit function
    theorem, :mod:`morphoshell.solvers.parametric`); the pre-ablation shell does not
    depend on its family's ``pre_ablation`` parameters (their columns get no
    contribution from it).  The rim is the material point s = Σ in both
    states (a node of each mesh), z in the far-end gauge.

    Parameters
    ----------
    ablation : Ablation
        From :func:`ablate` with the direct method.
    wrt : sequence of str
        Parameter names (h, opening or the family's); not ``cut``, which moves
        the compared material point itself.

    Returns
    -------
    RecoilJacobian
        ``values`` (shape (5,)) and ``jacobian`` (shape (5, len(wrt))), rows in the order
        of :data:`~morphoshell.solvers.observables.RECOIL` (``.rows``; ``.row(name)``
        picks one): unpacks as ``values, jacobian``.
    """
    wrt = tuple(wrt)
    if "cut" in wrt:
        raise ValueError("recoil_jacobian: derivatives with respect to the cut are not "
                         "available (the compared material point moves with it)")
    states, jacs = [], []
    for eq, key in ((ablation.pre, "pre"), (ablation.post, "post")):
        solver = solver_of(eq)
        if solver is None:
            raise ValueError("recoil_jacobian needs an ablation solved by the direct method")
        d = solver.disc
        p = eq.problem.parameter_vector()
        sigma = ablation.problem.cut
        obs = state_at(d, sigma, d.cell_of(p, eq.anchors, sigma), gauge="far_end")
        fixed = set(eq.problem.family_obj.pre_ablation) if key == "pre" else set()
        names = [n for n in wrt if n not in fixed]
        value, J = parametric(solver).jacobian(eq, obs, names)
        full = np.zeros((3, len(wrt)))
        full[:, [wrt.index(n) for n in names]] = J
        states.append(value)
        jacs.append(full)
    y, dy = recoil_function()(*states)
    return RecoilJacobian(np.asarray(y).ravel(), np.asarray(dy) @ np.vstack(jacs))
