"""A specimen with no model: ``specimen.model: none`` makes its segments labels; a label
that looks like a model's name misspelt is warned about, a lab's own label is not, and a
name that names nothing in a specimen with a model says what was probably meant."""

import textwrap

import pytest
from hypothesis import given
from hypothesis import strategies as st

from labrig.config.protocol import parse_protocol
from labrig.config.segment_names import (
    label_warnings,
    name_warnings,
    suggestion,
    unknown_segment_hint,
)
from labrig.errors import InputError

NO_MODEL = textwrap.dedent(
    """\
    name: characterise LAB-S37
    specimen: {segments: [LAB-S37], model: none}
    rig: sim
    limits: {max_pressure_kpa: 95, max_volume_ml: 25}
    steps:
      - zero_pressure: {}
      - infuse: {rate_ml_min: 60, volume_ml: 18}
      - withdraw: {rate_ml_min: 60, volume_ml: 18}
    """
)


def test_model_none_makes_the_segments_labels():
    specimen = parse_protocol(NO_MODEL).specimen
    assert specimen.model == "none" and not specimen.has_model
    assert specimen.segments == ["LAB-S37"]


def test_the_default_model_is_built_from_the_segments():
    specimen = parse_protocol(NO_MODEL.replace(", model: none", "")).specimen
    assert specimen.model == "segments" and specimen.has_model


@pytest.mark.parametrize("spelling", ["null", "false", "None", "no", "'off'", "calibrated"])
def test_other_spellings_of_no_model_are_refused_with_what_is_allowed(spelling):
    """``model: null`` or ``false`` might be meant as none, or as the default: neither is
    guessed."""
    with pytest.raises(InputError) as error:
        parse_protocol(NO_MODEL.replace("model: none", f"model: {spelling}"), "p.yaml")
    message = str(error.value)
    assert message.startswith("p.yaml: line 2: specimen.model: ")
    assert "'segments' or 'none'" in message
    assert "\n" not in message


def test_a_comparison_asked_for_without_a_model_is_refused():
    text = NO_MODEL + "analysis: {compare_model: true}\n"
    with pytest.raises(InputError) as error:
        parse_protocol(text, "p.yaml")
    assert "analysis.compare_model: true asks for a comparison with the model, but " in str(
        error.value
    )
    assert "specimen.model: none says the specimen has none" in str(error.value)
    # left out or false, nothing contradicts
    parse_protocol(NO_MODEL + "analysis: {compare_model: false, average_last: 1}\n")
    parse_protocol(NO_MODEL + "analysis: {average_last: 1}\n")


@pytest.mark.parametrize(
    ("typed", "meant"),
    [
        ("B46-T2O", "B46-T20"),  # the letter O for zero
        ("b46-t2o", "B46-T20"),
        ("B46T20", "B46-T20"),
        ("B46_T20", "B46-T20"),
        ("calibrated:B46-T2O", "calibrated:B46-T20"),
        ("paper-r:B4O-T30", "paper-r:B40-T30"),
        ("SI-B46-T2O", "SI-B46-T20"),
        ("gent-A", "gent-a"),
    ],
)
def test_a_misspelt_model_name_gets_what_it_meant(typed, meant):
    assert suggestion(typed) == meant


@pytest.mark.parametrize("label", ["LAB-S37", "S37", "seg-3", "tube 2026-12-07 #4", "A1", "B-37"])
def test_a_labs_own_label_is_like_no_model_name(label):
    assert suggestion(label) is None
    assert label_warnings([label]) == []


@given(st.from_regex(r"(LAB|S|seg|lab)-?[0-9]{1,4}[a-z]?", fullmatch=True))
def test_no_numbered_lab_label_is_taken_for_a_misspelt_model_name(label):
    assert suggestion(label) is None


def test_labels_that_name_a_model_are_warned_about(tmp_path):
    (tmp_path / "MY-B46.csv").write_text("volume_ml,pressure_kpa,length_mm\n")
    warnings = label_warnings(
        ["B46-T20", "B46-T2O", "gent-b", "MY-B46", "data/s37.csv", "LAB-S37"], tmp_path
    )
    assert len(warnings) == 5
    assert warnings[0].startswith(
        "specimen.segments[0] 'B46-T20' is a library segment, but specimen.model: none makes "
        "it a label only"
    )
    assert warnings[1].startswith("specimen.segments[1] 'B46-T2O' looks like 'B46-T20' misspelt")
    assert "'gent-b' is a Gent membrane" in warnings[2]
    assert "'MY-B46' is a measured segment in the library" in warnings[3]
    assert "'data/s37.csv' is a CSV file" in warnings[4]


def test_measured_names_are_suggested_only_for_a_specimen_with_a_model(tmp_path):
    """One measured specimen's number from the next is no typo of a label (LAB-S38 after
    LAB-S37 was added); a name that must resolve is matched against them."""
    (tmp_path / "LAB-S37.csv").write_text("volume_ml,pressure_kpa,length_mm\n")
    assert label_warnings(["LAB-S38"], tmp_path) == []
    assert unknown_segment_hint("LAB-S38", tmp_path).startswith("did you mean 'LAB-S37'? ")
    assert unknown_segment_hint("LAB-X", tmp_path).startswith("a specimen nothing models yet")
    assert "specimen.model: none" in unknown_segment_hint("LAB-X", tmp_path)


def test_validation_warns_of_names_that_name_nothing(tmp_path):
    protocol = parse_protocol(NO_MODEL.replace("[LAB-S37], model: none", "[B46-T2O, B46-T20]"))
    [warning] = name_warnings(protocol.specimen, tmp_path)
    assert warning.startswith("specimen.segments[0] 'B46-T2O' names no segment here")
    assert "labrig run refuses it; did you mean 'B46-T20'?" in warning
    assert name_warnings(parse_protocol(NO_MODEL).specimen, tmp_path) == []
