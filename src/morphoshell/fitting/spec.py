"""What a fit varies: the fitted parameters, their bounds and how the others follow.

The Volvox model has 13 fitting parameters (paper, Supplementary, "Fitting of
the morphoelastic theory to the average cell sheet midlines of Volvox
inversion", "Fitting parameters encode cell shape changes in intrinsic
stretches and curvatures"): stretches f₁ … f₅, curvatures κ₁ … κ₄ and the
breakpoints s₁ < s₂ < s₃ < s₄ between regions of different cell shapes; the
smoothing width σ is not fitted.  :class:`FitSpec` says which are varied, in
which order (the vector θ), within which bounds, and which follow from others;
:func:`volvox_spec` builds it for each of the paper's hypotheses on the
posterior intrinsic curvature κ₁ (:data:`VARIANTS`; "Fitting details for the
different fits in the main text"):

``flat``        κ₁ = 0;
``undeformed``  κ₁ = 1 (units of 1/R);
``unstressed``  κ₁ = 1/f₁: the contracted posterior is stress-free (a relation
                between parameters, not a value);
``free``        κ₁ fitted.

σ, h and P are never fitted; any other parameter can be held (``hold``).
Least-squares methods take bounds, not constraints: the breakpoints are kept
ordered and σ apart by disjoint boxes around them (:func:`breakpoint_bounds`),
which :func:`morphoshell.fitting.bilevel.fit` moves when a fit ends on one of
their edges (:meth:`FitSpec.on_box_edges`, :meth:`FitSpec.recentred`).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Callable, Mapping, Sequence

import numpy as np

from .._runtime.validate import instance
from ..model.problem import Problem

__all__ = ["FitSpec", "SpecError", "volvox_spec", "check_spec", "breakpoint_bounds", "VARIANTS",
           "LABELS", "BOUNDS", "EDGE_RTOL", "PUSH_SHARE", "VOLVOX_BREAKPOINTS", "BOUND_SLACK",
           "ROOM_RTOL"]

#: Hypotheses on the posterior intrinsic curvature κ₁ (see the module docstring).
VARIANTS = ("flat", "undeformed", "unstressed", "free")
#: The labels of a spec (:attr:`FitSpec.variant`): a hypothesis, or "custom" for any other
#: spec (a fit's record is read back with one of them, :meth:`FitResult.from_dict`).
LABELS = (*VARIANTS, "custom")
#: Bounds of fitted Volvox parameters: stretches, curvatures (1/R).  Breakpoints
#: are bounded by the shell and kept apart by at least the smoothing width σ.
BOUNDS = {"f": (0.5, 2.0), "kappa": (-15.0, 15.0)}
#: The Volvox model's breakpoints, in order along the shell.
VOLVOX_BREAKPOINTS = ("s1", "s2", "s3", "s4")
#: A fitted breakpoint within this fraction of its box's width from an edge rests on it
#: (:meth:`FitSpec.on_box_edges`).
EDGE_RTOL = 1e-4
#: A start this close to a bound (relative to max(1, |bound|)) but outside it lies on it: an
#: earlier fit's result, outside by Ipopt's bound relaxation (its ``bound_relax_factor``,
#: 1e-8, and the constraint tolerances), is projected onto the bound, not refused.
BOUND_SLACK = 1e-6
#: The share of the room between two breakpoints that a moved box gives the one that pushed
#: against its edge, when the other did not (:meth:`FitSpec.recentred`; tuned by the moves
#: the synthetic campaign's fits needed: halves crept, all of it made neighbours take turns).
PUSH_SHARE = 0.75
#: A fitted breakpoint whose box (:func:`breakpoint_bounds`) is narrower than this fraction of
#: the shell's length has none: round-off of s_{i+1} − s_i − σ (4e-17 for the defaults' gaps
#: of 0.3 and σ = 0.3) left boxes that SciPy accepted but no fit could move in.
ROOM_RTOL = 1e-9


class SpecError(ValueError):
    """A start, held value or σ that the fit cannot take (raised before any work).

    Attributes
    ----------
    names : tuple of str
        The parameters the message is about, so that a caller can name where
        their values came from (the command line: ``--set NAME=VALUE`` or
        ``--start FILE``).
    """

    def __init__(self, message: str, names=()):
        super().__init__(message)
        self.names = tuple(names)


@dataclass(frozen=True)
class FitSpec:
    """The fitted parameters of a problem and how the others follow.

    θ is the vector of the fitted parameters, in the order of ``fitted``; every
    other family parameter is held at ``base``'s value or tied to others.  For
    the Volvox model :func:`volvox_spec` builds it (paper, Supplementary,
    "Fitting of the morphoelastic theory to the average cell sheet midlines of
    Volvox inversion").

    Attributes
    ----------
    base : Problem
        Everything not fitted (h, Σ, P, theory, held parameters) and the start
        values of the fitted ones.
    fitted : tuple of str
        Family parameters varied by the fit, in the order of θ.
    tied : mapping
        Parameters given by a function of the others,
        ``{name: (function, derivative)}`` with ``function(params) -> value`` and
        ``derivative(params) -> {other: d value/d other}`` (the ``unstressed``
        variant: κ₁ = 1/f₁).
    bounds : mapping
        (low, high) for every fitted parameter.
    variant : str
        A label (the Volvox hypothesis, or ``"custom"``): one of :data:`LABELS`.
    ordered : tuple of str
        Breakpoints, in order along the shell, that the bounds keep ordered
        and at least σ apart (:func:`breakpoint_bounds`): boxes around their
        start values, which :func:`morphoshell.fitting.bilevel.fit` moves when
        a fit ends on one of their edges.

    Raises
    ------
    ValueError
        A fitted name that is not a parameter of the family, a start value
        outside its bounds by more than :data:`BOUND_SLACK` (closer ones are
        moved onto the bound), or a variant that is not one of :data:`LABELS`.
    """

    base: Problem
    fitted: tuple[str, ...]
    tied: Mapping[str, tuple[Callable, Callable]] = field(default_factory=dict)
    bounds: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    variant: str = "custom"
    ordered: tuple[str, ...] = ()

    def __post_init__(self):
        if self.variant not in LABELS:
            raise ValueError(f"variant = {self.variant!r} must be one of {list(LABELS)}")
        unknown = [n for n in self.fitted if n not in self.base.params]
        if unknown:
            raise ValueError(f"cannot fit {unknown}: not parameters of family "
                             f"{self.base.family!r} ({list(self.base.params)})")
        projected = {n: _projected(n, self.base.params[n], self.bounds.get(n))
                     for n in self.fitted}
        moved = {n: v for n, v in projected.items() if v != self.base.params[n]}
        if moved:
            object.__setattr__(self, "base", self.base.with_updates(**moved))

    @property
    def theta0(self) -> np.ndarray:
        """Starting values of the fitted parameters (from the base problem).

        Returns
        -------
        theta0 : ndarray, shape (k,)
            In ``fitted`` order.
        """
        return np.array([self.base.params[n] for n in self.fitted])

    def params(self, theta) -> dict:
        """All family parameters at θ, the tied ones from the others.

        Parameters
        ----------
        theta : array_like, shape (k,), or casadi.MX
            The fitted parameters, in ``fitted`` order (numbers or CasADi
            expressions).

        Returns
        -------
        dict
            Every family parameter by name (numbers or CasADi expressions).
        """
        out = dict(self.base.params)
        out.update(zip(self.fitted, [theta[i] for i in range(len(self.fitted))]))
        for name, (function, _) in self.tied.items():
            out[name] = function(out)
        return out

    def problem(self, theta) -> Problem:
        """The problem at θ (validated: a ValueError names an infeasible value)."""
        return self.base.with_updates(**{k: float(v) for k, v in self.params(theta).items()})

    def chain(self, theta, names: Sequence[str]) -> np.ndarray:
        """The derivatives of the parameters ``names`` in θ, tied ones through their ties.

        Parameters
        ----------
        theta : array_like, shape (k,)
            The fitted parameters.
        names : sequence of str
            Family parameters (fitted, tied or held: a held one's row is 0).

        Returns
        -------
        ndarray, shape (len(names), k)
            d params[names[i]] / dθ[j].
        """
        values = self.params(theta)
        out = np.zeros((len(names), len(self.fitted)))
        for i, n in enumerate(names):
            if n in self.fitted:
                out[i, self.fitted.index(n)] = 1.0
            elif n in self.tied:
                for other, d in self.tied[n][1](values).items():
                    if other in self.fitted:
                        out[i, self.fitted.index(other)] += d
        return out

    def box(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds of the fitted parameters.

        Returns
        -------
        lo, hi : ndarray, shape (k,)
            In ``fitted`` order, ±inf where unbounded.
        """
        lo = np.array([self.bounds.get(n, (-np.inf, np.inf))[0] for n in self.fitted])
        hi = np.array([self.bounds.get(n, (-np.inf, np.inf))[1] for n in self.fitted])
        return lo, hi

    def _pushing(self, theta) -> tuple[list, list, list, float]:
        """Which ordered breakpoints push against the lower (upper) edge of their box at θ.

        A fitted breakpoint pushes when it rests on an edge (within
        :data:`EDGE_RTOL` of the box's width) where the fit has no constraint: its neighbour
        (or the pole, or the shell's end) lies more than σ beyond it.
        Returns (values, down, up, σ).
        """
        values = self.params(theta)
        s, sigma = [float(values[n]) for n in self.ordered], float(values["sigma"])
        near, far = [0.0, *s], [*s[1:], self.base.end]      # each one's neighbours
        down, up = [False] * len(s), [False] * len(s)
        for i, n in enumerate(self.ordered):
            if n in self.fitted:
                lo, hi = self.bounds[n]
                tol = EDGE_RTOL * (hi - lo)
                down[i] = s[i] - lo <= tol and lo > near[i] + sigma + tol
                up[i] = hi - s[i] <= tol and hi < far[i] - sigma - tol
        return s, down, up, sigma

    def on_box_edges(self, theta) -> list[str]:
        """The fitted breakpoints that rest on an edge of their box at θ where the fit has no
        constraint (another breakpoint more than σ away, the pole or the shell's end farther
        than σ): their optimum may lie beyond it (:data:`EDGE_RTOL`)."""
        if not self.ordered:
            return []
        _, down, up, _ = self._pushing(theta)
        return [n for n, d, u in zip(self.ordered, down, up) if d or u]

    def on_constraints(self, theta) -> list[tuple[str, tuple[str, ...]]]:
        """The hard constraints that hold at θ: (description, the fitted parameters in it).

        Ordered breakpoints σ apart, the first σ from the pole, the last σ
        from the shell's end (the ordering that :func:`breakpoint_bounds`
        keeps, within :data:`EDGE_RTOL` of the shell's length), and fitted
        parameters on their bounds (:data:`BOUNDS`, within EDGE_RTOL of their
        width; not the breakpoints' movable boxes).  An optimum there is a
        constrained one: the Gauss–Newton errors of a free optimum do not
        describe it, and refits of resampled data pin to the same constraint,
        so that their scatter (a jackknife) understates the error too.
        """
        values = self.params(theta)
        return self._on_ordering(values) + self._on_bounds(values)

    def _on_ordering(self, values: Mapping) -> list[tuple[str, tuple[str, ...]]]:
        """The ordering constraints of :meth:`on_constraints` that hold at ``values``."""
        out = []
        if self.ordered:
            s, sigma = [float(values[n]) for n in self.ordered], float(values["sigma"])
            tol = EDGE_RTOL * self.base.end
            names = list(self.ordered)
            if s[0] - sigma <= tol and names[0] in self.fitted:
                out.append((f"{names[0]} = sigma (from the pole)", (names[0],)))
            for a, b, sa, sb in zip(names, names[1:], s, s[1:]):
                both = tuple(n for n in (a, b) if n in self.fitted)
                if sb - sa - sigma <= tol and both:
                    out.append((f"{b} - {a} = sigma", both))
            if self.base.end - sigma - s[-1] <= tol and names[-1] in self.fitted:
                out.append((f"{names[-1]} = L - P - sigma (the shell's end)", (names[-1],)))
        return out

    def _on_bounds(self, values: Mapping) -> list[tuple[str, tuple[str, ...]]]:
        """The bounds of :meth:`on_constraints` that hold at ``values`` (not the boxes)."""
        out = []
        for n in self.fitted:
            if n in self.ordered or n not in self.bounds:
                continue
            lo, hi = self.bounds[n]
            tol = EDGE_RTOL * (hi - lo)
            v = float(values[n])
            if v - lo <= tol or hi - v <= tol:
                out.append((f"{n} = {lo if v - lo <= tol else hi:g} (its bound)", (n,)))
        return out

    def recentred(self, theta) -> "FitSpec":
        """This spec started at θ, with the ordered breakpoints' boxes around their values there.

        The boxes of :func:`breakpoint_bounds`; between a breakpoint that
        pushes against its box's edge and a neighbour that does not, the
        pusher gets :data:`PUSH_SHARE` of the room between them: more than
        half, so that a breakpoint with far to go gets there in few moves, and
        less than all, so that neighbours that both have to move do not take
        turns.
        """
        s, down, up, sigma = self._pushing(theta)
        share = [PUSH_SHARE if up[i] and not down[i + 1] else
                 1 - PUSH_SHARE if down[i + 1] and not up[i] else 0.5 for i in range(len(s) - 1)]
        boxes = breakpoint_bounds(s, sigma, self.base.end, share)
        return replace(self, base=self.problem(theta),
                       bounds={**self.bounds, **{n: b for n, b in zip(self.ordered, boxes)
                                                 if n in self.fitted}})


def check_spec(spec) -> FitSpec:
    """``spec``, or TypeError unless it is a :class:`FitSpec` (a Problem is what one is made
    from, not one: ``fit(Problem(...), data)`` raised "'Problem' object has no attribute
    'base'")."""
    return instance("spec", spec, FitSpec, "a FitSpec, e.g. volvox_spec('free', problem)")


def breakpoint_bounds(s: Sequence[float], sigma: float, end: float,
                      share: Sequence[float] | None = None) -> list[tuple[float, float]]:
    """Disjoint boxes around ordered breakpoints 0 < s₁ < … < s_m < ``end`` that keep them σ apart.

    The paper's breakpoints s₁ < s₂ < s₃ < s₄ bound the regions of different
    cell shapes (Supplementary, "Fitting parameters encode cell shape changes
    in intrinsic stretches and curvatures"), which the smoothing width σ
    blends: they stay at least σ apart, and σ from the pole and the end.

    Of the room between neighbours s_i and s_{i+1} (their gap less σ), s_i's
    box takes the fraction ``share[i]`` (default ½: each box stops σ/2 short
    of the midpoint) and s_{i+1}'s the rest; the first and last boxes reach
    to σ from the pole and the shell's end.  So any point of the boxes keeps
    the breakpoints at least σ apart (the fit's constraint; the ``kkt``
    method's ordering constraints say the same).  A pair already closer than
    σ is pinned at its gap (it can only widen).  Least-squares methods take
    bounds, not the ordering itself: these boxes order the breakpoints for
    them, and :func:`morphoshell.fitting.bilevel.fit` moves them when a fit
    ends on an edge (:meth:`FitSpec.on_box_edges`).

    Parameters
    ----------
    s : sequence of float, length m
        The breakpoints, in order.
    sigma : float
        The least distance between them (the smoothing width σ).
    end : float
        The shell's intrinsic length L − P.
    share : sequence of float, length m − 1, optional
        Of the room between s_i and s_{i+1}, the fraction s_i's box takes.

    Returns
    -------
    list of (float, float), length m
        (low, high) of each breakpoint's box.
    """
    s = list(s)
    share = [0.5] * (len(s) - 1) if share is None else list(share)
    # the boundaries of the room between neighbours: s_i's box ends at a, s_{i+1}'s begins at b
    room = [max(b - a - sigma, 0.0) for a, b in zip(s, s[1:])]
    below = [sigma] + [a + w * r + sigma for a, w, r in zip(s, share, room)]
    above = [a + w * r for a, w, r in zip(s, share, room)] + [end - sigma]
    return [(min(lo, b), max(hi, b)) for lo, b, hi in zip(below, s, above)]   # (b when pinned)


def _projected(name: str, value: float, bounds) -> float:
    """``value`` onto ``bounds`` if it is outside by no more than :data:`BOUND_SLACK`.

    On an edge is inside: a fit that ended there starts the next one.

    Raises
    ------
    ValueError
        Outside by more, with today's message naming the start and its bounds.
    """
    lo, hi = bounds if bounds is not None else (-np.inf, np.inf)
    if lo <= value <= hi:
        return value
    edge = lo if value < lo else hi
    if abs(value - edge) <= BOUND_SLACK * max(1.0, abs(edge)):
        return float(edge)
    raise SpecError(f"the start {name} = {value!r} lies outside its bounds ({lo:g}, {hi:g})",
                    (name,))


def volvox_spec(variant: str, start: Problem | None = None, hold: Mapping[str, float] = (),
                breakpoint_boxes: bool = True) -> FitSpec:
    """The fit of the Volvox model for one of :data:`VARIANTS`.

    The paper's fits (Supplementary, "Fitting of the morphoelastic theory to
    the average cell sheet midlines of Volvox inversion", "Fitting details for
    the different fits in the main text") hold the posterior intrinsic
    curvature κ₁ = κ_post⁰ at 0 (``flat``) or 1/R (``undeformed``), tie it to
    1/r_post = 1/f₁ (``unstressed``), or fit it (``free``).  Every other
    parameter but σ is fitted unless held; stretches and curvatures within
    :data:`BOUNDS`.

    Parameters
    ----------
    variant : {"flat", "undeformed", "unstressed", "free"}
    start : Problem, optional
        A ``volvox`` problem with the start values (default: the family's
        illustrative defaults, h = 0.15, P = 0.3: "Problems and families").
    hold : mapping
        Parameters held at the given values (not fitted).
    breakpoint_boxes : bool
        Bound each breakpoint to a disjoint interval around its start
        (:func:`breakpoint_bounds`), so that methods without constraints keep
        them ordered; :func:`morphoshell.fitting.bilevel.fit` moves the
        intervals when a fit ends on one of their edges.  Without them each breakpoint lies within σ
        of the shell only: the ``kkt`` method imposes the ordering as constraints
        and does not need them.

    Returns
    -------
    FitSpec

    Raises
    ------
    ValueError
        An unknown variant, a start of another family.
    TypeError
        A start that is not a :class:`Problem` (a mapping of parameters, say).
    SpecError
        κ₁ held by the ``unstressed`` variant or held at another value than
        the ``flat`` or ``undeformed`` one's; a held stretch or curvature
        outside :data:`BOUNDS`; a σ that leaves a fitted breakpoint no box or
        two held ones closer than σ (:func:`_check_room`).
    """
    if variant not in VARIANTS:
        raise ValueError(f"variant = {variant!r} must be one of {list(VARIANTS)}")
    start = Problem("volvox", h=0.15, opening=0.3) if start is None else start
    if not isinstance(start, Problem):
        raise TypeError(f"start = {start!r} must be a Problem (Problem('volvox', params, h=..., "
                        f"opening=...)); parameters to hold go in hold=")
    if start.family != "volvox":
        raise ValueError(f"the Volvox fit needs a 'volvox' problem, got {start.family!r}")
    hold, tied = _variant_holds_and_ties(variant, hold)
    _check_held(hold)
    params = {**start.params, **hold}
    if variant == "unstressed":
        params["kappa1"] = 1 / params["f1"]
    base = start.with_updates(**params)
    fitted = tuple(n for n in base.family_obj.parameters
                   if n not in hold and n not in tied and n != "sigma")
    _check_room(base, fitted if breakpoint_boxes else ())
    bounds = _volvox_bounds(base, fitted, breakpoint_boxes)
    return FitSpec(base, fitted, tied, bounds, variant,
                   VOLVOX_BREAKPOINTS if breakpoint_boxes else ())


def _variant_holds_and_ties(variant: str, hold: Mapping[str, float]) -> tuple[dict, dict]:
    """The held parameters and the tied ones (:attr:`FitSpec.tied`) of a Volvox variant.

    ``flat`` and ``undeformed`` hold κ₁ at 0 and 1 (holding it at another
    value is refused: a fit labelled flat with κ₁ = 0.5 would silently be
    another hypothesis); ``unstressed`` ties κ₁ = 1/f₁ (holding it is
    refused); ``free`` adds nothing to ``hold``.
    """
    hold = dict(hold)
    tied: dict = {}
    fixed = {"flat": 0.0, "undeformed": 1.0}.get(variant)
    if fixed is not None:
        if hold.setdefault("kappa1", fixed) != fixed:
            raise SpecError(f"the {variant} variant holds kappa1 = {fixed:g}, not "
                            f"{hold['kappa1']:g}: hold kappa1 in the free variant instead",
                            ("kappa1",))
    elif variant == "unstressed":
        if "kappa1" in hold:
            raise SpecError("the unstressed variant ties kappa1 = 1/f1: it cannot be held",
                            ("kappa1",))
        tied["kappa1"] = (lambda p: 1 / p["f1"], lambda p: {"f1": -1 / p["f1"] ** 2})
    return hold, tied


def _check_held(hold: Mapping[str, float]) -> None:
    """SpecError for a held stretch or curvature outside :data:`BOUNDS` (by more than
    :data:`BOUND_SLACK`, which a value from an earlier fit on its bound may be).

    The bounds are the range of cell shapes the fit considers; a value held outside is none
    of them: ``f1 = 5`` (a posterior cell five times its length) ran to E_fit 16.5 R.
    """
    for name, value in hold.items():
        kind = "f" if name.startswith("f") else "kappa" if name.startswith("kappa") else None
        if kind is None:
            continue
        lo, hi = BOUNDS[kind]
        slack = BOUND_SLACK * max(1.0, abs(lo), abs(hi))
        if not lo - slack <= value <= hi + slack:
            what = "stretches f1..f5" if kind == "f" else "curvatures kappa1..kappa4 (1/R)"
            raise SpecError(f"{name} = {value:g} lies outside the fit's bounds [{lo:g}, {hi:g}] "
                            f"of the {what}: a held value must be one the fit could reach",
                            (name,))


def _check_room(base: Problem, fitted: Sequence[str]) -> None:
    """SpecError unless σ leaves every breakpoint of ``fitted`` a box and keeps held ones apart.

    The fit keeps the breakpoints σ apart and σ from the pole and the shell's
    end (:func:`breakpoint_bounds`; the KKT fit's constraints).  A fitted
    breakpoint whose neighbours on both sides lie σ or less away has a box of
    no width (SciPy: "Each lower bound must be strictly less than each upper
    bound", after the whole set-up); two held neighbours closer than σ break
    the constraint whatever the fit does.  The message gives the largest σ
    that these breakpoints allow.
    """
    sigma, end = float(base.params["sigma"]), base.end
    points = ([("the pole", 0.0, False)]
              + [(n, float(base.params[n]), n in fitted) for n in VOLVOX_BREAKPOINTS]
              + [("the shell's end", end, False)])
    tol = ROOM_RTOL * end
    limits, cramped, names = [], [], set()
    for (a, sa, fa), (b, sb, fb), (c, sc, fc) in zip(points, points[1:], points[2:]):
        if fb:          # (a box needs room on one side at least)
            limits.append(max(sb - sa, sc - sb))
            if sigma >= limits[-1] - tol:
                cramped.append(f"{b} ({sb - sa:.4g} from {a}, {sc - sb:.4g} from {c})")
                names.update({b, a, c})
    for (a, sa, fa), (b, sb, fb) in zip(points, points[1:]):
        if not (fa or fb) and {a, b} & set(VOLVOX_BREAKPOINTS):
            limits.append(sb - sa)
            if sb - sa < sigma - tol:
                cramped.append(f"{a} and {b}, held, {sb - sa:.4g} apart")
                names.update({a, b})
    if cramped:
        values = ", ".join(f"{base.params[n]:.4g}" for n in VOLVOX_BREAKPOINTS)
        raise SpecError(f"sigma = {sigma:g} leaves no room for {'; '.join(cramped)}: the fit "
                        f"keeps the breakpoints sigma apart, and sigma from the pole and the "
                        f"shell's end (L - P = {end:.4g}); with s1..s4 = {values} sigma must be "
                        f"below {min(limits):.4g}, or the breakpoints further apart",
                        ("sigma", *(n for n in VOLVOX_BREAKPOINTS if n in names)))


def _volvox_bounds(base: Problem, fitted: tuple[str, ...],
                   breakpoint_boxes: bool) -> dict[str, tuple[float, float]]:
    """Bounds of the fitted Volvox parameters: :data:`BOUNDS` for stretches and
    curvatures, for breakpoints their boxes (:func:`breakpoint_bounds`) or, without
    them, the shell less σ at either end."""
    bounds = {}
    for n in fitted:
        if n.startswith("f"):
            bounds[n] = BOUNDS["f"]
        elif n.startswith("kappa"):
            bounds[n] = BOUNDS["kappa"]
    names = VOLVOX_BREAKPOINTS
    sigma = base.params["sigma"]
    boxes = breakpoint_bounds([base.params[n] for n in names], sigma, base.end)
    for name, box in zip(names, boxes):
        if name in fitted:
            bounds[name] = box if breakpoint_boxes else (sigma, base.end - sigma)
    return bounds
