"""The simulated specimen against independent computations: volume conservation, the
quasi-static equilibrium found by root-finding, and snap-throughs that end in a stable
equilibrium after a time set by the flow resistance."""

import threading

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.interpolate import PchipInterpolator
from scipy.optimize import brentq

from labrig.model.segments.curve import SegmentCurve
from labrig.sim.plant import Plant

V = np.linspace(0.0, 80.0, 1601)


def cubic_curve(name="cubic", scale=1.0):
    """Rise to a peak at v=5.9, fall to a valley at v=14.1, then stiffen."""
    v = V / scale
    return SegmentCurve(name, V, 10 * v - 1.2 * v**2 + 0.04 * v**3, 20 + V / 4, V0_ml=3.0)


def monotone_curve(name, stiffness):
    return SegmentCurve(name, V, stiffness * V + 0.05 * V**2, 30 - V / 10, V0_ml=2.0)


def ramp(rate_ml_s, v_max_ml):
    return lambda t: min(rate_ml_s * t, v_max_ml)


def test_total_volume_always_equals_the_pumps():
    pump = ramp(0.5, 30.0)
    plant = Plant([cubic_curve("a"), cubic_curve("b", 1.1)], pump)
    for t in np.linspace(0, 80, 41):
        plant.advance_to(t)
        assert plant.volumes_ml.sum() == pytest.approx(pump(t), abs=1e-9)


def test_slow_inflation_follows_the_equilibrium_found_by_root_finding():
    a, b = monotone_curve("a", 1.0), monotone_curve("b", 3.0)
    rate = 20 / 60
    plant = Plant([a, b], ramp(rate, 40.0), resistance_kpa_s_per_ml=0.5)
    for target_ml in (5.0, 15.0, 30.0):
        t = target_ml / rate
        inlet = float(plant.pressure_kpa_at(t))

        def excess(p, target=target_ml):
            va = brentq(lambda v: float(a.pressure_kpa(v)) - p, 0, 80)
            vb = brentq(lambda v: float(b.pressure_kpa(v)) - p, 0, 80)
            return va + vb - target

        p_equilibrium = brentq(excess, 1e-9, 300)
        # First order in the flow: the inflow splits as the compliances 1/k_i, each
        # segment lags the manifold by R q_i, and the sensor on the manifold reads
        # p_eq + R Q sum(1/k^2) / (sum 1/k)^2.
        va = brentq(lambda v, p=p_equilibrium: float(a.pressure_kpa(v)) - p, 0, 80)
        vb = brentq(lambda v, p=p_equilibrium: float(b.pressure_kpa(v)) - p, 0, 80)
        compliance = np.array([1 / a.slope_kpa_per_ml(va), 1 / b.slope_kpa_per_ml(vb)])
        q = rate * compliance / compliance.sum()
        lag = 0.5 * rate * np.sum(compliance**2) / compliance.sum() ** 2
        assert inlet == pytest.approx(p_equilibrium + lag, abs=0.005)
        w = plant.volumes_ml
        p_a, p_b = float(a.pressure_kpa(w[0])), float(b.pressure_kpa(w[1]))
        assert p_a - p_b == pytest.approx(0.5 * (q[1] - q[0]), abs=0.005)


def settle(curves, v_hold_ml, resistance=1.0, seed=0):
    """Inflate to v_hold quickly enough to pass a peak, then hold until settled."""
    plant = Plant(curves, ramp(0.5, v_hold_ml), resistance_kpa_s_per_ml=resistance, seed=seed)
    plant.advance_to(v_hold_ml / 0.5 + 60.0)
    return plant


def test_identical_segments_snap_to_a_stable_asymmetric_equilibrium():
    a, b = cubic_curve("a"), cubic_curve("b")
    plant = settle([a, b], 16.0)
    w = plant.volumes_ml
    p = [float(a.pressure_kpa(w[0])), float(b.pressure_kpa(w[1]))]
    k = [float(a.slope_kpa_per_ml(w[0])), float(b.slope_kpa_per_ml(w[1]))]
    assert p[0] == pytest.approx(p[1], abs=1e-6)  # equilibrium: Eq. 7
    assert k[0] + k[1] > 0  # stability for n = 2: Eq. 10
    assert abs(w[0] - w[1]) > 5.0  # the symmetric state was unstable and was left
    assert sum(w) == pytest.approx(16.0, abs=1e-9)


def test_the_same_seed_gives_the_same_run_and_the_seed_picks_the_branch():
    curves = [cubic_curve("a"), cubic_curve("b")]
    first, again = settle(curves, 16.0, seed=3), settle(curves, 16.0, seed=3)
    np.testing.assert_array_equal(first.volumes_ml, again.volumes_ml)
    winners = {int(np.argmax(settle(curves, 16.0, seed=s).volumes_ml)) for s in range(6)}
    assert winners == {0, 1}


def snap_duration_s(resistance):
    """Time for the internal flow of a snap at constant volume to do 10..90 % of its work."""
    curves = [cubic_curve("a"), cubic_curve("b", 1.05)]
    plant = Plant(curves, ramp(2.0, 13.0), resistance_kpa_s_per_ml=resistance)
    plant.advance_to(60.0)
    t = np.array(plant._history_t)
    w0 = np.array([w[0] for w in plant._history_w])
    hold = t > 13.0 / 2.0
    moved = np.abs(w0[hold] - w0[hold][0])
    total = moved[-1]
    return t[hold][np.argmax(moved > 0.9 * total)] - t[hold][np.argmax(moved > 0.1 * total)]


def test_snap_takes_a_finite_time_proportional_to_the_resistance():
    short, long = snap_duration_s(0.5), snap_duration_s(1.0)
    assert 0.1 < short < 5.0
    assert long / short == pytest.approx(2.0, rel=0.15)


def test_queries_in_any_order_from_several_threads():
    plant = Plant([cubic_curve("a"), cubic_curve("b", 1.1)], ramp(0.3, 20.0))
    times = np.linspace(0.0, 50.0, 5001)
    reference = plant.pressure_kpa_at(times).copy()
    results = []

    def query(order):
        results.append(np.array([plant.pressure_kpa_at(times[i]) for i in order]))

    orders = [np.arange(0, 5001, 7), np.arange(5000, -1, -11)]
    threads = [threading.Thread(target=query, args=(o,)) for o in orders]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert len(results) == 2
    for order in orders:
        assert any(len(r) == len(order) and np.allclose(r, reference[order]) for r in results)


def test_history_that_was_dropped_is_an_error():
    plant = Plant([cubic_curve()], ramp(0.1, 5.0), history_s=10.0)
    plant.advance_to(100.0)
    with pytest.raises(ValueError, match="history starts"):
        plant.pressure_kpa_at(1.0)


def test_length_is_the_sum_of_segments_plus_fittings():
    a, b = monotone_curve("a", 1.0), monotone_curve("b", 2.0)
    plant = Plant([a, b], ramp(1.0, 10.0), fittings_length_mm=12.0)
    plant.advance_to(20.0)
    w = plant.volumes_ml
    expected = float(a.length_mm(w[0]) + b.length_mm(w[1])) + 12.0
    assert float(plant.length_mm_at(20.0)) == pytest.approx(expected, abs=1e-9)


KNOTS_ML = np.array([0.0, 0.5, 1.25, 2.0, 4.0, 7.5, 9.0])
TABLE = SegmentCurve(
    "table",
    KNOTS_ML,
    3 * KNOTS_ML - 0.4 * KNOTS_ML**2 + 0.03 * KNOTS_ML**3,
    20 + KNOTS_ML,
    V0_ml=0.0,
)


@given(
    st.one_of(
        st.floats(-2.0, 12.0, allow_nan=False),
        st.sampled_from(KNOTS_ML.tolist()),  # on a knot: the interval to its right
    )
)
def test_the_plants_scalar_curve_is_the_pchip_of_its_table(v_ml):
    """ScalarCurve's own interval search and Horner evaluation against scipy's
    interpolant of the same table: below the table the first interval's polynomial,
    past its end a straight continuation (pressure) or the held end (length)."""
    from labrig.sim.plant import ScalarCurve

    curve = ScalarCurve(TABLE)
    pressure = PchipInterpolator(TABLE.v_ml, TABLE.p_kpa)
    length = PchipInterpolator(TABLE.v_ml, TABLE.l_mm)
    v_end = float(KNOTS_ML[-1])
    p_kpa, slope = curve.pressure_and_slope(v_ml)
    if v_ml > v_end:
        slope_end = float(pressure.derivative()(v_end))
        expected = (float(pressure(v_end)) + slope_end * (v_ml - v_end), slope_end, TABLE.l_mm[-1])
        expected_dl = 0.0
    else:
        expected = (float(pressure(v_ml)), float(pressure.derivative()(v_ml)), float(length(v_ml)))
        expected_dl = float(length.derivative()(v_ml))
    got = (p_kpa, slope, curve.length(v_ml))
    assert got == pytest.approx(expected, rel=1e-12, abs=1e-12)
    assert curve.length_slope(v_ml) == pytest.approx(expected_dl, rel=1e-12, abs=1e-12)


def reference_pressure_kpa(plant, curves, pieces, times):
    """The manifold pressure of the plant's equations integrated independently: scipy's
    Radau (implicit, fifth order) at tight tolerances on dw_i/dt = c_i (p_m - p_i) with
    p_m = (Q + sum c_j p_j) / C, piece by piece between the pump's rate changes
    (``pieces``: (start, end, rate) each), the curves from scipy's own PCHIP."""
    from scipy.integrate import solve_ivp

    c = np.array(plant._conductances)
    pressure = [PchipInterpolator(s.v_ml, s.p_kpa, extrapolate=True) for s in curves]
    slope = [p.derivative() for p in pressure]
    w = np.zeros(len(curves))
    out = np.empty_like(times)
    for start, end, rate in pieces:

        def rhs(t, w, rate=rate):
            p = np.array([f(wi) for f, wi in zip(pressure, w, strict=True)])
            return c * ((rate + c @ p) / c.sum() - p)

        def jacobian(t, w):
            k = np.array([f(wi) for f, wi in zip(slope, w, strict=True)])
            return np.outer(c, c * k) / c.sum() - np.diag(c * k)

        done = solve_ivp(rhs, (start, end), w, method="Radau", jac=jacobian, rtol=1e-7,
                         atol=1e-9, dense_output=True)  # fmt: skip
        assert done.success, done.message
        inside = (times >= start) & (times <= end)
        ws = done.sol(times[inside])
        ps = np.array([f(wi) for f, wi in zip(pressure, ws, strict=True)])
        out[inside] = (rate + c @ ps) / c.sum()
        w = done.y[:, -1]
    return out


def test_the_demo_specimen_follows_a_reference_integration_through_its_snap():
    """The demo's two segments filled at 40 mL/min past their (2, 1) snap, held, then
    emptied past the snap back: the sensor's pressure at 1 kHz, as the DAQ reads it
    from the plant's history, against an independent integration. Away from the snaps
    it is within 0.1 kPa (twice the sensor's noise) at every sample and 0.01 kPa at
    99 % of them; each snap (the pressure falling faster than 150 kPa/s) starts within
    5 ms of the reference's."""
    from labrig.model.segments.catalog import load_segment

    curves = [load_segment("B48-T30"), load_segment("B50-T20")]
    rate = 40 / 60
    fill_s = 38 / rate
    pieces = [(0.0, fill_s, rate), (fill_s, fill_s + 5, 0.0), (fill_s + 5, 2 * fill_s + 5, -rate)]

    def supplied_ml(t):
        return rate * min(t, fill_s) - rate * min(max(t - fill_s - 5, 0.0), fill_s)

    plant = Plant(curves, supplied_ml, history_s=1e3)
    end_s = pieces[-1][1]
    for t in np.arange(0.1, end_s, 0.1):  # the rig asks every 0.1 s at least
        plant.advance_to(float(t))
    times = np.arange(0.0, end_s, 0.001)
    got = plant.pressure_kpa_at(times)
    expected = reference_pressure_kpa(plant, curves, pieces, times)

    def snap_starts_s(p):
        falling = np.flatnonzero(np.diff(p) < -0.15)  # kPa a millisecond
        return times[falling[np.r_[True, np.diff(falling) > 100]]]

    snaps = snap_starts_s(expected)
    assert len(snaps) == 2  # the (2, 1) snap filling and its return emptying
    assert snap_starts_s(got) == pytest.approx(snaps, abs=0.005)
    away = np.ones(len(times), dtype=bool)
    for t in snaps:
        away &= (times < t - 0.05) | (times > t + 1.5)
    error = np.abs(got - expected)[away]
    assert error.max() < 0.1
    assert np.percentile(error, 99) < 0.01


def test_a_softening_segment_beside_a_stiff_one_is_stable_and_grows_no_step_limit():
    """``growth_rate`` against the largest eigenvalue of the plant's Jacobian
    -(diag(c) - c c^T / C) diag(k), computed by numpy: zero where every eigenvalue is
    negative (a softening segment whose neighbours take up its volume), otherwise the
    growth rate or a little above it (a limit on the step)."""
    from labrig.sim.plant import growth_rate

    rng = np.random.default_rng(5)
    for n in (1, 2, 3, 4):
        for _ in range(200):
            c = rng.uniform(5.0, 15.0, n)
            k = rng.uniform(-20.0, 40.0, n)
            jacobian = -(np.diag(c) - np.outer(c, c) / c.sum()) @ np.diag(k)
            largest = max(np.linalg.eigvals(jacobian).real.max(), 0.0)
            got = growth_rate(k.tolist(), c.tolist())
            if largest < 1e-9:
                assert got == 0.0
            else:
                assert largest <= got <= largest * 1.01 + 1e-9


def test_a_single_segment_reads_its_curve_at_the_pumps_volume_between_steps():
    """One segment takes all the pump gives: its sensor reads p(V(t)) + Q/c exactly
    (scipy's PCHIP of its table), and the history's straight lines between the plant's
    steps, as the DAQ reads them at 1 kHz, stay within 0.03 kPa of it where the curve
    turns (its peak, its knots) and 0.01 kPa at 99 % of the samples."""
    from labrig.model.segments.catalog import load_segment

    curve = load_segment("B50-T20")
    rate = 40 / 60
    fill_s = 20 / rate

    def supplied_ml(t):
        return rate * min(t, fill_s) - rate * min(max(t - fill_s - 5, 0.0), fill_s)

    plant = Plant([curve], supplied_ml, history_s=1e3)
    end_s = 2 * fill_s + 5
    for t in np.arange(0.1, end_s, 0.1):
        plant.advance_to(float(t))
    times = np.arange(0.0, end_s, 0.001)
    volume = np.array([supplied_ml(t) for t in times])
    flow = np.where(times < fill_s, rate, np.where(times < fill_s + 5, 0.0, -rate))
    expected = PchipInterpolator(curve.v_ml, curve.p_kpa)(volume) + flow / plant._conductances[0]
    # a sample within a millisecond of the pump's start or stop falls on a step across it
    away = np.abs(times[:, None] - np.array([0.0, fill_s, fill_s + 5, end_s])).min(axis=1) > 1e-3
    error = np.abs(plant.pressure_kpa_at(times) - expected)[away]
    assert error.max() < 0.03
    assert np.percentile(error, 99) < 0.01
