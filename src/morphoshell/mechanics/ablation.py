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

from dataclasses import dataclass
from functools import lru_cache
from typing import NamedTuple, Sequence

import casadi as ca
import numpy as np

from .._runtime.tables import html_table, problem_attrs, problem_rows, xarray_module
from ..model.problem import Problem
from ..solvers.direct import solver_of
from ..solvers.observables import RECOIL, recoil, state_at
from ..solvers.options import check_guess, check_problem
from ..solvers.parametric import parametric
from ..solvers.results import FIELD_NAMES, FIELD_UNITS, FIELDS, Equilibrium
from ..solvers.routes import solve

__all__ = ["Ablation", "ablate", "edge_state", "intact_problem", "recoil_jacobian",
           "RecoilJacobian", "UNITS"]

#: Units of the observables of an :class:`Ablation` (lengths in units of R).
UNITS = {"opening": "R", "rotation": "rad", "displacement": "R", "radial_displacement": "R",
         "axial_displacement": "R", "energy_released": "C R^2", "energy_removed": "C R^2"}

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
        rows = problem_rows(self.problem) + [
            (names[k][0], f"{v:.6g} {names[k][1]}") for k, v in self.observables().items()]
        for label, eq in (("pre-ablation", self.pre), ("post-ablation", self.post)):
            rows += [(f"{label} {k}", v) for k, v in eq._repr_rows(edges=False)]
        return html_table(rows, "Ablation")

    def observables(self) -> dict[str, float]:
        """The recoil observables by name (units: :data:`UNITS`; lengths in R, rotation in rad)."""
        return {k: getattr(self, k) for k in (*RECOIL, "energy_released", "energy_removed")}

    def to_dict(self, arrays: bool = True) -> dict:
        """JSON-ready: problem, observables, their units (:data:`UNITS`, the problem's lengths in
        R) and both equilibria (optionally with arrays)."""
        return {"problem": self.problem.describe(), **self.observables(),
                "units": {"h": "R", "cut": "R", **UNITS},
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
            and ``gauge``.  Concatenate several (``pandas.concat``) for a sweep.
            The equilibria themselves: ``ab.pre.to_dataframe()``,
            ``ab.post.to_dataframe()``.
        """
        import pandas as pd

        d = self.problem.describe()
        row = {"name": d["name"], "family": d["family"], "theory": d["theory"],
               "geometry": d["geometry"], "h": d["h"], "cut": d["cut"],
               "opening_P": d["opening"], **d["params"], **self.observables()}
        df = pd.DataFrame([row])
        units = {"h": "R", "cut": "R", "opening_P": "R", **UNITS}
        df.attrs.update(units=units, problem=d, gauge=_GAUGE)
        return df

    def to_xarray(self):
        """The ablation as an xarray Dataset: the observables and both equilibria.

        Needs the optional extra ``xarray`` (``pip install 'morphoshell[xarray]'``).

        Returns
        -------
        xarray.Dataset
            Scalar variables :meth:`observables` (with ``units``); the fields of
            the pre- and post-ablation equilibria as ``<field>_pre`` along the
            coordinate ``s_pre`` and ``<field>_post`` along ``s_post`` (the
            undeformed arclength, units of R; each state has its own points);
            attributes as :meth:`Equilibrium.to_xarray` (the problem, flat) and
            ``gauge``.
        """
        xr = xarray_module()
        data: dict = {k: ((), float(v), {"units": UNITS[k]}) for k, v in self.observables().items()}
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
        Passed to :func:`morphoshell.solvers.routes.solve` for both states.
    pre : Equilibrium, optional
        The pre-ablation equilibrium (:func:`intact_problem`).  By default it
        is solved on a mesh with a node at s = Σ (an anchor), where its state
        is compared with the rim's; a ``pre`` given here is evaluated there by
        its cell polynomials (less accurate between nodes).

    Returns
    -------
    Ablation

    Raises
    ------
    TypeError
        A ``problem`` that is not a Problem or a ``pre`` that is not an Equilibrium.
    """
    check_problem(problem)
    check_guess(pre, "pre")
    if not problem.cut > 0:
        raise ValueError(f"cut (Sigma) = {problem.cut!r}: an ablation needs a cut > 0")
    intact = intact_problem(problem)
    sigma = problem.cut
    if pre is None:
        # a node at the rim's material point, where the intact shell is compared
        anchors = {"anchors": (sigma,)} if method == "direct" else {}
        pre = solve(intact, nodes=nodes, method=method, **anchors, **options)
    elif pre.problem.describe() | {"name": ""} != intact.describe() | {"name": ""}:
        raise ValueError("pre must be the equilibrium of the same problem with cut = 0")
    post = solve(problem, nodes=nodes, method=method, **options)
    obs = recoil(edge_state(pre, sigma), edge_state(post, sigma))
    removed = pre.energy_between(pre.s[0], sigma)
    return Ablation(problem=problem, pre=pre, post=post, **{k: float(obs[k]) for k in RECOIL},
                    energy_released=post.energy - (pre.energy - removed),
                    energy_removed=removed)


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
