"""Energy on both sides of the comparison: the demo pair's cycle, measured and model."""

import shutil

import h5py
import pytest

import labrig
from labrig.analysis.compare import PredictedTransition


def test_the_models_energies_agree_with_its_own_curve(quick_run):
    """Two computations of the model's energy: the segments' stored energy at each
    snap (the solver's) and the trapezoid ∫ p dv along its sampled path (the cycle's),
    and the loop's area against the releases of its snaps (energy conservation)."""
    document = labrig.open_run(quick_run).comparison_document
    energy = document["energy"]
    assert energy["released_model_mj"] == pytest.approx(
        energy["released_by_snaps_model_mj"], rel=1e-3
    )
    snaps = [t for t in document["paper_transitions"] if t["type"] == "snap"]
    first = next(t for t in snaps if t["phase"] == "inflate")
    assert first["cycle_energy_before_model_mj"] == pytest.approx(
        first["energy_before_model_mj"], rel=1e-3
    )
    for t in snaps:
        expected = (t["energy_after_model_mj"] - t["energy_before_model_mj"]) / t[
            "energy_before_model_mj"
        ]
        assert t["dE_model"] == pytest.approx(expected, rel=1e-9)
        assert t["dE_model"] < 0  # a snap releases energy


def test_the_measured_cycle_beside_the_models(quick_run):
    """The simulated specimen is the model's pair plus noise: the measured loop and the
    inflation snap's cycle dE come within a few percent of the model's."""
    run = labrig.open_run(quick_run)
    energy = run.comparison_document["energy"]
    assert energy["released_measured_mj"] == pytest.approx(energy["released_model_mj"], rel=0.05)
    assert energy["stored_measured_mj"] == pytest.approx(energy["stored_model_mj"], rel=0.05)
    table = run.paper_comparison
    snap = table[(table["type"] == "snap") & (table["phase"] == "inflate")].iloc[0]
    assert snap["cycle_dE_measured"] == pytest.approx(snap["cycle_dE_model"], abs=0.03)
    assert snap["cycle_dE_model"] <= snap["dE_model"] < 0  # the loop holds both snaps


def test_a_file_analysed_before_energies_were_kept_still_reads(quick_run, tmp_path):
    """Its model transitions have no energies: they read as NaN, the rest as stored."""
    old = tmp_path / "old.h5"
    shutil.copy(quick_run, old)
    with h5py.File(old, "r+") as h5:
        table = h5["entry/analysis/model/transitions"]
        for name in ("energy_before_mj", "energy_after_mj"):
            del table[name]
    transitions = labrig.open_run(old).analysis.comparison.prediction.transitions
    assert transitions and all(isinstance(t, PredictedTransition) for t in transitions)
    assert all(t.energy_before_mj != t.energy_before_mj for t in transitions)  # NaN
    document = labrig.open_run(old).comparison_document
    assert all(t["energy_before_model_mj"] is None for t in document["transitions"])
