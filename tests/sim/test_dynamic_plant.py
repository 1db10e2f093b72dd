"""The step experiments' plant against analytic limits: an RC decay, the isothermal gas
law, the model's quasi-static path when slow, and the model's blocked force."""

import numpy as np
import pytest

from labrig.model.actuator.prediction import predicted_inflation
from labrig.model.blocked import BlockedActuator
from labrig.model.segments.catalog import load_segment
from labrig.model.segments.curve import SegmentCurve
from labrig.sim.dynamic_plant import AIR, ATMOSPHERE_KPA, WATER, Coupling, DynamicPlant, Plumbing


def linear_segment(k_kpa_per_ml: float) -> SegmentCurve:
    v = np.linspace(0.0, 50.0, 11)
    return SegmentCurve("linear", v, k_kpa_per_ml * v, np.full_like(v, 30.0), V0_ml=5.0)


# manifold compliance C_m (the line's), segment compliance C_s = 1/k, resistance R:
# after a quick push of V the manifold falls from V/C_m to V/(C_m + C_s) with
# tau = R C_m C_s / (C_m + C_s) = 0.05 s
C_M, K, R, VOLUME, PUSH_END_S = 0.1, 10.0, 1.0, 1.0, 1.0 + 1e-4
C_S = 1 / K
TAU_S = R * C_M * C_S / (C_M + C_S)
FINAL_KPA = VOLUME / (C_M + C_S)


def pushed_rc_circuit() -> DynamicPlant:
    """A linear segment behind the line's compliance and a resistance, pushed by VOLUME
    from the reservoir over 0.1 ms at t = 1 s."""
    plumbing = Plumbing(fluid=WATER, dead_volume_ml=1e-6, line_compliance_ml_per_kpa=C_M)
    plant = DynamicPlant(
        [linear_segment(K)],
        lambda t: 0.0,
        plumbing=plumbing,
        coupling=Coupling(R, 0.0, 1e-7),
        wall_damping=False,
    )
    plant.connect("reservoir", 1.0)
    plant.push_reservoir(VOLUME, 1e-4, 1.0)
    return plant


def rc_decay_kpa(t_s):
    return FINAL_KPA + (VOLUME / C_M - FINAL_KPA) * np.exp(-(t_s - PUSH_END_S) / TAU_S)


def test_a_quick_push_decays_into_a_linear_segment_as_an_rc_circuit():
    plant = pushed_rc_circuit()
    t = PUSH_END_S + np.array([0.5, 1.0, 2.0, 4.0]) * TAU_S
    np.testing.assert_allclose(plant.pressure_kpa_at(t), rc_decay_kpa(t), rtol=5e-3)
    plant.advance_to(1.0 + 40 * TAU_S)
    assert plant.volumes_ml[0] == pytest.approx(VOLUME * C_S / (C_M + C_S), rel=1e-3)


def test_a_plant_at_rest_is_held_where_it_settled_without_integrating(monkeypatch):
    """The RC circuit above asked every 0.1 s for 10 s, as a run's loops ask during a
    technician's prompt: at each time the analytic decay, and once it has settled (its
    rates below the integrator's tolerance over an interval) the intervals are held, not
    integrated: scipy's integrator is started for the first few only."""
    import labrig.sim.dynamic_plant as dynamic_plant

    calls = []
    solve = dynamic_plant.solve_ivp
    monkeypatch.setattr(
        dynamic_plant, "solve_ivp", lambda *a, **k: calls.append(1) or solve(*a, **k)
    )
    plant = pushed_rc_circuit()
    times = PUSH_END_S + 0.1 * np.arange(1, 101)
    for t in times:
        plant.advance_to(t)
    np.testing.assert_allclose(
        plant.pressure_kpa_at(times), rc_decay_kpa(times), rtol=5e-3, atol=1e-5
    )
    assert plant.volumes_ml[0] == pytest.approx(VOLUME * C_S / (C_M + C_S), rel=1e-5)
    assert 2 <= len(calls) <= 20


def test_air_obeys_the_isothermal_gas_law_at_rest():
    segments = [load_segment("B44-T30"), load_segment("B48-T26")]
    plumbing = Plumbing(
        fluid=AIR,
        dead_volume_ml=2.0,
        syringe_ml=50.0,
        air_reservoir_ml=10.0,
        line_compliance_ml_per_kpa=0.002,
    )
    displaced = 30.0
    plant = DynamicPlant(segments, lambda t: min(max(t, 0.0), displaced), plumbing=plumbing)
    plant.advance_to(displaced + 10.0)
    p = float(plant.pressure_kpa_at(displaced + 10.0))
    v0 = sum(s.V0_ml for s in segments)
    gas_before = 50.0 + 2.0 + 10.0 + v0
    # the line's wall compliance holds a little more at pressure
    gas_after = gas_before - displaced + plant.volumes_ml.sum() + 0.002 * p
    assert (ATMOSPHERE_KPA + p) * gas_after == pytest.approx(ATMOSPHERE_KPA * gas_before, rel=5e-4)
    # the membranes hold the gas's pressure
    for segment, w in zip(segments, plant.volumes_ml, strict=True):
        assert float(segment.pressure_kpa(w)) == pytest.approx(p, abs=0.02)


def test_a_slow_water_inflation_follows_the_models_quasi_static_path():
    # slow means the flow's pressure drop is small: through 1.5 mm couplings 5 mL/min
    # drops a few hundredths of a kPa (coupling and wall); the default bore, narrower to
    # give the water snap its time, would need about 1 mL/min. The SI's segments of this
    # pair have no snap below 22 mL
    segments = [load_segment("SI-B48-T30"), load_segment("SI-B50-T20")]
    rate_ml_s = 5 / 60
    plant = DynamicPlant(
        segments,
        lambda t: max(t, 0.0) * rate_ml_s,
        plumbing=Plumbing(bore_mm=1.5),
        fittings_length_mm=10,
    )
    t = np.arange(1.0, 18.0 / rate_ml_s, 0.5)
    v_model, p_model, l_model = predicted_inflation(segments, 18.0, 0.05)
    p = plant.pressure_kpa_at(t)
    length = plant.length_mm_at(t)
    # the volume in the segments: the pump's, less what the line's wall compliance holds
    v = plant.segment_volumes_ml_at(t).sum(axis=1)
    assert np.sqrt(np.mean((p - np.interp(v, v_model, p_model)) ** 2)) < 0.06
    # the plant's length is the marker distance: the segments' and the 10 mm fittings
    assert np.max(np.abs(length - 10 - np.interp(v, v_model, l_model))) < 0.05


def test_the_blocked_plant_pushes_with_the_models_force():
    segments = [load_segment("SI-B48-T30"), load_segment("SI-B50-T20")]  # snaps at 15.8 mL
    rate_ml_s = 5 / 60
    plant = DynamicPlant(
        segments, lambda t: max(t, 0.0) * rate_ml_s, fittings_length_mm=10, blocked=True
    )
    t = np.arange(1.0, 15.0 / rate_ml_s, 0.5)
    model = BlockedActuator(segments, 10).path(15.0, 0.05)
    force = plant.force_n_at(t)
    expected = np.interp(t * rate_ml_s, model.v_ml, model.force_n)
    # the plant lags the pump by its flow time: a few hundredths of a newton at 5 mL/min
    np.testing.assert_allclose(force, expected, rtol=0.02, atol=0.02)
    assert np.all(plant.length_mm_at(t) == plant.length_mm_at(0.0))
