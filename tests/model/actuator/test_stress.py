"""Numerical stress tests of the path solver as scans use it (hypothesis).

Random segment curves — one or two peaks, flat plateaus and near-zero slopes, dips from
1e-6 kPa to tens of kPa, peaks above the 100 kPa pressure grid, near-coincident and
identical peaks of different segments, noisy measured curves through the shape fit,
volumes from microlitres to litres — and the invariants every path must keep:

- every state before and after a transition is an equilibrium: one pressure in every
  segment, the supplied volume; the state after is stable; a snap keeps the volume and
  releases energy (the flow is a gradient descent); numbers are finite, no NaN;
- alpha and beta count the segments right of their peak;
- the model is scale-free in volume: scaling every curve's volumes by s scales the
  transition volumes by s and leaves the relative changes of a snap unchanged;
- determinism: the same input gives the same output, and a scan gives the same rows
  with 1 or 2 workers.
"""

import io
import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from support.stress_curves import STRESS, TWIN, knot_curve, shapes

from labrig.model.actuator.equilibria import Actuator, is_stable
from labrig.model.actuator.path import INFLATE, quasi_static_path, sample_path
from labrig.model.actuator.transitions import transitions
from labrig.model.scan.scan import Chunk, ScanLibrary, make_chunks, run_chunks


def check_invariants(actuator, deflate=False):
    """The invariants of the module docstring, with tolerances relative to the scales of
    the actuator (volumes from microlitres to litres): a fold is located to ~1e-11 kPa,
    which on a near-flat stretch (dv/dp up to ~1e4 mL/kPa) is ~1e-7 of the volume."""
    path = quasi_static_path(actuator, deflate=deflate)
    found = transitions(path)
    kernels = actuator.kernels
    v_scale = path.v_end_ml
    for t in found:
        for name in ("v_ml", "dE", "dv", "dl", "dp"):
            assert math.isfinite(getattr(t, name)), (name, t)
        for state in (t.pre, t.post):
            p = [kern.pressure(v) for kern, v in zip(kernels, state.v_i_ml, strict=True)]
            assert max(abs(x - state.p_kpa) for x in p) <= 1e-7 * max(1.0, abs(state.p_kpa))
            assert all(math.isfinite(x) for x in state.v_i_ml)
        assert t.alpha == actuator.alpha(t.pre.branches)
        assert t.beta == actuator.alpha(t.post.branches)
        assert 0 <= t.alpha <= actuator.n and 0 <= t.beta <= actuator.n
        k_post = np.array([kern.slope(v) for kern, v in zip(kernels, t.post.v_i_ml, strict=True)])
        # stable, or marginally so: on an extremum (k = 0) or on a fold (sum 1/k = 0),
        # where a stable transition's window can end when the next snap follows at once
        at_extremum = np.min(np.abs(k_post)) <= 1e-9 * np.max(np.abs(k_post))
        at_fold = not at_extremum and abs(np.sum(1 / k_post)) <= 1e-6 * np.sum(1 / np.abs(k_post))
        assert is_stable(k_post) or at_extremum or at_fold, k_post
        if not t.stable:
            moved = t.post.v_ml - t.pre.v_ml
            assert abs(moved) <= 1e-7 * v_scale
            # a snap at constant volume releases energy (the flow is a gradient descent)
            e_pre = actuator.energy_mj(t.pre.v_i_ml)
            assert t.dE <= (abs(t.pre.p_kpa * moved) + 1e-12 * e_pre) / e_pre
    inflating = [t.v_ml for t in found if t.direction == INFLATE]
    assert inflating == sorted(inflating)
    sampled = sample_path(path, dv_ml=v_scale / 200)
    assert np.all(np.isfinite(sampled.v_i_ml)) and np.all(np.isfinite(sampled.p_kpa))
    np.testing.assert_allclose(sampled.v_i_ml.sum(axis=0), sampled.v_ml, rtol=1e-9, atol=1e-12)
    assert quasi_static_path(actuator, deflate=deflate).timeline == path.timeline
    return found


# cases hypothesis found, each once a solver failure (kept as regressions)
PLATEAU = ([0, 1, 3, 6], [0, 2, 2, 300])  # exactly flat from 1 to 3 mL
FLAT_DIP = ([0, 1, 2, 5], [0, 2, 1.999999, 300])  # a peak and a 1e-6 kPa dip


@STRESS
@given(st.lists(shapes(), min_size=2, max_size=3), st.booleans())
@example([FLAT_DIP, PLATEAU], True)  # a plateau at the pressure of another's peak
@example([([0, 1, 2, 3, 4, 8], [0, 2, 2, 3, 2.999999, 300]), FLAT_DIP], True)
@example([TWIN, TWIN], True)  # identical segments whose fold mirrors itself
@example([([0, 1, 2, 5], [0, 40, 39.999999, 300])] * 2, True)  # common peak and valley
def test_random_curves_keep_the_invariants(knots, deflate):
    actuator = Actuator([knot_curve(f"S{i}", *k) for i, k in enumerate(knots)])
    check_invariants(actuator, deflate=deflate)


@STRESS
@given(
    shapes(peak_kpa=40.0, min_peaks=1, min_dip_kpa=1e-3),
    st.sampled_from([0.0, 1e-12, 1e-9, 1e-6, 1e-3, 0.1]),
    st.booleans(),
    st.data(),
)
def test_near_coincident_and_identical_peaks(first, offset_kpa, twin, data):
    """A second segment peaking within ``offset_kpa`` of the first (0: the same peak
    pressure, a singular Hessian), and identical segments (a symmetric bifurcation: one
    deterministic branch, no NaN).

    Not covered (docs/explanation/scans.md, limits): dips of 1e-6 kPa (1e-8 of the peak; the random
    curves above have them) next to near-coincident peaks, and a twin pair plus a third
    segment peaking within 1e-9 kPa of them: such degeneracies are decided by rounding
    and the solver may give up (a FlowError, which a scan records as a failed
    actuator). The smallest dip of the library is 0.007 kPa."""
    if twin and 0.0 < offset_kpa < 0.1:
        offset_kpa = 0.0
    second = data.draw(shapes(peak_kpa=40.0 + offset_kpa, min_peaks=1, min_dip_kpa=1e-3))
    curves = [knot_curve("A", *first), knot_curve("B", *second)]
    if twin:
        curves.append(knot_curve("A-twin", *first))
    check_invariants(Actuator(curves), deflate=True)
    twins = Actuator([knot_curve("A", *first), knot_curve("A-twin", *first)])
    check_invariants(twins, deflate=True)


# two failing draws of the test above that hypothesis found when the set of imported
# modules differed (tests/conftest.py, _import_every_module): a peak exactly at
# another's (offset 0) next to an exact plateau and a 1e-3 kPa dip (cases 1 and 2 below)
COINCIDENT_PEAK = ([0, 0.5, 4.5, 7.5], [0, 40, 15, 300])
PLATEAU_THEN_PEAK = ([0, 1, 3.6875, 6.6875, 8.265625, 15.078125], [0, 12, 12, 40, 39.999, 300])


@pytest.mark.xfail(strict=True, reason="a twin pair and a third segment peaking at "
                   "their pressure exactly: no equilibrium where a fold leads")  # fmt: skip
def test_a_twin_pair_and_a_third_segment_at_exactly_their_peak():
    curves = [
        knot_curve("A", *COINCIDENT_PEAK),
        knot_curve("B", *PLATEAU_THEN_PEAK),
        knot_curve("A-twin", *COINCIDENT_PEAK),
    ]
    check_invariants(Actuator(curves), deflate=True)


@pytest.mark.xfail(strict=True, reason="a fold pair of 3e-5 kPa on deflation past an exact "
                   "plateau gains 2.6e-9 of the energy (a snap must release it)")  # fmt: skip
def test_a_fold_pair_past_an_exact_plateau_releases_energy():
    second = ([0, 1, 2, 4, 5.6875, 10.265625], [0, 2, 2, 40, 39.999, 300])
    curves = [knot_curve("A", [0, 1, 3, 6], [0, 40, 15, 300]), knot_curve("B", *second)]
    check_invariants(Actuator(curves), deflate=True)


@STRESS
@given(shapes(), st.floats(110.0, 250.0), st.floats(2.0, 10.0))
def test_a_peak_above_the_pressure_grid(low, peak_kpa, width_ml):
    """A segment that peaks above 100 kPa (the paper's grid and the sensor's range),
    with a 20 kPa dip and a wall after it."""
    tall = (
        [0.0, width_ml, 2 * width_ml, 3 * width_ml],
        [0.0, peak_kpa, peak_kpa - 20, peak_kpa + 150],
    )
    check_invariants(Actuator([knot_curve("low", *low), knot_curve("tall", *tall)]), deflate=True)


@STRESS
@given(st.lists(shapes(), min_size=2, max_size=2), st.sampled_from([1e-3, 1e-2, 0.1, 10.0, 1e3]))
def test_volumes_from_microlitres_to_litres_scale_the_path(knots, scale):
    """Pressure is unchanged and energy scales with volume, so the same actuator built
    at another volume scale has its transitions at s times the volumes, with the same
    types and the same relative changes of every snap."""
    unit = transitions(
        quasi_static_path(Actuator([knot_curve(f"S{i}", *k) for i, k in enumerate(knots)]))
    )
    scaled_actuator = Actuator([knot_curve(f"S{i}", *k, scale=scale) for i, k in enumerate(knots)])
    scaled = check_invariants(scaled_actuator)
    assert [(t.alpha, t.beta, t.stable) for t in scaled] == [
        (t.alpha, t.beta, t.stable) for t in unit
    ]
    for a, b in zip(unit, scaled, strict=True):
        assert b.v_ml == pytest.approx(a.v_ml * scale, rel=1e-7)
        if not a.stable:
            for name in ("dE", "dv", "dl", "dp"):
                assert getattr(b, name) == pytest.approx(getattr(a, name), rel=1e-5, abs=1e-9)


# found by this test: the fit's offset made a plateau's curve fall 0 -> -23 kPa first
# (a spline that missed its flat start), then fall by its first bin's noise below zero
@example(knots=[([0.0, 1.0, 2.0, 5.0], [0.0, 2.0, 2.0, 300.0])] * 2, seed=0)
@example(knots=[([0.0, 3.0], [0.0, 300.0]), ([0.0, 1.0, 2.0, 6.0], [0.0, 2.0, 2.0, 300.0])], seed=0)
@settings(STRESS, max_examples=8)
@given(st.lists(shapes(min_valley_kpa=2.0), min_size=2, max_size=2), st.integers(0, 2**32 - 1))
def test_noisy_measured_curves(tmp_path_factory, knots, seed):
    """Raw rig-like data (1000 samples/mL, 0.3 kPa noise, 0.3 kPa quantisation) through
    the measured-curve loader's shape fit, then the path. Valleys stay 2 kPa (7 noise
    sigmas) above zero: a fitted valley below 0 kPa asks another segment for a pressure
    below its unpressurised state, outside the curves (a FlowError, docs/explanation/scans.md)."""
    from labrig.model.segments.measured import load_csv

    rng = np.random.default_rng(seed)
    folder = tmp_path_factory.mktemp("noisy")
    curves = []
    for i, k in enumerate(knots):
        clean = knot_curve(f"S{i}", *k)
        v = np.arange(0.0, clean.v_max_ml * 0.9, 0.001)
        p = clean.pressure_kpa(v) + rng.normal(0.0, 0.3, len(v))
        p = np.round(p / 0.3) * 0.3
        text = io.StringIO()
        text.write("volume_ml,pressure_kpa,length_mm\n")
        np.savetxt(text, np.column_stack([v, p, clean.length_mm(v)]), delimiter=",", fmt="%.5f")
        path = folder / f"S{i}.csv"
        path.write_text(text.getvalue())
        curves.append(load_csv(path))
    check_invariants(Actuator(curves), deflate=True)


@settings(STRESS, max_examples=5)
@given(st.lists(shapes(), min_size=4, max_size=4))
def test_a_scan_is_the_same_with_one_or_two_workers(knots):
    library = ScanLibrary("random", tuple(knot_curve(f"S{i}", *k) for i, k in enumerate(knots)))
    chunks = make_chunks(4, 2, 2) + [
        Chunk(3 + i, c.start, c.stop, 3) for i, c in enumerate(make_chunks(4, 3, 2))
    ]
    results = {}
    for workers in (1, 2):
        found = []
        run_chunks(library, chunks, found.extend, workers=workers)
        results[workers] = found
    assert [r.index for r in results[2]] == [c.index for c in chunks]
    for one, two in zip(results[1], results[2], strict=True):
        np.testing.assert_array_equal(one.actuator, two.actuator)
        np.testing.assert_array_equal(one.segments, two.segments)
        for name, column in one.columns.items():
            np.testing.assert_array_equal(column, two.columns[name])
        assert one.failed_error == two.failed_error == ()
