"""Parameter sweeps: equilibria or ablations on the Cartesian product of axes, in parallel.

:func:`sweep` solves (or, with ``ablate=True``, ablates) a problem at every
point of the Cartesian product of its ``axes`` (any of h, theory, cut,
opening and the family's parameters) and returns a
:class:`~morphoshell.workflows.sweep_results.SweepResult`, a table with one
row per point (:meth:`~morphoshell.workflows.sweep_results.SweepResult.to_dataframe`)
that is also an xarray Dataset with the axes as dimensions
(:meth:`~morphoshell.workflows.sweep_results.SweepResult.to_xarray`).

How it is fast
--------------
The product is cut into *chunks*: segments of one line along the *chunk
axis* (the numeric axis with the most values), at fixed values of the other
axes, in increasing position along it.  One chunk is one task of
:mod:`morphoshell.workflows.executor` (Dask distributed, a process pool or this
process); a worker solves a chunk with its own solvers, each point
warm-started from the previous one, so a point costs about one warm solve
(two for an ablation: the intact and the cut shell) instead of
``solve()``'s continuation and error estimate (5–10 solves).

* **Branch safety.** The first point of a chunk, and a point after a failure,
  is reached by continuation from the family's stress-free parameters
  (:func:`morphoshell.solvers.continuation.continue_to`), as :func:`solve` does.  A
  warm step that fails or needs more than
  :data:`~morphoshell.solvers.continuation.HARD_STEP` Newton iterations (a sign of a
  jump to another branch) is split in two, recursively (at most
  :data:`MAX_SPLITS` times), as :class:`morphoshell.inverse.recoil_model.RecoilModel` does;
  so is one that left its start's branch (past a fold: :mod:`.sweep_steps`), and where the
  last split still does, the point is solved by continuation and the sweep notes it;
  the last resort is continuation again.  Where the shell is bistable the warm path
  can keep to another stable state than ``solve()``'s route: after a snap or switch the
  next point is reached by continuation, and a chunk whose last point is another state
  than continuation reaches there is solved again by continuation at every point.
* **Meshes.** Every point is solved on the mesh :func:`solve` and
  :func:`~morphoshell.mechanics.ablation.ablate` would use
  (:func:`morphoshell.numerics.mesh.mesh_spec`, graded for the point's h and cut, the
  intact shell anchored at its s = Σ), so each row agrees with
  ``solve(point)`` or ``ablate(point)`` to the solver's tolerance, whatever the
  chunking and the number of workers.  The mesh changes only where a
  rounded grading or anchor knot moves to the next octave, or a breakpoint's
  knot moves; the solution is then carried over by interpolation
  (:func:`morphoshell.solvers.refinement.solve_from`), and where the new mesh
  does not hold at the previous point, the step is split, each half on its own
  end's mesh.  Solvers are built once per worker process and mesh (cached).
* **Error estimates** need two more meshes per point (the half and the
  quarter mesh, as :func:`solve`'s estimate), which would triple a sweep's
  cost.  ``errors="ends"`` (default) estimates at both ends of the chunk
  axis for every value of the other axes (the discretisation error varies
  smoothly along a line); ``"all"`` at every point; ``"none"`` nowhere.
  Rows without an estimate have NaN in the ``*_error`` columns.
* **Caveats** that ``solve()`` warns of at each shell (walls that pass through
  each other, an estimate above :data:`~morphoshell.solvers.refinement.COARSE`,
  an estimate that cannot be made) the sweep says once, naming the points
  (:mod:`morphoshell.workflows.sweep_notes`).
* **Determinism.** The chunks depend on the sweep only, never on the number
  of workers, and are independent: the same sweep gives the same numbers on
  any number of workers.

Columns (units in ``SweepResult.units``; lengths in units of R, angles in
radians, energies in C R²)
-------------------------------------------------------------------------
The axes (in ablation sweeps the far-end opening P is ``opening_P``; units as the
family declares its parameters), then

* solves: ``energy`` and the edge values ``r_start``, ``psi_start``,
  ``r_end``, ``psi_end`` and ``z_end`` (the last point's height above the
  first), each with its ``<name>_error``;
* ablations: the observables of :class:`~morphoshell.mechanics.ablation.Ablation`
  (``opening``, ``rotation``, ``displacement``, ``radial_displacement``,
  ``axial_displacement``, ``energy_released``, ``energy_removed``) and the
  errors of the first four and of ``energy_released``;
* ``status`` (the back end's: Ipopt's, ``Newton_Converged`` for a warm start
  certified by :mod:`morphoshell.numerics.newton`, or a
  :class:`~morphoshell.solvers.results.SolverError`'s for a failed point, whose values are NaN:
  failed points are never dropped), ``iterations`` (Newton iterations spent on the point, the intact
  and the cut shell together), ``path`` (``continuation``, ``warm``, ``split`` or
  ``remesh``), ``event`` (what the point's continuation crossed: ``snapped``,
  ``switched``), ``walls_cross`` (the walls pass through each other:
  :func:`~morphoshell.solvers.contact.wall_contact`), ``seconds`` (wall time of
  the point in its worker) and ``message`` (why a point failed).
"""
from __future__ import annotations

import logging
import math
import os
import time
from dataclasses import dataclass
from functools import partial
from itertools import product
from typing import Any, Mapping, Sequence

import numpy as np

from .._runtime import lifeline
from ..mechanics.ablation import UNITS as ABLATION_UNITS
from ..mechanics.ablation import intact_problem, measure, relative_errors
from ..model.problem import BASE_KEYS, Problem
from ..model.profiles import ENTRY_POINT_GROUP, FAMILIES
from ..numerics.mesh import mesh_spec
from ..numerics.status import RETRY_FINER, STEP_NOT_SPLITTABLE
from ..solvers.continuation import SAME_STATE, continue_to
from ..solvers.direct import check_nodes
from ..solvers.contact import wall_contact
from ..solvers.options import BVP_ADVICE, check_direct_options
from ..solvers.observables import RECOIL
from ..solvers.refinement import (COARSE, coarse_level, error_estimate, half_mesh, level_errors,
                                  too_coarse)
from ..solvers.results import ESTIMATED, Equilibrium, SolverError
from ..solvers.routes import DIRECT_OPTIONS
from .executor import check_workers, no_free_core
from .sweep_notes import log_summary
from .sweep_results import SweepResult, point_label, result_columns
from .sweep_steps import MAX_SPLITS, Shell, point_events
from .sweep_runs import (SweepInterrupted, interruptible, restored, run_chunks, settings_record,
                         whole_chunks)

__all__ = ["sweep", "SweepInterrupted", "ERRORS", "MAX_SPLITS", "SOLVE_COLUMNS", "ABLATE_COLUMNS",
           "ESTIMATED_ABLATION", "UNITS", "chunk_plan"]

log = logging.getLogger(__name__)

#: Where error estimates are computed (see the module docstring).
ERRORS = ("ends", "all", "none")
#: Chunking: at least this many tasks when the product allows it (enough to keep
#: 2, 3, 4 or 6 workers busy to the end) ...
MIN_TASKS = 12
#: ... but no chunk shorter than this (each chunk starts with a continuation,
#: about ten warm solves' worth) ...
MIN_CHUNK = 16
#: ... or longer than this (progress and load balance on many workers).
MAX_CHUNK = 256
#: Below this many solves (two per ablation) ``workers=None`` runs in this
#: process: a Dask cluster's start and each worker's imports and solver builds cost
#: more than a second core saves (on 2 cores the routes break even at about 400 solves
#: when the second core is free; docs/benchmarks.md, "Sweeps and campaigns: when
#: workers pay") ...
SERIAL_BELOW = 400
#: ... and below this many when no core is free
#: (:func:`~morphoshell.workflows.executor.no_free_core`: at load 3-6 on 2 cores two workers lost up
#: to 600 ablations and won at 999).
SERIAL_BELOW_BUSY = 1400

#: Value columns of a solve sweep (energy in C R², edge values in R and rad).
SOLVE_COLUMNS = ESTIMATED
#: Value columns of an ablation sweep (:class:`~morphoshell.mechanics.ablation.Ablation`'s
#: observables).
ABLATE_COLUMNS = (*RECOIL, "energy_released", "energy_removed")
#: The ablation observables that get an error estimate.
ESTIMATED_ABLATION = ("opening", "rotation", "displacement", "energy_released")
#: Units of the columns (lengths in units of R, angles in rad, energies in C R²).
UNITS = {"energy": "C R^2", "r_start": "R", "psi_start": "rad", "r_end": "R", "psi_end": "rad",
         "z_end": "R", **ABLATION_UNITS, "h": "R", "cut": "R", "opening_P": "R",
         "seconds": "s", "iterations": "1"}
#: Families that worker processes can load by name: the packaged ones.
_PACKAGED = frozenset(FAMILIES)


# --------------------------------------------------------------------------
# the plan: points, validated, and chunks
# --------------------------------------------------------------------------

def _check_axes(problem: Problem, axes: Mapping[str, Sequence]) -> dict[str, tuple]:
    """The axes as tuples, every name and value checked (ValueError naming it)."""
    if not isinstance(axes, Mapping) or not axes:
        raise ValueError(f"axes = {axes!r} must be a non-empty mapping of names to values, "
                         f"e.g. {{'k': [0, 0.5], 'cut': [0.1, 0.2]}}")
    valid = (*BASE_KEYS, *problem.family_obj.parameters)
    out = {}
    for name, values in axes.items():
        if name not in valid:
            raise ValueError(f"sweep axis {name!r} is not a key of a {problem.family!r} problem; "
                             f"valid: {list(valid)}")
        values = _axis_values(name, values)
        out[name] = tuple(float(v) if name != "theory" else v for v in values)
    return out


def _axis_values(name: str, values) -> tuple:
    """The values of axis ``name`` as a tuple of Python scalars: a list of distinct values,
    finite numbers (theory names for ``theory``)."""
    if isinstance(values, (str, bytes)) or not isinstance(values, (Sequence, np.ndarray)):
        raise ValueError(f"sweep axis {name!r}: the values {values!r} must be a list")
    values = tuple(v.item() if isinstance(v, np.generic) else v for v in values)
    if not values:
        raise ValueError(f"sweep axis {name!r} has no values")
    for v in values:
        if name == "theory":
            if not isinstance(v, str):
                raise ValueError(f"sweep axis 'theory': {v!r} is not a theory name")
        elif isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ValueError(f"sweep axis {name!r}: {v!r} is not a finite number")
    if len(set(values)) != len(values):
        repeated = sorted({v for v in values if values.count(v) > 1}, key=str)
        raise ValueError(f"sweep axis {name!r} repeats the value(s) {repeated}")
    return values


def chunk_plan(axes: Mapping[str, Sequence], chunk_size: int | None = None
               ) -> tuple[str, list[list[int]]]:
    """How a sweep is cut into tasks: (the chunk axis, row indices of every chunk, in order).

    Rows are numbered in the order of the Cartesian product (last axis
    fastest).  The chunk axis is the numeric axis with the most values (the
    last of equals); each line along it, at fixed values of the other axes,
    is cut into segments of about equal length (at most ``chunk_size``; by
    default at least :data:`MIN_TASKS` chunks in all where lines allow it,
    each of :data:`MIN_CHUNK` to :data:`MAX_CHUNK` points).  The plan depends
    on the axes only, never on the number of workers.

    Parameters
    ----------
    axes : mapping
        Axis name → values (only their number and the name ``theory`` count).
    chunk_size : int, optional
        Most points per chunk.

    Returns
    -------
    chunk_axis : str
        The axis the chunks run along.
    chunks : list of list of int
        Row indices of each chunk, increasing along the chunk axis; together
        every row of the product once.

    Raises
    ------
    ValueError
        ``chunk_size`` is not a positive integer.
    """
    names = list(axes)
    shape = [len(axes[n]) for n in names]
    numeric = [i for i, n in enumerate(names) if n != "theory"] or list(range(len(names)))
    c = max(reversed(numeric), key=lambda i: shape[i])
    n, lines = shape[c], int(np.prod(shape)) // shape[c]
    if chunk_size is not None:
        if isinstance(chunk_size, bool) or not isinstance(chunk_size, (int, np.integer)) \
                or chunk_size < 1:
            raise ValueError(f"chunk_size = {chunk_size!r} must be a positive integer")
        segments = math.ceil(n / chunk_size)
    else:
        segments = max(1, min(math.ceil(MIN_TASKS / lines), n // MIN_CHUNK),
                       math.ceil(n / MAX_CHUNK))
    bounds = np.linspace(0, n, segments + 1).round().astype(int)
    index = np.arange(int(np.prod(shape))).reshape(shape)
    others = [range(s) if i != c else [slice(None)] for i, s in enumerate(shape)]
    chunks = []
    for key in product(*others):
        line = index[key]
        chunks += [line[a:b].tolist() for a, b in zip(bounds[:-1], bounds[1:]) if b > a]
    return names[c], chunks


def _points(problem: Problem, axes: Mapping[str, tuple], ablate: bool, nodes: int,
            stages: int) -> list[dict]:
    """Every point's updates, each problem validated (ValueError naming the point)."""
    names = list(axes)
    points, intact = [], {}
    for values in product(*axes.values()):
        updates = dict(zip(names, values))
        where = ", ".join(f"{k} = {v!r}" for k, v in updates.items())
        try:
            p = problem.with_updates(**updates)
            if ablate:
                if not p.cut > 0:
                    raise ValueError(f"cut (Sigma) = {p.cut!r}: an ablation needs a cut > 0")
                key = tuple((k, v) for k, v in updates.items() if k != "cut")
                if key not in intact:       # the intact shell does not depend on the cut
                    intact[key] = intact_problem(p)
                mesh_spec(intact[key], nodes, stages, (p.cut,))   # the rim must be a node
            else:
                mesh_spec(p, nodes, stages)       # (breakpoints too close to be nodes)
        except ValueError as exc:
            raise ValueError(f"sweep point {where}: {exc}") from None
        points.append(updates)
    return points


def _portable(problem: Problem) -> bool:
    """Whether a fresh worker process finds the problem's family by its name."""
    if problem.family in _PACKAGED and FAMILIES.get(problem.family) is problem.family_obj:
        return True
    from importlib.metadata import entry_points
    return problem.family in {ep.name for ep in entry_points(group=ENTRY_POINT_GROUP)}


# --------------------------------------------------------------------------
# the work: one chunk in one worker
# --------------------------------------------------------------------------

@dataclass(frozen=True)
class _Chunk:
    """A task: the base problem (a description), the points and how to solve them."""

    base: Mapping[str, Any]
    points: tuple[tuple[int, Mapping[str, Any]], ...]
    ablate: bool
    nodes: int
    options: Mapping[str, Any]
    estimate: tuple[bool, ...]
    #: The sweep's process (:mod:`morphoshell._runtime.lifeline`): a worker ends when it has.
    owner: tuple | None = None


def _measure(problem: Problem, pre: Equilibrium, post: Equilibrium) -> dict[str, float]:
    """The observables of :class:`~morphoshell.mechanics.ablation.Ablation`, as ``ablate``
    measures them (:func:`~morphoshell.mechanics.ablation.measure`)."""
    return measure(problem.cut, pre, post)


def _estimate(shells: Sequence[tuple[Shell, Problem, tuple, Equilibrium]], measure,
              order: int) -> tuple[dict[str, float], str]:
    """Error of each value of ``measure``: the half and quarter meshes, as ``solve()``'s
    estimate; (errors, "") or (NaN errors, why there is no estimate).

    :func:`morphoshell.solvers.refinement.level_errors` of the levels
    :func:`~morphoshell.solvers.refinement.coarse_level` finds (the quarter mesh may be
    missing, as in ``solve()``).
    """
    levels = [measure([eq for *_, eq in shells])]
    eqs = [eq for *_, eq in shells]
    nodes, note = shells[0][0].nodes, ""
    for _ in range(2):
        nodes, found = half_mesh(nodes), []
        for (shell, p, anchors, _), eq in zip(shells, eqs):
            level, note = coarse_level(partial(shell.solver, p, anchors), nodes, p, eq, anchors)
            if level is None:
                break
            found.append(level)
        if len(found) < len(shells):
            break
        eqs = found
        levels.append(measure(eqs))
    if len(levels) < 2:
        return {k: math.nan for k in levels[0]}, note
    return level_errors(levels[0], levels[1], levels[2] if len(levels) > 2 else None, order), ""


def _run_chunk(chunk: _Chunk, tick=None) -> list[tuple[int, dict]]:
    """Solve one chunk in order, each point warm-started from the previous one (a task);
    again by ``solve()``'s route at every point where the warm path ended on another
    stable state than that route (:func:`_left_solves_branch`).  ``tick()`` after each
    point of the first pass (a progress bar in this process)."""
    lifeline.watch(chunk.owner)     # (a pool's workers outlived a killed sweep, idle)
    rows, shells = _solve_chunk(chunk, verify=False, tick=tick)
    if _left_solves_branch(rows, shells):
        rows, _ = _solve_chunk(chunk, verify=True)
    return rows


def _left_solves_branch(rows: list[tuple[int, dict]], shells: Sequence[Shell]) -> bool:
    """Whether the chunk's last point, reached warm, is another state than ``solve()``'s
    route reaches there (continuation from the stress-free parameters).

    Where a shell is bistable the two can differ, both stable: a sweep of κ₁ from −8
    stayed on the state its first point snapped to up to κ₁ = 3, where ``solve()`` ends
    on the other (energies 0.027 against 0.018).  :attr:`Shell.crossed` keeps to the
    route after a snap; this catches the rest at one continuation per chunk.
    """
    if len(rows) < 2 or rows[-1][1]["path"] in ("continuation", "failed"):
        return False
    for shell in shells:
        if shell.last is None:
            continue
        problem, anchors, eq = shell.last
        try:
            route = continue_to(shell.solver(problem, anchors), problem, anchors, switch=True)
        except SolverError:
            return True
        if np.max(np.abs(route.x - eq.x)) > SAME_STATE:
            log.info("sweep: the warm path to %s ended on another state than solve()'s "
                     "(bistable): the chunk again by continuation at every point",
                     problem.params)
            return True
    return False


def _solve_chunk(chunk: _Chunk, verify: bool, tick=None) -> tuple[list[tuple[int, dict]], tuple]:
    """The rows of one chunk and its two shells (:func:`_run_chunk`); with ``verify`` every
    point by continuation; ``tick()`` after each point, if given."""
    base = Problem(**chunk.base)
    options = dict(chunk.options)
    order = 2 * options.get("stages", 2)
    post_shell = Shell(chunk.nodes, options, verify=verify)
    pre_shell = Shell(chunk.nodes, options, verify=verify)
    names = ABLATE_COLUMNS if chunk.ablate else SOLVE_COLUMNS
    rows, intact, intact_key = [], None, None
    for (index, updates), estimate in zip(chunk.points, chunk.estimate):
        t0 = time.perf_counter()
        # (named by its point: the notes of its continuation, -v, and its messages say which)
        problem = base.with_updates(
            **updates, name=f"{base.name or base.family} ({point_label(updates, chunk.ablate)})")
        if chunk.ablate and intact_key != (key := {k: v for k, v in updates.items() if k != "cut"}):
            intact, intact_key = intact_problem(problem), key   # the same for every cut
        row = _blank_row(chunk.ablate)
        try:
            if chunk.ablate:
                eqs = _ablate_point(row, problem, intact, pre_shell, post_shell, estimate, order)
            else:
                eqs = _solve_point(row, problem, post_shell, estimate, order)
            _flag(row, eqs)
            # (the warm path jumped branches before this point: the sweep's note names it)
            row["_jumped"] = pre_shell.jumped or post_shell.jumped
        except SolverError as exc:
            row.update({k: math.nan for k in names}, status=exc.status,
                       path="failed", message=_in_sweep_terms(str(exc).splitlines()[0]))
        row["seconds"] = time.perf_counter() - t0
        rows.append((index, row))
        if tick is not None:
            tick()
    return rows, (pre_shell, post_shell)


def _blank_row(ablate: bool) -> dict[str, Any]:
    """A row before its point is solved: NaN values and errors, empty bookkeeping."""
    names, estimated = ((ABLATE_COLUMNS, ESTIMATED_ABLATION) if ablate else
                        (SOLVE_COLUMNS, SOLVE_COLUMNS))
    row: dict[str, Any] = {k: math.nan for k in names}
    row.update({f"{k}_error": math.nan for k in estimated})
    row.update(status="", iterations=0, path="", event="", walls_cross=False, message="")
    return row


def _flag(row: dict, eqs: Sequence[Equilibrium]) -> None:
    """The row's status (the last shell's), ``event`` (what the continuations of its
    shells crossed: :func:`point_events`) and ``walls_cross`` (a shell's walls pass through
    each other, which ``solve()`` warns of: :func:`~morphoshell.solvers.contact.wall_contact`)."""
    row["status"] = eqs[-1].solver.status
    row["event"] = ", ".join(dict.fromkeys(e for eq in eqs for e in point_events(eq)))
    row["walls_cross"] = any(wall_contact(eq) is not None for eq in eqs)


#: Advice of the solvers' messages in a sweep's terms: a sweep has no rtol and no bvp method.
_SWEEP_TERMS = ((RETRY_FINER, "more nodes: nodes=, --nodes"),
                (BVP_ADVICE, 'solve() with method="bvp", point by point (morphoshell solve '
                             '--method bvp; sweeps use the direct method),'))


def _in_sweep_terms(message: str) -> str:
    """A failure message with the options it advises that a sweep lacks put in its terms."""
    for theirs, ours in _SWEEP_TERMS:
        message = message.replace(theirs, ours)
    return message


def _solve_point(row: dict, problem: Problem, shell: Shell, estimate: bool,
                 order: int) -> tuple[Equilibrium]:
    """Solve one point of a chunk into ``row`` (values, path, iterations, errors); (its
    equilibrium,)."""
    try:
        post, row["path"] = shell.advance(problem, ())
    finally:
        row["iterations"] += shell.iterations
    row.update(post.estimated_values())
    if estimate:
        errors, row["_unestimated"] = _estimate([(shell, problem, (), post)],
                                                lambda eqs: eqs[0].estimated_values(), order)
        row.update({f"{k}_error": v for k, v in errors.items()})
        # solve()'s estimate, its energy floor with it (h for a stress-free shell)
        est = error_estimate(post, errors, half_mesh(shell.nodes), order)
        row["_coarse"] = too_coarse(est) if not row["_unestimated"] else None
    return (post,)


def _ablate_point(row: dict, problem: Problem, intact: Problem, pre_shell: Shell,
                  post_shell: Shell, estimate: bool, order: int) -> tuple[Equilibrium, ...]:
    """Ablate one point of a chunk into ``row``: the intact shell, then the cut one.

    The row's path is the most laborious of the two shells'.  Returns the
    equilibria of the intact and the cut shell.
    """
    rim = (problem.cut,)
    try:
        pre, pre_path = pre_shell.advance(intact, rim)
    finally:
        row["iterations"] += pre_shell.iterations
    try:
        post, post_path = post_shell.advance(problem, ())
    finally:
        row["iterations"] += post_shell.iterations
    values = _measure(problem, pre, post)
    row.update(values)
    paths = (pre_path, post_path)
    row["path"] = next(p for p in ("continuation", "split", "remesh", "warm") if p in paths)
    if estimate:
        errors, row["_unestimated"] = _estimate(
            [(pre_shell, intact, rim, pre), (post_shell, problem, (), post)],
            lambda eqs: {k: v for k, v in _measure(problem, *eqs).items()
                         if k in ESTIMATED_ABLATION}, order)
        row.update({f"{k}_error": v for k, v in errors.items()})
        # relative to the observables' scales, as ablate() warns (a tiny cut's d was 27 % off
        # on 200 nodes where its error in R, 4e-8, passed)
        rel = relative_errors(values, errors, intact, problem)
        worst = max(rel, key=lambda k: rel[k])
        row["_coarse"] = ((worst, rel[worst]) if rel[worst] > COARSE and not row["_unestimated"]
                          else None)
    return pre, post


# --------------------------------------------------------------------------
# the front door
# --------------------------------------------------------------------------

def sweep(problem: Problem, axes: Mapping[str, Sequence], *, ablate: bool = False,
          nodes: int = 200, workers: int | None = None, scheduler: str | None = None,
          errors: str = "ends", chunk_size: int | None = None,
          resume: str | os.PathLike | None = None, **options) -> SweepResult:
    """Solve or ablate ``problem`` at every point of the Cartesian product of ``axes``.

    Parameters
    ----------
    problem : Problem
        The base problem; a point is ``problem.with_updates(**point)``.
    axes : mapping
        Axis name → values, e.g. ``{"k": [0, 0.5, 2], "cut": np.linspace(0.05, 1.4, 15)}``:
        h, theory, cut, opening or a parameter of the problem's family
        (numbers; theory names for ``theory``).  Rows follow the product in
        this order, the last axis fastest.  Every point is validated before
        any work starts.
    ablate : bool
        Ablate at every point (the cut is Σ > 0; recoil observables, as
        :func:`~morphoshell.mechanics.ablation.ablate`) instead of solving it.
    nodes : int
        Mesh nodes (direct method; see :func:`~morphoshell.solvers.routes.solve`).
    workers : int, optional
        Worker processes (see :func:`morphoshell.workflows.executor.open_executor`).
        Default: this process for fewer than :data:`SERIAL_BELOW` solves
        (two per ablation; :data:`SERIAL_BELOW_BUSY` when the load average leaves no
        core free), else one per CPU core.  Never more than one per chunk
        (a sweep of one chunk runs in this process).  Families registered
        only in this session (not packaged, not a plugin) need ``workers=1``.
    scheduler : str, optional
        Address of a running Dask scheduler (or ``DASK_SCHEDULER_ADDRESS``).
    errors : {"ends", "all", "none"}
        Where to estimate discretisation errors (see the module docstring).
    chunk_size : int, optional
        Most points per task (default: see :func:`chunk_plan`).
    resume : str or Path, optional
        A partial sweep's file (:meth:`SweepInterrupted.write`, CSV or JSON): its finished
        chunks are kept and only the others computed (none there: all are).  Its rows are
        restored at the grid points of their axis values, wherever they stand in the file
        (a point without a row is computed again).
    **options
        Direct solver options: ``stages``, ``linear_solver``, ``tol``,
        ``max_iter``, ``stability``, ``ipopt_options``.

    Returns
    -------
    SweepResult
        One row per point, failed points included (NaN values, their status).

    Raises
    ------
    ValueError
        A bad axis, value or option, a point that is not a valid problem (named), or a
        ``resume`` file that is not a partial sweep with these settings (the setting
        named) or has a row off the grid (the row named), before any work.
    SweepInterrupted
        Ctrl-C (a ``KeyboardInterrupt``): the workers are stopped at once; it holds the
        rows of the chunks finished (:mod:`morphoshell.workflows.sweep_runs`).

    Examples
    --------
    >>> from morphoshell import Problem, sweep
    >>> res = sweep(Problem("uniform", h=0.3, cut=0.3), {"k": [0.0, 0.5]}, nodes=60,
    ...             workers=1)
    >>> res.to_dataframe()[["k", "psi_start"]].round(3).values.tolist()
    [[0.0, 0.822], [0.5, 0.561]]
    """
    nodes, stages = _check_arguments(problem, nodes, errors, options)
    axes = _check_axes(problem, axes)
    points = _points(problem, axes, ablate, nodes, stages)
    chunk_axis, chunks = chunk_plan(axes, chunk_size)
    plan = {"chunks": len(chunks), "chunk_axis": chunk_axis, "nodes": nodes, "errors": errors}
    n, blank = len(points), _blank_row(ablate)
    settings = settings_record(problem, axes, ablate, nodes, errors, chunk_size,
                               {**options, "stages": stages})
    kept = (restored(resume, settings, blank, axes, ablate,
                     ABLATE_COLUMNS if ablate else SOLVE_COLUMNS) if resume else {})
    results = whole_chunks(kept, chunks, n)
    chunks = [c for c in chunks if results[c[0]] is None]     # (the others restored)
    todo = sum(map(len, chunks))
    if scheduler is None and not os.environ.get("DASK_SCHEDULER_ADDRESS"):
        workers = _local_workers(workers, todo * (2 if ablate else 1), len(chunks))
    parallel = scheduler is not None or os.environ.get("DASK_SCHEDULER_ADDRESS") or workers != 1
    if parallel and not _portable(problem):
        raise ValueError(f"family {problem.family!r} is registered only in this session: worker "
                         f"processes cannot load it; use workers=1, or install it as a plugin "
                         f"(entry point group {ENTRY_POINT_GROUP!r})")
    base = problem.describe()
    if not parallel:
        base = {**base, "family": problem.family_obj}     # not pickled: any family
    tasks = _tasks(base, axes, chunk_axis, chunks, points, ablate, nodes, options, errors)
    what = "ablations" if ablate else "equilibria"
    log.info("sweep of %d %s (%s) in %d chunks along %s", n, what,
             " x ".join(f"{len(v)} {k}" for k, v in axes.items()), len(chunks), chunk_axis)
    t0 = time.perf_counter()
    finish = partial(_finish, problem, axes, ablate, timing={"t0": t0, **plan})
    with interruptible(results, blank, finish, settings):
        backend = run_chunks(_run_chunk, tasks, results, workers, scheduler,
                             f"sweep: {todo} {what}")
    notes = _row_notes(results)
    result = _finish(problem, axes, ablate, results, timing={
        "t0": t0, "workers": workers if scheduler is None else "scheduler",
        "backend": backend, **plan, "restored": n - todo})
    log_summary(result, *notes)
    return result


def _row_notes(rows: list[dict]) -> tuple[dict, dict, list]:
    """What the summary says of the rows, not their columns (the errors' columns show it),
    taken out of them: the rows whose estimate is too coarse, those without an estimate
    asked for, and those whose warm path left its branch (:func:`log_summary`'s)."""
    coarse = {i: c for i, row in enumerate(rows) if (c := row.pop("_coarse", None))}
    unestimated = {i: u for i, row in enumerate(rows) if (u := row.pop("_unestimated", ""))}
    jumped = [i for i, row in enumerate(rows) if row.pop("_jumped", False)]
    return coarse, unestimated, jumped


def _finish(problem: Problem, axes: Mapping[str, tuple], ablate: bool, rows: list[dict],
            timing: Mapping[str, Any]) -> SweepResult:
    """The :class:`SweepResult` of ``rows`` (every point's, in the product's order), its
    ``timing``'s ``t0`` (when the work began) replaced by the seconds since."""
    columns = result_columns(axes, rows, ablate)
    timing = {"seconds": time.perf_counter() - timing["t0"],
              **{k: v for k, v in timing.items() if k != "t0"}}
    return SweepResult(problem, axes, bool(ablate), columns,
                       _units(columns, problem.family_obj.units), timing)


def _check_arguments(problem: Problem, nodes: int, errors: str, options: Mapping
                     ) -> tuple[int, int]:
    """(nodes, stages) of :func:`sweep`, with its problem, errors and options checked."""
    if not isinstance(problem, Problem):
        raise ValueError(f"problem must be a Problem, got {problem!r}")
    unknown = sorted(set(options) - set(DIRECT_OPTIONS) | ({"max_nodes"} & set(options)))
    if unknown:
        raise ValueError(f"unknown option(s) {unknown} of a sweep; valid: "
                         f"{[o for o in DIRECT_OPTIONS if o != 'max_nodes']}")
    if errors not in ERRORS:
        raise ValueError(f"errors = {errors!r} must be one of {list(ERRORS)}")
    nodes = check_nodes(nodes)
    check_direct_options(**options)       # (a linear solver Ipopt cannot load: before the workers)
    return nodes, options.get("stages", 2)


def _local_workers(workers: int | None, solves: int, chunks: int) -> int:
    """Workers of a sweep of ``solves`` solves in ``chunks`` chunks without a scheduler:
    ``workers``, by default this process below :data:`SERIAL_BELOW` solves
    (:data:`SERIAL_BELOW_BUSY` when no core is free) and else one per CPU core; at most one
    per chunk (a worker without a chunk only costs its start: a 21-point
    sweep on 2 workers had taken 2.6 s against 1.2 s in one process, audit 18)."""
    workers = check_workers(workers)
    if workers is None:
        serial_below = SERIAL_BELOW_BUSY if no_free_core() else SERIAL_BELOW
        workers = 1 if solves < serial_below else os.cpu_count() or 1
    return max(1, min(workers, chunks))


def _tasks(base: Mapping[str, Any], axes: Mapping[str, tuple], chunk_axis: str,
           chunks: list[list[int]], points: list[dict], ablate: bool, nodes: int,
           options: Mapping[str, Any], errors: str) -> list[_Chunk]:
    """One :class:`_Chunk` per chunk of the plan, each point marked where errors are estimated.

    ``errors="ends"`` estimates at both ends of the chunk axis (its first and
    last value), ``"all"`` everywhere.
    """
    c = list(axes).index(chunk_axis)
    line = len(axes[chunk_axis])
    tasks = []
    for rows in chunks:
        where = [np.unravel_index(i, [len(v) for v in axes.values()])[c] for i in rows]
        estimate = tuple(errors == "all" or (errors == "ends" and w in (0, line - 1))
                         for w in where)
        tasks.append(_Chunk(base, tuple((i, points[i]) for i in rows), bool(ablate), nodes,
                            dict(options), estimate, lifeline.owner()))
    return tasks


def _units(columns: Mapping[str, np.ndarray], family_units: Mapping[str, str]
           ) -> dict[str, str]:
    """The units of the columns there are: :data:`UNITS`, the family's parameters' (as
    the family declares them), the errors' (their values')."""
    known = {**UNITS, **family_units}     # (the axis opening, P, and the observable o: R)
    units = {k: v for k, v in known.items() if k in columns}
    units.update({f"{k}_error": known[k] for k in known if f"{k}_error" in columns})
    return units
