"""Results of every solution route, and the errors they raise.

An :class:`Equilibrium` is what the direct solver, the boundary-value
reference and the shooting route return; :class:`SolverError` (with the last
iterate attached) and its subclass :class:`NotAMinimumError` are what they
raise.  This module imports nothing else of the package but the problem, so
every route can depend on it.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Mapping, NamedTuple

import numpy as np

from .._runtime.tables import html_table, problem_attrs, problem_rows, xarray_module
from ..model.problem import Problem
from ..numerics.mesh import breakpoints
from ..numerics.status import NotAMinimumError, SolverError

__all__ = ["Equilibrium", "SolverStats", "SolverError", "NotAMinimumError", "FIELDS", "unconverged",
           "Quadrature", "ErrorEstimate", "ESTIMATED", "ENERGY_FLOOR", "energy_floor",
           "FIELD_UNITS", "FIELD_NAMES", "JSON_UNITS"]


#: Nodal arrays of an :class:`Equilibrium`, in order.
FIELDS = ("s", "r", "z", "psi", "f_s", "f_phi", "kappa_s", "kappa_phi",
          "E_s", "E_phi", "K_s", "K_phi", "N_s", "N_phi", "M_s", "M_phi", "eta", "e")


#: Unit of each of :data:`FIELDS` (lengths in units of the undeformed radius R,
#: energies per undeformed area in units of C, "1": dimensionless).
FIELD_UNITS = {"s": "R", "r": "R", "z": "R", "psi": "rad", "f_s": "1", "f_phi": "1",
               "kappa_s": "1/R", "kappa_phi": "1/R", "E_s": "1", "E_phi": "1",
               "K_s": "1/R", "K_phi": "1/R", "N_s": "C", "N_phi": "C", "M_s": "C R",
               "M_phi": "C R", "eta": "1", "e": "C"}

#: Units of :meth:`Equilibrium.to_dict` (the form of a sweep's ``units``): the energy, the
#: problem's lengths and the fields, also those of ``edge_start`` and ``edge_end``.
JSON_UNITS = {"energy": "C R^2", "h": "R", "cut": "R", "opening": "R", **FIELD_UNITS}

#: What each of :data:`FIELDS` is (the ``long_name`` of :meth:`Equilibrium.to_xarray`).
FIELD_NAMES = {
    "s": "undeformed arclength from the pole s = 0", "r": "distance from the axis",
    "z": "height along the axis (solver gauge: z(s[0]) = its undeformed height)",
    "psi": "tangent angle of the meridian", "f_s": "meridional stretch dS/ds",
    "f_phi": "circumferential stretch r/rho", "kappa_s": "meridional curvature",
    "kappa_phi": "circumferential curvature", "E_s": "meridional stretching strain",
    "E_phi": "circumferential stretching strain", "K_s": "meridional bending strain",
    "K_phi": "circumferential bending strain", "N_s": "meridional stress resultant de/dE_s",
    "N_phi": "circumferential stress resultant de/dE_phi",
    "M_s": "meridional moment resultant de/dK_s",
    "M_phi": "circumferential moment resultant de/dK_phi",
    "eta": "large-bending parameter kappa_s0 h / (2 f_s0 f_phi0)",
    "e": "energy per undeformed area"}

class Quadrature(NamedTuple):
    """The Gauss rule of a direct solution: points, weights (Δs w_k), integrand L = 2πρe, r there.

    Attributes
    ----------
    s, weights, integrand, r : ndarray, shape (G,)
        At the G = stages × cells Gauss points: s, the weights Δs w_k, L = 2πρe
        (Materials and Methods, Eq. 7) and r.
    stages : int
        Gauss points per cell.
    """

    s: np.ndarray
    weights: np.ndarray
    integrand: np.ndarray
    stages: int
    r: np.ndarray


#: Floor of the energy scale in relative comparisons (C R²) at h ≥ 0.1: energies at
#: round-off.  Thinner shells' energies scale with h³ (bending), and so does their floor
#: (:func:`energy_floor`): a fixed one had deflated the relative error of a shell at
#: h = 10⁻⁶ by 10⁶ (a 1300 % error met rtol = 10⁻³).
ENERGY_FLOOR = 1e-12


def energy_floor(h: float, stress_free: bool = False) -> float:
    """The smallest energy scale of relative energy errors (C R²).

    For a stressed shell :data:`ENERGY_FLOOR`, scaled with the bending energy h³ below
    h = 0.1: its energy, at least of the order of its bending energy, is the scale.

    A stress-free shell (``stress_free``: its family's neutral parameters,
    :func:`morphoshell.solvers.paths.stress_free`) has energy 0, and its discrete energy
    is the discretisation error of that zero: the stretching energy (C/2) h E² of the
    strains E by which the mesh misrepresents the undeformed shell, ∝ h.  Relative to the
    round-off floor it read as errors of many times the energy and drove rtol to
    thousands of nodes for a shape exact on 200.  Its scale is the stretching energy of a
    unit strain, h (C R²): the relative error is then the squared strain error, tiny on
    any mesh (docs/benchmarks.md, "solvers/results.py").  (A stressed shell's scale
    cannot be h: a thin one's bending energy, ∝ h³, would be deflated by h⁻².)
    """
    if stress_free:
        return float(h)
    return ENERGY_FLOOR * min(1.0, (h / 0.1) ** 3)

#: Quantities an :class:`ErrorEstimate` covers: the energy (C R²) and the edge
#: values r, ψ at both ends and z at the far end (units of R and radians).
ESTIMATED = ("energy", "r_start", "psi_start", "r_end", "psi_end", "z_end")


@dataclass(frozen=True)
class ErrorEstimate:
    """Estimated discretisation error of a direct solution.

    The difference from the same problem on the mesh with half the cells,
    solved from this solution (so on its branch), or, if larger, the
    difference between the half and the quarter mesh reduced by the design
    order (:func:`morphoshell.solvers.refinement.estimate`: two levels can agree by
    luck).  It bounds the error of the finer solution for any order of
    convergence ≥ 1, also on pre-asymptotic meshes (a thin boundary layer or a
    step resolved by a few cells), where a Richardson estimate
    |fine − coarse|/(2^p − 1) fell short by 1.4× in fuzzing; on a
    well-resolved mesh of order p it is 2^p − 1 times (15× at order 4)
    pessimistic.  A coarse mesh that lands elsewhere (a spurious minimum, an
    unresolved layer) shows up as a large estimate.

    Attributes
    ----------
    errors : mapping
        Estimated absolute error of each of :data:`ESTIMATED`.
    values : mapping
        The estimated quantities themselves.
    nodes, reference_nodes : int
        Nodes of this mesh and of the half mesh compared with.
    order : int
        Order p of the scheme (2 × stages).
    note : str
        Why there is no estimate, if there is none (errors are then NaN).
    energy_floor : float
        The smallest energy scale of relative errors (C R²; :func:`energy_floor`).
    levels : tuple of Equilibrium
        The coarser solutions compared with: the half mesh's, then the quarter mesh's
        where there is one (empty without an estimate).  Kept so that a quantity derived
        from the solution, such as an ablation's observables, is estimated from the same
        levels (:func:`morphoshell.solvers.refinement.derived_errors`) without solving
        them again; neither written out nor compared.
    polished : Equilibrium or None
        This solution solved on to the default ``tol`` on its own mesh, where it was
        solved to a looser one (its stopping error is in ``errors``, and
        :func:`~morphoshell.solvers.refinement.derived_errors` adds a derived
        quantity's); None otherwise.  Neither written out nor compared.
    """

    errors: Mapping[str, float]
    values: Mapping[str, float]
    nodes: int
    reference_nodes: int
    order: int
    note: str = ""
    energy_floor: float = ENERGY_FLOOR
    levels: tuple = field(default=(), repr=False, compare=False)
    polished: Any = field(default=None, repr=False, compare=False)

    def relative(self) -> dict[str, float]:
        """Errors relative to their scale: the energy to max(|𝓔|, ``energy_floor``), edge
        values absolutely (lengths in units of R and angles in radians are O(1))."""
        out = dict(self.errors)
        out["energy"] = self.errors["energy"] / max(abs(self.values["energy"]),
                                                    self.energy_floor)
        return out

    def worst(self) -> tuple[str, float]:
        """The quantity with the largest relative error, and that error."""
        rel = self.relative()
        key = max(rel, key=lambda k: rel[k] if np.isfinite(rel[k]) else np.inf)
        return key, rel[key]

    def meets(self, rtol: float) -> bool:
        """Whether every relative error (:meth:`relative`) is finite and at most ``rtol``."""
        return all(np.isfinite(v) and v <= rtol for v in self.relative().values())

    def summary(self, energy_unit: str = "C R²") -> str:
        """One line: the relative errors of the energy and the worst edge value, and the
        meshes compared; the energy's scale named where it is the floor (a stress-free
        shell's, or round-off), not the energy."""
        rel = self.relative()
        scale = ("the energy" if abs(self.values["energy"]) >= self.energy_floor else
                 f"the energy scale {self.energy_floor:.2g} {energy_unit}")
        edge = max(v for k, v in rel.items() if k != "energy")
        return (f"{rel['energy']:.2g} of {scale}, {edge:.2g} R or rad at the edges (vs "
                f"{self.reference_nodes} nodes, order {self.order})")

    def to_dict(self) -> dict:
        """JSON-ready: absolute and relative errors (energy in C R², edges in R and rad)."""
        return {"errors": dict(self.errors), "relative": self.relative(), "nodes": self.nodes,
                "reference_nodes": self.reference_nodes, "order": self.order,
                "note": self.note}


@dataclass(frozen=True)
class SolverStats:
    """How an equilibrium was obtained.

    Attributes
    ----------
    method : {"direct", "bvp", "shooting"}
    iterations : int
        Newton (Ipopt) iterations, ``solve_bvp``'s, or shooting evaluations.
    seconds : float
        Wall time of the solve (s).
    status : str
        How it ended: a key of :data:`morphoshell.numerics.status.STATUSES`.
    nodes : int
        Mesh nodes (the route's final mesh).
    build_seconds : float
        Wall time of building the direct solver (s).
    details : mapping
        The route's own: how a minimum was certified, the path, residuals.
    """

    method: str
    iterations: int
    seconds: float
    status: str
    nodes: int
    build_seconds: float = 0.0
    details: Mapping[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict:
        """JSON-ready: method, iterations, seconds (wall time, s), status, nodes and scalar
        details."""
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
    s, r, z, psi : ndarray, shape (N,)
        Undeformed arclength, deformed distance from the axis, height and
        tangent angle at the N points.  z is fixed by z(s[0]) = z₀(s[0]) (the
        undeformed height).
    f_s, f_phi, kappa_s, kappa_phi : ndarray, shape (N,)
        Stretches and curvatures (paper, Materials and Methods, Eq. 5).
    E_s, E_phi, K_s, K_phi : ndarray, shape (N,)
        Strains (Materials and Methods, Eq. 6).
    N_s, N_phi, M_s, M_phi : ndarray, shape (N,)
        Resultants ∂e/∂E_a (units of C) and ∂e/∂K_a (units of C R).
    eta : ndarray, shape (N,)
        Large-bending parameter η(s).
    e : ndarray, shape (N,)
        Energy per undeformed area (units of C); 𝓔 = 2π ∫ e ρ ds
        (Materials and Methods, Eq. 7).
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
    quadrature: Quadrature | None = field(default=None, repr=False)
    #: Estimated discretisation error (direct solutions from ``solve()``).
    error: ErrorEstimate | None = None
    #: Positions of the mesh's anchors (material points that are nodes), if any.
    anchors: tuple = ()
    #: The direct solver that produced it (a weak reference: results do not
    #: keep solvers alive); see :func:`morphoshell.solvers.direct.solver_of`.
    source: Any = field(default=None, repr=False)

    def __getstate__(self) -> dict:
        """Pickled with every field, but the weak reference to its solver replaced by
        :func:`_released` (a weak reference does not pickle, and a solver stays in its
        process): the mesh and stages stay, so :func:`morphoshell.solvers.direct.solver_of`
        builds a solver of the same mesh where one is needed, as for a result whose solver
        was garbage-collected, and warm starts, observables and derivatives of the
        unpickled result are those of the original."""
        state = dict(self.__dict__)
        if self.source is not None:
            state["source"] = (_released, *self.source[1:])
        return state

    def __repr__(self) -> str:
        return (f"Equilibrium({self.problem.name or self.problem.family!r}, "
                f"energy={self.energy:.10g}, points={len(self.s)}, method={self.solver.method!r}, "
                f"converged={self.converged})")

    def _repr_rows(self, edges: bool = True) -> list[tuple[str, str]]:
        """Energy, solver, error estimate and (``edges``) the first and last points, as rows."""
        st, err = self.solver, self.error
        rows = [("energy", f"{self.energy:.10g} C R²"),
                ("solver", f"{st.method}, {st.nodes} nodes ({len(self.s)} points), "
                           f"{st.iterations} iterations, {st.seconds:.3g} s: {st.status}")]
        if not self.converged:
            rows.append(("converged", "no: the last iterate of a failed solve"))
        if "path" in st.details:
            rows.append(("reached by", str(st.details["path"])))
        if err is not None:
            rows.append(("error estimate",
                         f"unavailable: {err.note}" if err.note else err.summary()))
        if edges:
            rows += [(f"{which} point, s = {e['s']:.6g} R",
                      f"r = {e['r']:.6g} R, z = {e['z']:.6g} R, ψ = {e['psi']:.6g} rad")
                     for which, e in (("first", self.edge("start")), ("last", self.edge("end")))]
        return rows

    def _repr_html_(self) -> str:
        """Jupyter's view: the problem, energy, solver and edge values, with units."""
        return html_table(problem_rows(self.problem) + self._repr_rows(), "Equilibrium")

    def estimated_values(self) -> dict[str, float]:
        """The quantities an :class:`ErrorEstimate` covers (:data:`ESTIMATED`).

        Returns
        -------
        dict
            Float by key of :data:`ESTIMATED` (energy in C R², edges in R and rad).
        """
        return {"energy": self.energy, "r_start": float(self.r[0]), "psi_start": float(self.psi[0]),
                "r_end": float(self.r[-1]), "psi_end": float(self.psi[-1]),
                "z_end": float(self.z[-1] - self.z[0])}

    def edge(self, which: str = "start") -> dict[str, float]:
        """Values at the first (``"start"``) or last (``"end"``) node.

        At a pole with η ≠ 0 (large-bending theory, or toy problem 3) the fields
        are weakly singular (docs/solution.md, "Three routes to one energy"): r,
        ψ and z converge with the mesh there, but the stretches, strains,
        resultants and energy density at the pole itself grow under refinement
        (f_s 1.5 → 4.5 from 50 to 400 nodes at η = 0.3) and mean nothing as
        numbers; a free edge's values are regular.

        Returns
        -------
        dict
            Float by field of :data:`FIELDS`.

        Raises
        ------
        ValueError
            ``which`` neither "start" nor "end" (any other word gave the end's values).
        """
        if which not in ("start", "end"):
            raise ValueError(f"which = {which!r} must be 'start' or 'end'")
        i = 0 if which == "start" else -1
        return {k: float(getattr(self, k)[i]) for k in FIELDS}

    def at(self, s) -> dict:
        """Fields interpolated (cubic) at the undeformed arclength ``s``.

        The cubic spline runs within the segment between the profile's breakpoints
        that are points of the result (a direct solution's are nodes), never across
        one: a field that kinks there (f_s where a profile kinks) would otherwise
        spill its kink onto the points next to it.  At a breakpoint itself the value
        is the point's.

        Parameters
        ----------
        s : float or array_like
            Material points, within [s[0], s[-1]] (units of R).

        Returns
        -------
        dict
            By field of :data:`FIELDS`: a float for a scalar ``s``, else an array of
            ``s``'s shape.

        Raises
        ------
        ValueError
            ``s`` not numbers, NaN or outside the shell (the first such value named).
        """
        from scipy.interpolate import CubicSpline

        try:
            points = np.asarray(s, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"s = {s!r} must be a number or an array of numbers") from None
        flat = points.ravel()
        outside = flat[~((flat >= self.s[0]) & (flat <= self.s[-1]))]    # NaN too
        if outside.size:
            raise ValueError(f"s = {outside[0]} lies outside the shell [{self.s[0]}, "
                             f"{self.s[-1]}]")
        cuts = self._cuts()
        segments = [self._segment(x, cuts) for x in flat]
        values = np.empty((flat.size, len(FIELDS)))
        for lo, hi in set(segments):
            mine = [i for i, seg in enumerate(segments) if seg == (lo, hi)]
            table = np.column_stack([getattr(self, k)[lo:hi] for k in FIELDS])
            values[mine] = CubicSpline(self.s[lo:hi], table)(flat[mine])
        if points.ndim == 0:
            return {k: float(values[0, j]) for j, k in enumerate(FIELDS)}
        return {k: values[:, j].reshape(points.shape) for j, k in enumerate(FIELDS)}

    def _cuts(self) -> list[int]:
        """The indices of the points that are the profile's breakpoints, with the ends."""
        cuts = [0, len(self.s)]
        for b, _ in breakpoints(self.problem):
            i = int(np.argmin(np.abs(self.s - b)))
            if 0 < i < len(self.s) - 1 and abs(self.s[i] - b) <= 1e-12 * (1 + abs(b)):
                cuts.append(i)
        return sorted(set(cuts))

    def _segment(self, s: float, cuts: list[int]) -> tuple[int, int]:
        """The slice [lo, hi) of the points between the breakpoints (``cuts``) around ``s``
        (the whole shell without breakpoints among the points; at least 4 points, or all)."""
        k = min(int(np.searchsorted(cuts, np.searchsorted(self.s, s, side="right") - 1,
                                    side="right")), len(cuts) - 1)
        lo, hi = cuts[k - 1], cuts[k] + 1
        return (lo, hi) if hi - lo >= 4 else (0, len(self.s))

    def quadrature_points(self) -> tuple[np.ndarray, np.ndarray]:
        """(s, r) at the Gauss points of a direct solution (empty for other routes).

        Returns
        -------
        s, r : ndarray, shape (G,)
            At the G Gauss points (G = 0 for the bvp and shooting routes).
        """
        if self.quadrature is None:
            return np.zeros(0), np.zeros(0)
        return self.quadrature.s, self.quadrature.r

    def energy_between(self, a: float, b: float) -> float:
        """2π ∫_a^b e ρ ds: the energy of the part a ≤ s ≤ b of the shell.

        Direct solutions use their own Gauss rule (exact integration of the
        cell's interpolant of L = 2πρe where a or b cuts a cell), so that
        ``energy_between(s[0], s[-1])`` is ``energy`` to rounding (the cells
        are summed in another order: test with ``np.isclose``, not ``==``);
        BVP solutions integrate the
        cubic spline of L through their collocation mesh.

        Parameters
        ----------
        a, b : float
            The ends, s[0] ≤ a ≤ b ≤ s[-1].

        Returns
        -------
        float
            The energy (units of C R²).
        """
        if not self.s[0] <= a <= b <= self.s[-1]:
            raise ValueError(f"[{a}, {b}] is not a part of the shell [{self.s[0]}, {self.s[-1]}]")
        if self.quadrature is None:
            # on use: a direct solution's ablation (the common case) need not import scipy
            from scipy.interpolate import CubicSpline

            rho = self.problem.geometry_obj.numeric(self.s)[0]
            return float(CubicSpline(self.s, 2 * np.pi * rho * self.e).integrate(a, b))
        sk, wk, Lk, stages = self.quadrature[:4]   # the cell's Gauss points, weights, L
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

    def to_dataframe(self):
        """The fields as a table: one row per point, one column per field (:data:`FIELDS`).

        Returns
        -------
        pandas.DataFrame
            Columns s, r, z, psi, …, e.  ``df.attrs`` holds ``units`` (column →
            unit, :data:`FIELD_UNITS`: lengths in units of R, angles in radians,
            e and N in units of C, M in C R), ``problem`` (:meth:`Problem.describe`),
            ``energy`` (C R²), ``converged``, ``solver`` and ``gauge`` (z is in
            the solver's gauge, z(s[0]) = its undeformed height).
        """
        import pandas as pd

        df = pd.DataFrame({k: np.asarray(getattr(self, k), dtype=float) for k in FIELDS})
        df.attrs.update(units=dict(FIELD_UNITS), problem=self.problem.describe(),
                        energy=float(self.energy), energy_units="C R^2",
                        converged=bool(self.converged), solver=self.solver.to_dict(),
                        gauge="solver: z(s[0]) = z0(s[0]), the undeformed height of the first "
                              "point")
        return df

    def to_xarray(self):
        """The fields as an xarray Dataset with the undeformed arclength ``s`` as coordinate.

        Needs the optional extra ``xarray`` (``pip install 'morphoshell[xarray]'``).

        Returns
        -------
        xarray.Dataset
            One variable per field of :data:`FIELDS` along ``s``, each with
            ``units`` and ``long_name``; the attributes are the problem
            (``family``, ``h``, ``cut``, ``opening`` in units of R,
            ``param_<name>``, and ``problem`` as JSON), ``energy`` (C R²),
            ``converged``, the solver's ``method``, ``nodes`` and ``status``:
            strings and numbers only, so the Dataset can be written to netCDF.
        """
        xr = xarray_module()
        data = {k: ("s", np.asarray(getattr(self, k), dtype=float),
                    {"units": FIELD_UNITS[k], "long_name": FIELD_NAMES[k]})
                for k in FIELDS if k != "s"}
        coords = {"s": ("s", np.asarray(self.s, dtype=float),
                        {"units": "R", "long_name": FIELD_NAMES["s"]})}
        attrs = {**problem_attrs(self.problem), "energy": float(self.energy),
                 "energy_units": "C R^2", "converged": int(self.converged),
                 "method": self.solver.method, "nodes": int(self.solver.nodes),
                 "status": str(self.solver.status), "z_gauge": "solver: z(s[0]) = z0(s[0])"}
        return xr.Dataset(data, coords=coords, attrs=attrs)

    def to_dict(self, arrays: bool = True) -> dict:
        """JSON-ready: problem, energy, solver, units (:data:`JSON_UNITS`) and (optionally)
        the nodal arrays."""
        out = {"problem": self.problem.describe(), "converged": self.converged,
               "energy": self.energy, "units": dict(JSON_UNITS), "solver": self.solver.to_dict(),
               "error_estimate": None if self.error is None else self.error.to_dict(),
               "edge_start": self.edge("start"), "edge_end": self.edge("end")}
        if arrays:
            out.update({k: getattr(self, k).tolist() for k in FIELDS})
        return out


def _released() -> None:
    """The solver reference of an unpickled result (:meth:`Equilibrium.__getstate__`): like a
    dead weak reference, it gives None."""
    return None


def unconverged(eq: Equilibrium) -> Equilibrium:
    """``eq`` marked as not converged (the last iterate of a failure)."""
    return replace(eq, converged=False)
