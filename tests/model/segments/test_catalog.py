"""The segment library: names, caching, and one entry point for names and files."""

import numpy as np
import pytest

from labrig.errors import InputError
from labrig.model.segments.braided import BraidedSegment
from labrig.model.segments.calibrated import calibrated_curve
from labrig.model.segments.catalog import (
    DEFAULT_LIBRARY,
    LIBRARIES,
    LIBRARY_NAMES,
    SI_NAMES,
    analytical_segment,
    library_names,
    load_segment,
    parse_library_name,
)
from labrig.model.segments.measured import write_csv
from labrig.model.segments.paper_braided import PaperBraidedSegment


def test_the_36_names_of_the_paper():
    assert len(LIBRARY_NAMES) == 36 == len(set(LIBRARY_NAMES))
    assert LIBRARY_NAMES[0] == "B40-T20" and LIBRARY_NAMES[-1] == "B50-T30"
    assert "B46-T22" in LIBRARY_NAMES and "B47-T20" not in LIBRARY_NAMES
    assert tuple("SI-" + name for name in LIBRARY_NAMES) == SI_NAMES


def test_a_name_is_its_geometry_and_its_library_and_is_built_once():
    curve = analytical_segment("calibrated:B46-T20")
    assert curve is analytical_segment("Calibrated:b46-t20")
    assert curve.name == "calibrated:B46-T20"
    np.testing.assert_array_equal(curve.p_kpa, calibrated_curve(46, 20, "B46-T20").p_kpa)
    paper = analytical_segment("paper:b46-t20")
    np.testing.assert_array_equal(paper.p_kpa, PaperBraidedSegment(46, 20).curve().p_kpa)
    bare = analytical_segment("b46-t20")
    assert bare is analytical_segment("B46-T20") and bare.name == "B46-T20"
    default = analytical_segment(f"{DEFAULT_LIBRARY}:B46-T20")
    np.testing.assert_array_equal(bare.p_kpa, default.p_kpa)
    assert (
        analytical_segment("si:B46-T20").p_kpa.tolist()
        == analytical_segment("SI-B46-T20").p_kpa.tolist()
    )
    si = analytical_segment("si-b46-t20")
    assert si.name == "SI-B46-T20" and si is analytical_segment("SI-B46-T20")
    np.testing.assert_array_equal(si.p_kpa, BraidedSegment(46, 20).curve().p_kpa)


@pytest.mark.parametrize(
    ("names", "without_peak"),
    [
        (library_names("calibrated"), []),
        (SI_NAMES, ["SI-B40-T28", "SI-B40-T30", "SI-B42-T30"]),
        (
            library_names("paper"),
            [  # contact (or straight braids) before any peak, as measured
                f"paper:{name}"
                for name in [
                    "B40-T24",
                    "B40-T26",
                    "B40-T28",
                    "B40-T30",
                    "B42-T26",
                    "B42-T28",
                    "B42-T30",
                    "B44-T26",
                    "B44-T28",
                    "B44-T30",
                    "B46-T28",
                    "B46-T30",
                    "B48-T30",
                ]
            ],
        ),
    ],
)
def test_every_library_segment_is_a_usable_curve(names, without_peak):
    no_peak = []
    for name in names:
        curve = analytical_segment(name)
        assert curve.v_ml[0] == 0 and curve.p_kpa[0] == 0 and np.all(curve.p_kpa[1:] > 0)
        assert curve.p_kpa[-1] == pytest.approx(300)
        assert len(curve.branch_bounds) in (1, 3)
        if curve.peak is None:
            no_peak.append(name)
    assert no_peak == without_peak


@pytest.mark.parametrize("spec", ["B47-T20", "B46", "foo", "B46-T20x"])
def test_unknown_names_list_the_valid_ones_compactly(spec):
    with pytest.raises(InputError) as info:
        load_segment(spec)
    message = str(info.value)
    assert repr(spec) in message and "B40..B50 x T20..T30 in steps of 2, e.g. B46-T20" in message
    assert "paper:B46-T20" in message
    # the six prefixes once each, never the 36 names of each library (over 2,000 characters)
    assert all(f"{library}:" in message for library in LIBRARIES)
    assert len(message) < 330


def test_load_segment_takes_names_gent_membranes_and_csv_paths(tmp_path):
    assert load_segment("B46-T22") is analytical_segment("B46-T22")
    assert load_segment("gent-c").name == "gent-c"
    write_csv(analytical_segment("B48-T26"), tmp_path / "mine.csv")
    curve = load_segment(str(tmp_path / "mine.csv"))
    assert curve.name == "mine"
    np.testing.assert_array_equal(curve.p_kpa, analytical_segment("B48-T26").p_kpa)
    with pytest.raises(InputError, match="no such file"):
        load_segment(str(tmp_path / "missing.csv"))


def test_library_prefixes_and_the_legacy_si_names_parse():
    assert parse_library_name("paper:B46-T20") == ("paper", 46, 20)
    assert parse_library_name("SI-B46-T20") == ("si", 46, 20)
    assert parse_library_name("b50-t30") == (DEFAULT_LIBRARY, 50, 30)
    assert parse_library_name("other:B46-T20") is None
    assert parse_library_name("paper:B47-T20") is None
    assert parse_library_name("Paper-R:b46-t20") == ("paper-r", 46, 20)
    assert parse_library_name("paper-x:B46-T20") is None
    assert set(LIBRARIES) == {"paper", "paper-r", "paper-gent", "paper-clamped", "calibrated", "si"}
    assert parse_library_name("Paper-Gent:b46-t20") == ("paper-gent", 46, 20)
    assert parse_library_name("paper-clamped:B48-T30") == ("paper-clamped", 48, 30)
    assert library_names("si")[0] == "si:B40-T20" and library_names() == LIBRARY_NAMES
