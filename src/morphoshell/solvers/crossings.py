"""Past a stall of a branch: snap-throughs at folds, switches of branches at branch points.

A physical shell loaded quasi-statically does not follow the unstable part of a
branch (:mod:`morphoshell.solvers.arclength`): at a fold it *snaps through*.
:func:`snap_through` leaves the fold the way the shell would, down the energy
along the fold's null direction (the one direction of zero curvature) to the
stable equilibrium just beyond it.  Where the branch loses its stability at a
branch point, :func:`switch_stable` goes on along the stable half of the other
branch through it, or down the point's unstable mode.  :func:`cross_fold` finds
which of them ends a stall of natural-parameter continuation.
"""
from __future__ import annotations

import logging
from dataclasses import replace
from itertools import product

import numpy as np

from ..numerics.status import BRANCH_ENDED, SNAP_FAILED, explain
from .arclength import (EASY, GROWTH, MAX_STEP, MIN_STEP, ArcPoint, Arclength, Snap, Switch)
from .direct import DirectSolver
from .paths import ParameterLine
from .results import Equilibrium, SolverError

__all__ = ["snap_through", "switch_stable", "cross_fold", "branch_ended", "BUCKLE_OVERSHOOT"]

log = logging.getLogger(__name__)

#: How far past a branch point (in τ) a shell that leaves it down its unstable mode is
#: minimised (:func:`switch_stable`; raised up to 64-fold while it returns to the point).
BUCKLE_OVERSHOOT = 1e-3


def snap_through(arc: Arclength, fold: ArcPoint, direction: float = 1.0,
                 overshoot: float = 1e-3) -> tuple[Equilibrium, Snap]:
    """The stable equilibrium the shell snaps to from the fold ``fold``.

    Past the fold (at τ_f + ``overshoot`` in the ``direction`` of travel) the
    branch has no equilibrium nearby; the shell leaves the fold along its null
    direction (the tangent there, t_τ = 0), down the energy, and comes to rest
    at a stable equilibrium: minimised from there (a cold solve: Ipopt's
    descent) and certified a minimum, with an energy below the fold's.

    Parameters
    ----------
    arc : Arclength
    fold : ArcPoint
        A located fold.
    direction : float
        +1 when the continuation was going to larger τ.
    overshoot : float
        How far past the fold in τ the snapped state is solved (raised up to
        64-fold if the descent returns to the fold).

    Returns
    -------
    Equilibrium
        The snapped, stable equilibrium at τ_f + overshoot.
    Snap

    Raises
    ------
    SolverError
        ``"Snap_Through_Failed"`` when no stable equilibrium of lower energy is
        found past the fold; the fold's state is attached.
    """
    before = arc.equilibrium(fold)
    found = _descend(arc, fold, fold.t, np.copysign(overshoot, direction), before,
                     downhill=True, lower=True)
    if found is not None:
        eq, tau, landed = found
        log.debug("snap-through at tau = %.6g: energy %.6g -> %.6g", fold.tau, before.energy,
                  landed.energy)
        return eq, Snap(float(fold.tau), float(tau), float(before.energy), float(eq.energy),
                        float(landed.energy))
    raise SolverError(
        f"no stable equilibrium found past the fold at {fold.tau:.6g} of the way: "
        f"{explain(SNAP_FAILED)}; the fold's state is attached", SNAP_FAILED,
        replace(before, converged=False))


def _onward(arc: Arclength, point: ArcPoint, ds: float, target: float,
            max_points: int = 200) -> ArcPoint:
    """``point``'s branch followed by arclength steps while stable and τ grows, to τ ≥
    ``target``: the last such point."""
    for _ in range(max_points):
        if point.tau >= target or ds < MIN_STEP:
            break
        new = arc.correct(point, ds)
        if new is None or arc.turned(point, new):
            ds /= 2
            continue
        if not new.inertia.stable or new.t_tau <= 0 or new.tau > 1:
            break
        point = new
        if new.iterations <= EASY:
            ds = min(GROWTH * ds, MAX_STEP)
    return point


def _settled(arc: Arclength, point: ArcPoint) -> tuple[Equilibrium, float] | None:
    """(equilibrium, τ) of the stable ``point``; where it lies past an end of the path at
    parameters out of their ranges, the state minimised from its shape at the end itself
    (:meth:`ParameterLine.clipped`, as :func:`_descend`'s), None if that fails.

    The other branch's first point past a branch point just before a path's end at a
    parameter's bound (a step of it, 3e-4 of the way past the end) is no valid problem:
    its ValueError ended the solve and the walk as bad input, naming a value never given
    (the blister 1e-4 past its first branch point, G's range ending there: G = 0.00305017
    for 0.00304921).  Minimised at the end, as both re-solve a landing past it."""
    end = arc.line.clipped(point.tau)
    if end == point.tau:
        return arc.equilibrium(point), float(point.tau)
    x0, _ = arc.kkt.unpack(point.u)
    try:
        return arc.solver.solve(arc.line.at(end), x0=x0, anchors=arc.q), end
    except SolverError:
        return None


def _descend(arc: Arclength, point: ArcPoint, mode: np.ndarray, overshoot: float,
             before: Equilibrium, *, downhill: bool,
             lower: bool) -> tuple[Equilibrium, float, Equilibrium | None] | None:
    """(equilibrium, τ, landed): a stable state minimised from ``point`` moved along
    ``mode``, at τ + ``overshoot`` (raised up to 64-fold while the descent returns to
    ``point``'s state); None if none is found.

    ``downhill`` turns ``mode`` to where the energy falls there; ``lower``
    also asks for an energy below ``before``'s at ``point``'s τ (a snap-through's
    landing, ``landed``: :func:`_landed`; None without ``lower``).  Past an end of the
    path to parameters out of their ranges (an event just before a path's end at a
    parameter's bound) the descent is solved at the end itself, once
    (:meth:`ParameterLine.clipped`): the problem beyond is no valid one, and its
    ValueError ended the walk as bad input, naming a value never given.
    """
    mask = arc.kkt.x_mask
    taus = (arc.line.clipped(point.tau + overshoot * factor) for factor in (1, 4, 16, 64))
    for tau in dict.fromkeys(taus):              # (each once: clipped ones coincide)
        v = mode
        if downhill:
            state = arc.kkt.state(point.u, arc._data(tau))
            # rhs = −∇ of the (penalised) Lagrangian: the energy falls along +v where rhs·v > 0
            v = mode * np.copysign(1.0, state.rhs[mask] @ mode[mask])
        for size in (0.02, 0.1):
            x0, _ = arc.kkt.unpack(arc.kkt.moved(point.u, size * v))
            try:
                eq = arc.solver.solve(arc.line.at(tau), x0=x0, anchors=arc.q)
            except SolverError:
                continue
            if lower:      # a snap lands far away and lower, at the fold's own τ
                landed = _landed(arc, eq, point.tau, before)
                if landed is not None:
                    return eq, float(tau), landed
            elif _moved(eq, before, 1e-9):   # a buckle off a branch point (whose own state
                return eq, float(tau), None  # is unstable there, never certified): 3e-5
    return None


def _landed(arc: Arclength, eq: Equilibrium, tau: float,
            before: Equilibrium) -> Equilibrium | None:
    """``eq``'s branch followed back to τ = ``tau`` (``before``'s), if it lies lower than
    ``before`` there and away from it; else None.

    Energies compare at one τ only: along a path they change by dE/dτ Δτ, which can
    outweigh the drop of a small snap (a thin shell's edge curling over: 2·10⁻¹⁰ C R²
    against 1.7·10⁻⁷ for Δτ = 10⁻³).
    """
    try:
        back = arc.solver.solve(arc.line.at(tau), warm_start=eq, anchors=arc.q)
    except SolverError:
        return None
    return back if back.energy < before.energy and _moved(back, before) else None


def _buckled(bp: ArcPoint, before: Equilibrium, landing: tuple, half: float) -> tuple:
    """(equilibrium, τ, Switch) of a buckle off the branch point ``bp`` onto ``half``."""
    eq, tau, _ = landing
    log.debug("buckled at tau = %.6g (direction %+g)", bp.tau, half)
    return eq, tau, Switch(float(bp.tau), tau, half, float(before.energy), float(eq.energy),
                           descent=True)


def _rises(eq: Equilibrium, before: Equilibrium) -> bool:
    """Whether the far end of ``eq`` lies higher above its first point than ``before``'s."""
    return bool(eq.z[-1] - eq.z[0] > before.z[-1] - before.z[0])


def _moved(eq: Equilibrium, before: Equilibrium, tol: float = 1e-3) -> bool:
    """Whether ``eq`` left the state ``before`` by more than ``tol`` (it did not just slide
    back onto it)."""
    return bool(np.max(np.abs(eq.x - before.x)) > tol)


def branch_ended(tau: float, why: str, last: Equilibrium | None,
                 remedy: str | None = None) -> SolverError:
    """The error of a branch that ended at τ (``"Branch_Ended"``), with the status's
    explanation, or ``remedy`` where the cause is known."""
    return SolverError(f"the branch ended at {tau:.6g} of the way ({why}): "
                       f"{remedy or explain(BRANCH_ENDED)}", BRANCH_ENDED, last)


def cross_fold(solver: DirectSolver, eq: Equilibrium, line: ParameterLine, tau: float,
               anchors=(), *, reach: float = 0.01, max_points: int = 200,
               switch: bool = False) -> tuple[Equilibrium, float, Snap | Switch | None]:
    """Past the point where natural-parameter continuation stalled, on the way to τ = 1.

    From the stable solution ``eq`` at ``tau``, the branch is followed by
    pseudo-arclength steps until either τ has grown by ``reach`` on stable
    points (the stall was not a fold: natural continuation can go on from
    there), or τ turns back: a fold, located, where the shell snaps through
    (:func:`snap_through`).  With ``switch``, a branch point where the branch
    loses its stability is a third way: the branch point is located and the
    stable half of the other branch through it taken (:func:`switch_stable`).
    A fold or branch point located beyond τ = 1 is not crossed: the shell
    reaches the target before it, on the branch followed (:func:`_at_target`).

    Returns
    -------
    Equilibrium
        Stable, at the returned τ.
    float
        Its τ: past 1 only for a landing within a snap's or switch's overshoot
        past an event just before τ = 1, or a step past 1 where the branch was
        not found at 1, the parameters there within their ranges (continuation
        re-solves it at 1: :func:`~.continuation.continue_to`).
    Snap, Switch or None
        The snap-through or the switch of branches, if there was one.

    Raises
    ------
    SolverError
        ``"Branch_Ended"`` when the steps fail before either (or, with
        ``switch``, no branch through the branch point goes on stable; or the
        branch reaches the target unstable), or ``"Snap_Through_Failed"``
        (:func:`snap_through`).
    """
    arc = Arclength(solver, line, anchors)
    point = arc.start(eq, tau, 1.0)
    ds = 1e-3
    for _ in range(max_points):
        new = arc.correct(point, ds)
        if new is None or arc.turned(point, new):
            ds /= 2
            if ds < MIN_STEP:
                break
            continue
        if new.t_tau < 0:
            fold = arc.locate_fold(point, ds)
            if fold.tau > 1:          # (the target comes first: :func:`_at_target`)
                return _at_target(arc, point)
            eq_s, snap = snap_through(arc, fold, 1.0)
            return eq_s, snap.tau_after, snap
        if switch and point.inertia.stable and not new.inertia.stable:
            bp = arc.locate_change(point, ds, new)
            return _at_target(arc, point) if bp.tau > 1 else switch_stable(arc, bp, ds, reach)
        if new.tau >= min(1.0, tau + reach) and new.inertia.stable:
            if new.tau > 1:
                new = arc.at_tau(point, 1.0) or new
            return arc.equilibrium(new), float(new.tau), None
        if new.tau > 1:       # beyond, p leaves the segment (extrapolated: the family's ranges)
            return _at_target(arc, point)     # (stable there if it lost that past τ = 1)
        point = new
        if new.iterations <= EASY:
            ds = min(GROWTH * ds, MAX_STEP)
    raise branch_ended(point.tau, "no fold and no stable way on past the stall",
                       arc.equilibrium(point))


def _at_target(arc: Arclength, point: ArcPoint) -> tuple[Equilibrium, float, None]:
    """(equilibrium, 1.0, None): the branch at τ = 1 next to ``point`` (below it), where a
    step from ``point`` passed the target, before an event or not; ``"Branch_Ended"`` where
    it is not found or not stable there (it reaches the target unstable).

    A fold or branch point located past τ = 1 is one the shell never gets to: the snap
    from it landed on a state the target does not reach (the volvox_fold path to 1e-5
    before its fold, from 1.2e-4 before the end: snapped at λ = 1.00001, inverted, 0.017777
    C R² at λ = 1.00101, where the target's state is 0.022599), and where the parameters
    beyond leave their ranges the event's own problem's ValueError ended the solve as bad
    input.  A branch point past it is not where the shell lost its stability either: the
    branch reached the target stable.
    """
    end = arc.at_tau(point, 1.0)
    if end is None or not end.inertia.stable:
        raise branch_ended(point.tau, "it reaches the target unstable", arc.equilibrium(point))
    return arc.equilibrium(end), 1.0, None


def switch_stable(arc: Arclength, bp: ArcPoint, ds: float, reach: float = 0.0) -> tuple:
    """(equilibrium, τ, Switch): the stable half of the other branch through the located
    branch point ``bp`` (where the branch loses its stability), one step ``ds`` past it and
    on by arclength steps while stable to τ + ``reach`` (a solve goes on by natural steps
    from there: close to the point the two halves are too close for them to keep to one).

    The half that is stable there and goes on to larger τ (a supercritical
    bifurcation), +1 first (:meth:`Arclength.switch`).  Where neither does
    (a subcritical bifurcation, where the shell jumps; or a branch point of a
    thin shell located too roughly for the other branch's corrector), the
    shell leaves the unstable state as it would: down the branch point's
    unstable mode (its null vector, +1 first), minimised to a stable state
    just past it (:func:`_descend`, as a snap-through).

    Raises
    ------
    SolverError
        ``"Branch_Ended"``: neither way found a stable state (the branch
        point's state attached).
    """
    before = arc.equilibrium(bp)
    mode = arc.null_vector(bp)      # (one subspace iteration for both halves and the descent)
    for direction in (1.0, -1.0):
        try:
            other = arc.switch(bp, direction, mode=mode)
        except ValueError:
            break
        first = arc.first_step(other, ds)
        if first is not None and first.inertia.stable and first.t_tau > 0:
            settled = _settled(arc, _onward(arc, first, ds, bp.tau + reach))
            if settled is None:
                continue
            eq, tau = settled
            log.debug("switched branches at tau = %.6g (direction %+g)", bp.tau, direction)
            return eq, tau, Switch(float(bp.tau), tau, direction, float(before.energy),
                                   float(eq.energy))
    phi = mode.vector.copy()      # (converged or not: any part along it descends)
    phi *= arc._rising(bp, phi)
    # φ is a unit vector: its entries shrink like 1/√n, and on fine meshes a move along it
    # ends back at the branch point's saddle (the blister at 600 nodes); then one of unit
    # root mean square, the continuation's norm.  The half is named by its landing, the
    # rising one first (+1, as switch() names halves): a larger move along +φ can
    # minimise to the falling half (the 600-node blister's mirror dome)
    fallback = None
    for mode, direction in product((phi, phi / arc.norm(phi, 0.0)), (1.0, -1.0)):
        landing = _descend(arc, bp, direction * mode, BUCKLE_OVERSHOOT, before,
                           downhill=False, lower=False)
        if landing is not None and _rises(landing[0], before):
            return _buckled(bp, before, landing, 1.0)
        fallback = fallback or landing
    if fallback is not None:
        return _buckled(bp, before, fallback, -1.0)
    raise branch_ended(bp.tau, "it loses its stability at a branch point and no stable "
                               "state was found past it, along the other branch or down "
                               "its unstable mode", before)
