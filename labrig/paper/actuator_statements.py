"""The paper's statements about its combined actuators: Movies S3-S6 (with Fig. 2C),
Fig. 3's pattern and Fig. 4 (n = 2), with transitions counted as the paper counts them
(``labrig.model.actuator.paper_counting``): the events at one supplied volume are one,
unstable if a snap is part of it; its volume is the supplied volume before it, the
fluid it moves dv * v."""

from __future__ import annotations

from collections import Counter

import numpy as np

from labrig.model.actuator.paper_counting import PaperTransition as Transition
from labrig.paper.pair_scan import PairScan, actuator_transitions, scan_pairs
from labrig.paper.statements import (
    MIN_RELEASE,
    MOVIE_S3,
    MOVIE_S4,
    MOVIE_S5,
    MOVIE_S6,
    PAPER_TYPES,
    PREDICTION,
    VOLUME_TOLERANCE_ML,
    Library,
    Outcome,
    Snap,
    library_names,
    nearest,
    snaps_of,
    snaps_text,
    within,
)

PAIRS = 630
# "some internal flow": more than the solver's noise by far
MIN_FLOW_ML = 0.1
# Fig. 4's "approximately zero" changes of a (0, 1) transition
SMALL_CHANGE = 0.01
# Fig. 4's stable energy increase, 4e-5 at the paper's increment (it calls the value
# increment-dependent): at most twice that, the tolerance of an "up to" value
MAX_STABLE_DE = 8e-5
# Fig. 4's (1, 1) flow "up to 80 %": a flow cannot pass 100 % of the supplied volume, so
# twice 80 % cannot fail; the upper bound halves the 20 % left unmoved instead
MAX_11_FLOW = 0.90
# Fig. 3: "at v = 6 mL a second local minimum for E emerges"; the energy landscape is
# read on this grid of supplied volume and of the first segment's volume
LANDSCAPE_DV_ML = 0.05
SECOND_MINIMUM_ML = 6.0


def releases(t: Transition) -> bool:
    """Whether ``t`` is unstable in the statements' sense: a snap that releases at
    least ``MIN_RELEASE`` of the stored energy."""
    return not t.stable and -t.dE >= MIN_RELEASE


def evidence(transitions: list[Transition], typed: bool = True) -> list[Transition]:
    """The unstable transitions a statement may rest on: those that release, and for a
    pair (``typed``) only of the types the paper reports."""
    return [
        t for t in transitions if releases(t) and (not typed or (t.alpha, t.beta) in PAPER_TYPES)
    ]


def _near(snaps: list[Snap], v_ml: float) -> Snap | None:
    snap = nearest(snaps, v_ml)
    return snap if snap is not None and abs(snap.v_ml - v_ml) <= VOLUME_TOLERANCE_ML else None


def _outcome(key, statement, paper, labrig, holds, why, tolerance) -> Outcome:
    return Outcome(key, statement, paper, labrig, bool(holds), PREDICTION, why, tolerance)


def _movie_s3(transitions: list[Transition]) -> list[Outcome]:
    snaps = snaps_of(evidence(transitions))
    snap = _near(snaps, 23.0)
    every = snaps_text(snaps_of(transitions))
    why = "" if snap else every
    text = "none" if snap is None else f"{snap.v_ml:.1f} mL"
    out = [
        _outcome(
            "S3-volume",
            "Movie S3, (46,20)+(46,22): a snap at 23 mL",
            "23 mL",
            text,
            snap is not None,
            why,
            "20-26 mL",
        )
    ]
    dl_ok = snap is not None and snap.dl > 0
    out.append(
        _outcome(
            "S3-elongation",
            "Movie S3 / Fig. 2C: the snap lengthens the actuator",
            "dl > 0",
            "none" if snap is None else f"{snap.dl:+.1%}",
            dl_ok,
            "" if dl_ok else every,
            "dl > 0",
        )
    )
    t = None if snap is None else next(x for x in transitions if x.v_ml == snap.v_ml)
    drop = t is not None and t.dp < 0 and snap.moved_ml >= MIN_FLOW_ML
    out.append(
        _outcome(
            "S3-pressure-flow",
            "Movie S3: the snap drops the pressure and moves fluid between the segments",
            "dp < 0, internal flow",
            "none" if t is None else f"dp {t.dp:+.1%}, {snap.moved_ml:.2f} mL moved",
            drop,
            "" if drop else every,
            f"dp < 0 and >= {MIN_FLOW_ML:g} mL moved",
        )
    )
    return out


def _movie_s4(transitions: list[Transition]) -> list[Outcome]:
    snaps = snaps_of(evidence(transitions))
    why = snaps_text(snaps_of(transitions))
    snap = _near(snaps, 26.0)
    dl_ok = snap is not None and within(snap.dl, 0.055, 0.22)
    return [
        _outcome(
            "S4-volume",
            "Movie S4, (48,30)+(50,20): a snap at 26 mL",
            "26 mL",
            "none" if snap is None else f"{snap.v_ml:.1f} mL",
            snap is not None,
            "" if snap else why,
            "23-29 mL",
        ),
        _outcome(
            "S4-elongation",
            "Movie S4: the snap lengthens the actuator by 10 mm (11 %)",
            "+11 %",
            "none" if snap is None else f"{snap.dl:+.1%}",
            dl_ok,
            "" if dl_ok else why,
            "+5.5 % to +22 %",
        ),
    ]


def _flows_ml(t: Transition) -> list[float]:
    """What each segment gains in transition ``t``, from before its first event to
    after its last."""
    pre, post = t.events[0].pre, t.events[-1].post
    return [b - a for a, b in zip(pre.v_i_ml, post.v_i_ml, strict=True)]


def _movie_s5(transitions: list[Transition]) -> list[Outcome]:
    unstable = evidence(transitions)
    snaps = snaps_of(unstable)
    first, second = _near(snaps, 16.0), _near(snaps, 24.0)
    both = first is not None and second is not None and first is not second
    released = first is not None and within(-first.dE, 0.05, 0.20)
    released = released and first.moved_ml >= MIN_FLOW_ML
    back = False
    if both:
        t1 = next(t for t in unstable if t.v_ml == first.v_ml)
        t2 = next(t for t in unstable if t.v_ml == second.v_ml)
        gained = _flows_ml(t1)
        k = max(range(len(gained)), key=gained.__getitem__)
        back = _flows_ml(t2)[k] < -MIN_FLOW_ML
    why = snaps_text(snaps_of(transitions))
    return [
        _outcome(
            "S5-two-snaps",
            "Movie S5, (44,30)+(48,26): two snaps, at 16 and 24 mL",
            "16 and 24 mL",
            ", ".join(f"{s.v_ml:.1f}" for s in snaps) + " mL" if snaps else "none",
            both,
            "" if both else why,
            "13-19 and 21-27 mL",
        ),
        _outcome(
            "S5-release",
            "Movie S5: the first snap releases ~10 % of the stored energy, with internal flow",
            "~10 %",
            "none" if first is None else f"{-first.dE:.1%}, {first.moved_ml:.1f} mL moved",
            released,
            "" if released else why,
            f"5-20 % released, >= {MIN_FLOW_ML:g} mL moved",
        ),
        _outcome(
            "S5-flow-back",
            "Movie S5: the second snap makes some fluid flow back",
            "flows back",
            "yes" if back else "no",
            back,
            "" if back else why,
            f">= {MIN_FLOW_ML:g} mL back into the other segment",
        ),
    ]


def _movie_s6(transitions: list[Transition]) -> list[Outcome]:
    unstable = [t for t in evidence(transitions, typed=False) if within(t.v_ml, 28.0, 29.0)]
    best = max(unstable, key=lambda t: t.dv, default=None)
    moved = None if best is None else best.dv * best.v_ml
    holds = moved is not None and within(moved, 10.0, 40.0)
    why = snaps_text(snaps_of(transitions))
    flows = [] if best is None else _flows_ml(best)
    losing = sum(f <= -MIN_FLOW_ML for f in flows)
    gaining = sum(f >= MIN_FLOW_ML for f in flows)
    two_into_one = (losing, gaining) == (2, 1)
    return [
        _outcome(
            "S6-flow",
            "Movie S6, (40,28)+(44,30)+(50,24): at 28 mL, +1 mL moves ~20 mL",
            "~20 mL moved",
            "none" if best is None else f"{best.v_ml:.1f} mL, {moved:.1f} mL moved",
            holds,
            "" if holds else why,
            "a snap at 28-29 mL moving 10-40 mL",
        ),
        _outcome(
            "S6-two-into-one",
            "Movie S6: the flow deflates two segments into one",
            "two segments empty into the third",
            "no snap at 28-29 mL"
            if best is None
            else "flows " + ", ".join(f"{f:+.1f}" for f in flows) + " mL",
            two_into_one,
            "" if two_into_one else why,
            f"that snap: two segments lose and one gains >= {MIN_FLOW_ML:g} mL each",
        ),
    ]


def _fig3_pairs(scan: PairScan) -> list[tuple[str, str]]:
    """The pairs with Fig. 3's transitions: a stable (0,1) near 5 mL, an unstable (1,1)
    near 19 and an unstable (1,2) near 22 mL after it."""
    found = []
    for pair, ts in scan.transitions.items():
        early = any(
            t.stable and (t.alpha, t.beta) == (0, 1) and abs(t.v_ml - 5.0) <= VOLUME_TOLERANCE_ML
            for t in ts
        )
        ones = [
            t
            for t in evidence(ts)
            if (t.alpha, t.beta) == (1, 1) and abs(t.v_ml - 19.0) <= VOLUME_TOLERANCE_ML
        ]
        twos = [
            t
            for t in evidence(ts)
            if (t.alpha, t.beta) == (1, 2)
            and abs(t.v_ml - 22.0) <= VOLUME_TOLERANCE_ML
            and any(o.v_ml < t.v_ml for o in ones)
        ]
        if early and ones and twos:
            found.append(pair)
    return found


def _pair_names(pairs) -> str:
    return ", ".join("+".join(n.split(":")[-1] for n in p) for p in pairs[:3])


def _fig3(found: list[tuple[str, str]]) -> Outcome:
    names = _pair_names(found)
    return _outcome(
        "fig3-pattern",
        "Fig. 3: a pair with a stable transition near 5 mL, an unstable (1,1) near 19 "
        "and an unstable (1,2) near 22 mL",
        "some pair",
        f"{len(found)} pairs" + (f" (e.g. {names})" if found else ""),
        bool(found),
        "" if found else "no pair has the three transitions",
        "volumes within 3 mL; (0,1), (1,1), (1,2); the last two release >= 0.1 %",
    )


def second_minimum_ml(curves, v_end_ml: float) -> float | None:
    """The smallest supplied volume at which the pair's energy E(v1) at fixed v has two
    local minima (``LANDSCAPE_DV_ML`` grids of v and v1), None if it never has.

    dE/dv1 = p1(v1) - p2(v - v1), so a minimum is where that difference changes sign
    from negative to positive: read off the segments' own curves, independently of the
    path solver."""
    first, second = curves
    v1 = np.arange(0.0, v_end_ml + LANDSCAPE_DV_ML / 2, LANDSCAPE_DV_ML)
    p1 = first.pressure_kpa(v1)
    for v in np.arange(LANDSCAPE_DV_ML, v_end_ml, LANDSCAPE_DV_ML):
        inside = v1 <= v + 1e-12
        difference = p1[inside] - second.pressure_kpa(v - v1[inside])
        rises = np.count_nonzero((difference[:-1] < 0) & (difference[1:] >= 0))
        if rises >= 2:
            return float(v)
    return None


def _fig3_second_minimum(library: Library, found: list[tuple[str, str]]) -> Outcome:
    volumes = [second_minimum_ml([library(n) for n in pair], 19.0) for pair in found]
    near = [
        (pair, v)
        for pair, v in zip(found, volumes, strict=True)
        if v is not None and abs(v - SECOND_MINIMUM_ML) <= VOLUME_TOLERANCE_ML
    ]
    text = (
        "no pair with Fig. 3's transitions"
        if not found
        else ", ".join("none" if v is None else f"{v:.2f} mL" for v in volumes[:5])
    )
    return _outcome(
        "fig3-second-minimum",
        "Fig. 3C: a second local minimum of E emerges at 6 mL (two stable states to 19 mL)",
        "6 mL",
        text,
        bool(near),
        "" if near else text,
        "in a pair with Fig. 3's transitions, within 3 mL of 6 mL",
    )


def _up_to(value: float, spec: str) -> str:
    """ "up to" a largest value, or "none" where no transition had one (NaN)."""
    return "none" if np.isnan(value) else f"up to {value:{spec}}"


def _extreme(ts: list[Transition], key, default=float("nan")) -> float:
    return max((key(t) for t in ts), default=default)


def _fig4(scan: PairScan) -> list[Outcome]:
    every = [t for ts in scan.transitions.values() for t in ts]
    types = Counter((t.alpha, t.beta) for t in every)
    # the statements below rest on the paper's three types only
    typed = [t for t in every if (t.alpha, t.beta) in PAPER_TYPES]
    of = {k: [t for t in typed if (t.alpha, t.beta) == k] for k in PAPER_TYPES}
    zero_one, one_one = of[(0, 1)], of[(1, 1)]
    one_two = of[(1, 2)]
    stable = [t for t in typed if t.stable]
    built = len(scan.transitions)
    fewest = min(
        (sum((t.alpha, t.beta) in PAPER_TYPES for t in ts) for ts in scan.transitions.values()),
        default=0,
    )
    with_01 = sum(any((t.alpha, t.beta) == (0, 1) for t in ts) for ts in scan.transitions.values())
    unstable_01 = [t for t in zero_one if not t.stable]
    small_01 = all(
        max(abs(t.dE), abs(t.dl), abs(t.dp), t.dv) < SMALL_CHANGE for t in zero_one
    ) and bool(zero_one)
    releasing_11 = [t for t in one_one if releases(t)]
    release_11 = _extreme(one_one, lambda t: -t.dE)
    flow_11 = _extreme(one_one, lambda t: t.dv)
    unstable_12 = [t for t in one_two if releases(t)]
    stable_12 = [t for t in one_two if t.stable]
    release_12 = _extreme(unstable_12, lambda t: -t.dE)
    length_12 = _extreme(unstable_12, lambda t: abs(t.dl))
    lowest = min((t.dE for t in typed), default=float("nan"))
    stable_de = _extreme(stable, lambda t: t.dE)
    type_text = ", ".join(f"({a},{b}) {n}" for (a, b), n in sorted(types.items()))
    failed = f"; {len(scan.failed)} pairs failed" if scan.failed else ""
    other = len(every) - len(typed)
    other_text = f" (and {other} of other types)" if other else ""
    rows = [
        (
            "fig4-count",
            "Fig. 4: more than 630 transitions, every actuator two or more",
            "> 630, each >= 2",
            f"{len(typed)}{other_text} in {built} actuators, fewest {fewest}{failed}",
            len(typed) > PAIRS and fewest >= 2 and built == PAIRS,
            "more than 630 of the three types and at least 2 in every one of the 630",
        ),
        (
            "fig4-types",
            "Fig. 4: three types for n = 2: (0,1), (1,1), (1,2)",
            "(0,1), (1,1), (1,2)",
            type_text or "none",
            set(types) == {(0, 1), (1, 1), (1, 2)},
            "exactly these three types",
        ),
        (
            "fig4-01-stable",
            "Fig. 4: (0,1) transitions occur in every actuator and are always stable",
            "all 630, all stable",
            f"in {with_01} of {built}; {len(unstable_01)} of {len(zero_one)} unstable",
            with_01 == PAIRS and not unstable_01,
            "in all 630 and none unstable",
        ),
        (
            "fig4-01-small",
            "Fig. 4: a (0,1) transition changes energy, length, pressure and flow by ~0",
            "~0",
            "largest size of dE, dl, dp, dv: "
            + ", ".join(
                f"{_extreme(zero_one, f, 0.0):.2%}"
                for f in (
                    lambda t: abs(t.dE),
                    lambda t: abs(t.dl),
                    lambda t: abs(t.dp),
                    lambda t: t.dv,
                )
            ),
            small_01,
            "each below 1 %",
        ),
        (
            "fig4-11-unstable",
            "Fig. 4: (1,1) transitions are always unstable",
            "all unstable",
            f"{len(releasing_11)} of {len(one_one)} release >= {MIN_RELEASE:.1%}",
            bool(one_one) and len(releasing_11) == len(one_one),
            f"every one releases >= {MIN_RELEASE:.1%} of the energy (and some exist)",
        ),
        (
            "fig4-11-release",
            "Fig. 4: (1,1) releases up to 10 % of the stored energy",
            "up to 10 %",
            _up_to(release_11, ".1%"),
            within(release_11, 0.05, 0.20),
            "largest release 5-20 %",
        ),
        (
            "fig4-11-flow",
            "Fig. 4: (1,1) moves up to 80 % of the volume between the segments",
            "up to 80 %",
            _up_to(flow_11, ".0%"),
            within(flow_11, 0.40, MAX_11_FLOW),
            f"largest flow 40-{MAX_11_FLOW:.0%}",
        ),
        (
            "fig4-12-both",
            "Fig. 4: (1,2) transitions can be either stable or unstable",
            "both",
            f"{len(stable_12)} stable, {len(unstable_12)} unstable",
            bool(unstable_12) and bool(stable_12),
            f"some stable and some releasing >= {MIN_RELEASE:.1%}",
        ),
        (
            "fig4-12-release",
            "Fig. 4: an unstable (1,2) releases up to 2.5 % of the stored energy",
            "up to 2.5 %",
            _up_to(release_12, ".1%"),
            within(release_12, 0.0125, 0.05),
            "largest release 1.25-5 %",
        ),
        (
            "fig4-12-length",
            "Fig. 4: an unstable (1,2) changes the length by up to 14 %",
            "up to 14 %",
            _up_to(length_12, ".1%"),
            within(length_12, 0.07, 0.28),
            "largest length change 7-28 % (either sign)",
        ),
        (
            "fig4-energy-range",
            "Fig. 4: -0.1 <= dE <= 4e-5 over all transitions",
            "-0.1 to 4e-5",
            f"{lowest:.3g} to {stable_de:.2g}",
            within(-lowest, 0.05, 0.20) and stable_de <= MAX_STABLE_DE,
            f"over the three types: lowest -0.05 to -0.2; highest <= {MAX_STABLE_DE:g}",
        ),
    ]
    return [
        _outcome(key, statement, paper, labrig, holds, "" if holds else labrig, tolerance)
        for key, statement, paper, labrig, holds, tolerance in rows
    ]


def evaluate(library: Library, prefix: str) -> list[Outcome]:
    """Movies S3-S6, Fig. 3 and Fig. 4 from the library's names (``prefix`` +
    ``B46-T20``); the two-segment movies are pairs of the scan."""
    pairs = scan_pairs(library, library_names(prefix))

    def pair(names):
        return pairs.transitions.get(tuple(prefix + n for n in names), [])

    out = _movie_s3(pair(MOVIE_S3)) + _movie_s4(pair(MOVIE_S4)) + _movie_s5(pair(MOVIE_S5))
    out += _movie_s6(actuator_transitions(library, [prefix + n for n in MOVIE_S6]))
    found = _fig3_pairs(pairs)
    out += [_fig3(found), _fig3_second_minimum(library, found)]
    return out + _fig4(pairs)
