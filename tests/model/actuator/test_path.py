"""The quasi-static path: its invariants, exact folds, hysteresis, coincident peaks, and
where snaps land (checked against independent computations of the flow)."""

import math

import numpy as np
import pytest
from support.actuator_curves import cubic_segment, kinked_segment, random_cubic

from labrig.model.actuator.equilibria import Actuator, hessian, is_stable
from labrig.model.actuator.path import (
    DEFLATE,
    INFLATE,
    default_end_volume_ml,
    quasi_static_path,
    sample_path,
)
from labrig.model.actuator.transitions import transitions
from labrig.model.segments.catalog import analytical_segment

PAIR = ("A", 4.0, 10.0, 30.0), ("B", 5.0, 13.0, 33.0)
TRIPLE = (*PAIR, ("C", 3.5, 9.0, 28.0))


def cubic_actuator(spec):
    return Actuator([cubic_segment(*s) for s in spec])


def random_actuator(seed, n):
    rng = np.random.default_rng(seed)
    return Actuator([random_cubic(rng, f"S{i}") for i in range(n)])


def library_actuator(*names):
    return Actuator([analytical_segment(n) for n in names])


ACTUATORS = {
    "cubic pair": lambda: cubic_actuator(PAIR),
    "cubic triple": lambda: cubic_actuator(TRIPLE),
    "random quadruple": lambda: random_actuator(7, 4),
    "SI-B48-T30 + SI-B50-T20": lambda: library_actuator("SI-B48-T30", "SI-B50-T20"),
    "SI-B40-T28 + SI-B44-T30 + SI-B50-T24": lambda: library_actuator(
        "SI-B40-T28", "SI-B44-T30", "SI-B50-T24"
    ),
}


@pytest.mark.parametrize("name", ACTUATORS)
def test_path_invariants(name):
    actuator = ACTUATORS[name]()
    path = quasi_static_path(actuator, deflate=True)
    sampled = sample_path(path, dv_ml=0.1)
    segments = actuator.segments
    # every state on the path shares one pressure and holds the supplied volume
    for seg, v in zip(segments, sampled.v_i_ml, strict=True):
        np.testing.assert_allclose(seg.pressure_kpa(v), sampled.p_kpa, atol=1e-8)
    np.testing.assert_allclose(sampled.v_i_ml.sum(axis=0), sampled.v_ml, atol=1e-12)
    # and is stable
    # and is stable: the Hessian's smallest eigenvalue is positive, or zero to rounding
    # at the marginal states where a piece ends (a fold, a segment at its extremum)
    k = np.array(
        [seg.slope_kpa_per_ml(v) for seg, v in zip(segments, sampled.v_i_ml, strict=True)]
    ).T
    stable = is_stable(k)
    scale = np.median(np.abs(k))
    smallest = np.array([np.linalg.eigvalsh(hessian(row)).min() for row in k[~stable]])
    assert len(smallest) < 0.01 * len(k) and np.all(smallest > -1e-6 * scale)
    # inflation to the end, then back to zero
    assert sampled.v_ml[0] == 0 and sampled.v_ml[-1] == pytest.approx(0.0, abs=1e-9)
    assert np.max(sampled.v_ml) == pytest.approx(default_end_volume_ml(actuator))
    # energy: dE = p dv along the path (trapezoid within 1e-3 relative of the step), and
    # a drop at constant volume at each snap, nothing else
    energy = np.array([actuator.energy_mj(v) for v in sampled.v_i_ml.T])
    dv = np.diff(sampled.v_ml)
    de = np.diff(energy)
    # a snap: the volumes jump at one total volume (near a fold v is stationary, so
    # neighbouring points there can also have equal totals, but barely moved volumes)
    jump = (np.abs(dv) < 1e-9) & (np.max(np.abs(np.diff(sampled.v_i_ml, axis=1)), axis=0) > 1e-6)
    trapezoid = 0.5 * (sampled.p_kpa[1:] + sampled.p_kpa[:-1]) * dv
    np.testing.assert_allclose(de[~jump], trapezoid[~jump], atol=2e-3 * np.max(np.abs(trapezoid)))
    snaps = [t for t in transitions(path) if not t.stable]
    assert np.count_nonzero(jump) == len(snaps) > 0
    assert np.all(de[jump] < 0)


def test_the_path_is_deterministic():
    first = quasi_static_path(cubic_actuator(TRIPLE), deflate=True)
    second = quasi_static_path(cubic_actuator(TRIPLE), deflate=True)
    assert first.timeline == second.timeline


def test_deflation_snaps_back_at_other_volumes_than_inflation():
    path = quasi_static_path(cubic_actuator(PAIR), deflate=True)
    snaps = [t for t in transitions(path) if not t.stable]
    up = [t.v_ml for t in snaps if t.direction == INFLATE]
    down = [t.v_ml for t in snaps if t.direction == DEFLATE]
    assert len(up) == len(down) == 1
    # hysteresis: the state inflation snapped away from is reached again only well
    # below the volume of the snap
    assert down[0] < up[0] - 5.0
    assert snaps[0].alpha == 2 and snaps[0].beta == 2
    assert snaps[1].alpha == 1 and snaps[1].beta == 1


def test_folds_are_the_turning_points_of_the_volume():
    """Independent of the sum-1/k root: maximise v(p) on the fold's branch combination."""
    from scipy.optimize import minimize_scalar

    actuator = cubic_actuator(TRIPLE)
    path = quasi_static_path(actuator, deflate=True)
    folds = [e for e in path.events if e.cause == "fold"]
    assert len(folds) >= 4

    def volume(branches, p):
        return sum(
            float(s.volume_on_branch(b, p)[0])
            for s, b in zip(actuator.segments, branches, strict=True)
        )

    for event in folds:
        pre = event.pre
        sign = 1 if event.direction == INFLATE else -1  # inflation: a maximum of v
        lo, hi = pre.p_kpa - 0.5, pre.p_kpa + 0.5
        best = minimize_scalar(
            lambda p, b=pre.branches, s=sign: -s * volume(b, p),
            bounds=(lo, hi),
            method="bounded",
            options={"xatol": 1e-10},
        )
        assert pre.v_ml == pytest.approx(volume(pre.branches, best.x), abs=1e-9)
        assert pre.p_kpa == pytest.approx(best.x, abs=1e-3)


def test_a_pair_snaps_to_the_first_balance_the_flow_meets():
    """For two segments the flow moves w1 monotonically until p1(w1) = p2(v - w1): find
    it on a dense grid, independently of the solver's scan."""
    actuator = cubic_actuator(PAIR)
    a, b = actuator.segments
    for event in quasi_static_path(actuator, deflate=True).events:
        if event.kind != "snap":
            continue
        v = event.pre.v_ml
        w1 = event.pre.v_i_ml[0]
        post = event.post.v_i_ml[0]
        grid = np.linspace(w1, post + 2 * (post - w1), 200_001)
        imbalance = a.pressure_kpa(grid) - b.pressure_kpa(v - grid)
        direction = np.sign(post - w1)
        moving = -np.sign(imbalance) == direction
        first_stop = grid[np.argmin(moving[20:]) + 20]  # skip the start at the fold
        assert post == pytest.approx(first_stop, abs=3 * abs(grid[1] - grid[0]))


def flow_destination(actuator, start):
    """The overdamped flow dw/dt = -(p_i - mean p) by scipy's Radau, tight tolerances,
    run until it rests on a stable equilibrium (leaving a fold's ghost takes long)."""
    from scipy.integrate import solve_ivp

    segments = actuator.segments

    def rate(_, w):
        p = np.array([s.pressure_kpa(x) for s, x in zip(segments, w, strict=True)], dtype=float)
        return p.mean() - p

    w = np.array(start)
    for _ in range(12):
        w = solve_ivp(rate, (0, 1e3), w, method="Radau", rtol=1e-8, atol=1e-10).y[:, -1]
        k = np.array([s.slope_kpa_per_ml(x) for s, x in zip(segments, w, strict=True)])
        if np.max(np.abs(rate(0, w))) < 1e-8 and is_stable(k):
            return w
    raise AssertionError(f"the reference flow did not settle from {start}")


@pytest.mark.parametrize("seed", [1, 2])
def test_snaps_of_three_and_four_segments_land_where_a_tight_integration_of_the_flow_does(seed):
    rng = np.random.default_rng(seed)
    checked = 0
    for n in (3, 4):
        actuator = Actuator([random_cubic(rng, f"S{i}") for i in range(n)])
        folds = [e for e in quasi_static_path(actuator, deflate=True).events if e.cause == "fold"]
        for event in folds[:2]:
            k = np.array(event.pre.k_i)
            direction = (1 if event.direction == INFLATE else -1) * (-1 if np.any(k < 0) else 1)
            u = direction / k
            u -= u.mean()
            start = np.array(event.pre.v_i_ml) + 1e-3 * u / np.max(np.abs(u))
            expected = flow_destination(actuator, start)
            np.testing.assert_allclose(event.post.v_i_ml, expected, atol=1e-6)
            checked += 1
    assert checked >= 2


def test_a_flow_onto_a_wall_narrower_than_its_step_settles_where_radau_does():
    # B40-T24's bulge plateau ends 0.02 mL below a 4 kPa rise (the braids' spring); the
    # flow's trial stage jumped it, the two stages cancelled, and the step control
    # accepted the same empty step for ever (this triple failed the n = 3 scan)
    from labrig.model.actuator.descent import settle
    from labrig.model.segments.catalog import analytical_segment

    actuator = Actuator([analytical_segment(n) for n in ("B40-T24", "B40-T30", "B48-T24")])
    start = [5.47366351961869, 8.794617197742577, 4.065241871136714]
    end = settle(actuator.kernels, start)
    np.testing.assert_allclose(end, flow_destination(actuator, start), atol=1e-6)
    assert sum(end) == pytest.approx(sum(start), abs=1e-12)
    assert transitions(quasi_static_path(actuator, deflate=True))


def test_a_snap_without_a_peak_crossing_is_a_transition():
    """A snap need not cross a peak: B jumps from its softening onto its stiffening branch while A
    stays right of its peak; no peak flag changes, and it is still an unstable transition."""
    actuator = Actuator([cubic_segment("A", 6.6, 13.3, 34.0), cubic_segment("B", 3.1, 7.0, 39.0)])
    found = transitions(quasi_static_path(actuator))
    snap = next(t for t in found if not t.stable)
    assert (snap.alpha, snap.beta) == (2, 2)
    assert snap.pre.branches == (2, 1) and snap.post.branches == (2, 2)
    assert snap.dv > 0.1


def test_identical_segments_cross_one_at_a_time_deterministically():
    """Identical cubics peak together (singular Hessian). The cubic's right side is
    flatter than its left, so either may cross stably with the same energy: the lower
    index does, without a snap."""
    actuator = Actuator([cubic_segment("A", 4.0, 10.0, 30.0), cubic_segment("A2", 4.0, 10.0, 30.0)])
    path = quasi_static_path(actuator, deflate=True)
    first = transitions(path)[0]
    assert first.stable and (first.alpha, first.beta) == (0, 1)
    assert first.post.branches[0] == 1 and first.post.branches[1] == 0
    assert first.v_ml == pytest.approx(2 * actuator.segments[0].peak.v_ml, abs=1e-9)
    assert path.timeline == quasi_static_path(actuator, deflate=True).timeline
    sampled = sample_path(path)
    assert np.all(np.isfinite(sampled.v_i_ml)) and np.all(np.isfinite(sampled.p_kpa))


def test_four_identical_segments_are_deterministic_and_finite():
    """Every peak and valley coincides four times over. The path still takes one
    deterministic way, with finite numbers, equal pressures and the supplied volume;
    only within table resolution of the degenerate points (hysteresis loops below
    0.01 mL, see docs/explanation/actuator-model.md) may it pass marginally unstable states."""
    segs = [random_cubic(np.random.default_rng(7), name) for name in "ABCD"]
    path = quasi_static_path(Actuator(segs), deflate=True)
    assert path.timeline == quasi_static_path(Actuator(segs), deflate=True).timeline
    sampled = sample_path(path, dv_ml=0.1)
    assert np.all(np.isfinite(sampled.v_i_ml)) and np.all(np.isfinite(sampled.p_kpa))
    for seg, v in zip(segs, sampled.v_i_ml, strict=True):
        np.testing.assert_allclose(seg.pressure_kpa(v), sampled.p_kpa, atol=1e-8)
    k = np.array([seg.slope_kpa_per_ml(v) for seg, v in zip(segs, sampled.v_i_ml, strict=True)]).T
    unstable = ~is_stable(k) & (np.max(np.abs(k), axis=1) > 0)
    events = np.array([t.v_ml for t in transitions(path)])
    distance = np.min(np.abs(sampled.v_ml[unstable, None] - events[None, :]), axis=1)
    assert np.all(distance < 0.05)
    kinds = [(t.alpha, t.beta, t.stable) for t in transitions(path)]
    assert kinds[:3] == [(0, 1, False), (1, 2, False), (2, 3, False)]


def test_coincident_peaks_with_no_stable_way_on_snap():
    """Two identical segments whose fall is steeper than their rise: past a common peak
    neither can go on alone (k_fall + k_rise < 0), so the state is lost at the peak."""
    segs = [kinked_segment(name, 4.0, 32.0, 2.0, 3.0, 6.0) for name in ("K1", "K2")]
    path = quasi_static_path(Actuator(segs), deflate=True)
    first = transitions(path)[0]
    assert not first.stable and first.v_ml == pytest.approx(8.0, abs=1e-6)
    assert first.post.branches in {(2, 0), (0, 2)}
    assert path.events[0].cause == "coincident"
    assert path.timeline == quasi_static_path(Actuator(segs), deflate=True).timeline


def test_coincident_library_peaks_take_the_continuous_stable_branch():
    """SI-B46-T20 and SI-B46-T22 peak at exactly the same pressure. Of the two ways on, only
    SI-B46-T22 crossing is stable and continuous (its fall is flatter than SI-B46-T20's
    rise), so the crossing is stable and the volumes move continuously through it."""
    actuator = library_actuator("SI-B46-T20", "SI-B46-T22")
    a, b = actuator.segments
    assert a.peak.p_kpa == b.peak.p_kpa
    path = quasi_static_path(actuator)
    first = path.events[0]
    assert first.cause == "coincident branch ends" and first.post.branches == (0, 1)
    after = sample_path(path, dv_ml=0.001)
    near = np.abs(after.v_ml - first.pre.v_ml) < 0.01
    assert np.max(np.abs(np.diff(after.v_i_ml[:, near], axis=1))) < 0.05


def test_a_segment_without_a_peak_is_never_right_of_it():
    actuator = library_actuator("SI-B40-T28", "SI-B46-T20")  # SI-B40-T28 only rises
    assert actuator.segments[0].peak is None
    for t in transitions(quasi_static_path(actuator, deflate=True)):
        assert max(t.alpha, t.beta) <= 1


def test_the_end_volume_leaves_no_transition_outside():
    actuator = cubic_actuator(TRIPLE)
    v_end = default_end_volume_ml(actuator)
    last = transitions(quasi_static_path(actuator))[-1]
    assert last.v_ml < v_end
    # the same path stopped early has the same transitions up to there
    early = transitions(quasi_static_path(actuator, v_end_ml=last.v_ml - 0.5))
    assert [t.v_ml for t in early] == [t.v_ml for t in transitions(quasi_static_path(actuator))][
        : len(early)
    ]


def test_transition_numbers_follow_the_papers_definitions():
    """Recompute dE, dv, dl, dp of every transition from its pre/post volumes with the
    SegmentCurve's own (numpy) energy and length, and check the stable ones against
    the window they are evaluated over."""
    actuator = cubic_actuator(TRIPLE)
    segs = actuator.segments
    found = transitions(quasi_static_path(actuator, deflate=True), window_ml=1e-4)
    for t in found:
        pre, post = np.array(t.pre.v_i_ml), np.array(t.post.v_i_ml)
        e_pre = sum(float(s.energy_mj(v)) for s, v in zip(segs, pre, strict=True))
        e_post = sum(float(s.energy_mj(v)) for s, v in zip(segs, post, strict=True))
        l_pre = sum(float(s.length_mm(v)) for s, v in zip(segs, pre, strict=True))
        l_post = sum(float(s.length_mm(v)) for s, v in zip(segs, post, strict=True))
        assert t.dE == pytest.approx((e_post - e_pre) / e_pre, rel=1e-6, abs=1e-12)
        assert t.dv == pytest.approx(np.max(post - pre) / pre.sum(), rel=1e-9, abs=1e-15)
        assert t.dl == pytest.approx((l_post - l_pre) / l_pre, rel=1e-6, abs=1e-12)
        assert t.dp == pytest.approx(
            (t.post.p_kpa - t.pre.p_kpa) / t.pre.p_kpa, rel=1e-9, abs=1e-15
        )
        if t.stable:
            # a window of 1e-4 mL around a pressure peak: dE = p dv / E, dp ~ 0
            # (near a peak v is known to ~sqrt(rounding of p): 1e-8 of the window)
            assert post.sum() - pre.sum() == pytest.approx(t.direction * 1e-4, rel=1e-4)
            assert t.dE == pytest.approx(t.direction * t.pre.p_kpa * 1e-4 / e_pre, rel=1e-3)
            assert abs(t.dp) < 1e-6
        else:
            assert post.sum() == pytest.approx(pre.sum(), abs=1e-9) and t.dE < 0
    assert math.isclose(found[0].v_ml, found[0].pre.v_ml + 0.5e-4, abs_tol=1e-12) or found[0].stable


TRICKY = [
    ("SI-B40-T28", "SI-B50-T22"),  # SI-B40-T28's contact kink under the other's long fall
    ("SI-B46-T26", "SI-B46-T28"),  # coincident peaks, a 0.08 mL snap right after them
    ("SI-B40-T20", "SI-B40-T24"),  # coincident peaks, snaps back on deflation next to them
    ("SI-B44-T22", "SI-B44-T30"),  # SI-B44-T30's 0.007 kPa dip
    ("SI-B42-T20", "SI-B42-T26", "SI-B50-T20"),
]


@pytest.mark.parametrize("names", TRICKY, ids=["+".join(n) for n in TRICKY])
def test_no_fold_is_missed_next_to_kinks_dips_and_coincident_peaks(names):
    """Sampled every 2 uL, the path holds only stable states (a missed fold would show
    as a stretch of unstable ones), checked with the SegmentCurve's own slopes."""
    actuator = library_actuator(*names)
    sampled = sample_path(quasi_static_path(actuator, deflate=True), dv_ml=0.002)
    k = np.array(
        [s.slope_kpa_per_ml(v) for s, v in zip(actuator.segments, sampled.v_i_ml, strict=True)]
    ).T
    unstable = ~is_stable(k)
    smallest = np.array([np.linalg.eigvalsh(hessian(row)).min() for row in k[unstable]])
    assert np.all(smallest > -1e-6 * np.median(np.abs(k)))
