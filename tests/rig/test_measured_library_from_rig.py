"""The paper's workflow on the simulated rig: characterise one segment, turn the run into
a measured segment, and use it in the model like a library name."""

import textwrap

import pytest
from support.simrig import run_sim

from labrig.analysis.measured_library import add_from_run
from labrig.model.segments.catalog import analytical_segment, load_segment

PROTOCOL = textwrap.dedent(
    """\
    name: characterise SI-B46-T20
    specimen: {segments: [SI-B46-T20], fittings_length_mm: 10}
    rig: sim
    limits: {max_pressure_kpa: 95, max_volume_ml: 25}
    acquisition: {pressure_rate_hz: 1000, camera_fps: 2}
    steps:
      - zero_pressure: {duration_s: 1}
      - repeat:
          times: 2
          steps:
            - infuse: {rate_ml_min: 60, volume_ml: 20.8}
            - hold: {seconds: 2}
            - withdraw: {rate_ml_min: 60, volume_ml: 20.8}
    analysis: {average_last: 2, compare_model: false}
    """
)


def test_a_characterised_segment_reproduces_the_specimen(tmp_path, monkeypatch):
    outcome = run_sim(tmp_path, PROTOCOL)
    assert outcome.result.status == "complete", outcome.result.reason
    library = tmp_path / "library"
    add_from_run(outcome.path, "MEASURED-B46", library)
    monkeypatch.setenv("LABRIG_LIBRARY", str(library))
    measured, truth = load_segment("MEASURED-B46"), analytical_segment("SI-B46-T20")
    # p(0) is extrapolated from the first bins, where the curve is steepest: the pump's
    # start, between two polls (and the previous repetition's log), is reconstructed
    # from its rate (analysis.curves.pump_path), else that bent or emptied the first
    # bins and shifted the curve by 1-3 kPa. Seen since: -0.42 to +0.47 kPa in 25 runs.
    assert measured.peak.p_kpa == pytest.approx(truth.peak.p_kpa, abs=1.0)
    drop_measured = measured.peak.p_kpa - measured.valley.p_kpa
    drop_truth = truth.peak.p_kpa - truth.valley.p_kpa
    assert drop_measured == pytest.approx(drop_truth, abs=0.5)
    assert measured.peak.v_ml == pytest.approx(truth.peak.v_ml, abs=0.4)
    assert measured.valley.v_ml == pytest.approx(truth.valley.v_ml, abs=0.5)
    assert float(measured.length_mm(10.0)) == pytest.approx(float(truth.length_mm(10.0)), abs=0.2)
