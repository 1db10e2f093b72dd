"""The ``paper-r:`` library (docs/decisions/0009): record 0008's segment with the braid
tubing's "inner radius of 7.94 mm" read as printed. Checked against independent
computations: the strips' width and the gap the latex tube leaves from the tubing's
circumference and the tube's own sizes, the fill from the elastica's envelope at 7.94
mm (tests/model/segments/test_elastica.py checks that envelope by integrating the
elastica), and the invariants the reading must not touch (the peak comes before any
contact; ``paper:`` keeps 3.97 mm)."""

import numpy as np
import pytest

from labrig.model.segments import elastica
from labrig.model.segments.catalog import analytical_segment, library_segment
from labrig.model.segments.paper_braided import (
    BRAID_INNER_RADIUS_AS_PRINTED_MM,
    TUBE_INNER_RADIUS_MM,
    TUBE_THICKNESS_MM,
)


@pytest.fixture(scope="module")
def pair():
    return library_segment("paper:B46-T20"), library_segment("paper-r:B46-T20")


def test_the_two_readings_differ_only_in_the_braid_tubing(pair):
    diameters, radius = pair
    assert diameters.end_radius_mm == 3.97 and radius.end_radius_mm == 7.94
    for name in ("radius_mm", "thickness_mm", "shear_modulus_mpa", "axial_force_n"):
        assert getattr(radius, name) == getattr(diameters, name)
    assert analytical_segment("paper-r:b46-t20").name == "paper-r:B46-T20"


def test_strips_twice_as_wide_and_a_tube_that_does_not_fit_snugly(pair):
    _, radius = pair
    # eight strips close the 15.9 mm bore: 2 pi 7.94/8 wide, calipers read the chord
    assert radius.lobes.width_mm == pytest.approx(np.pi * 15.88 / 8, rel=1e-12)
    assert 2 * 7.94 * np.sin(np.pi / 8) == pytest.approx(6.08, abs=0.005)
    # the latex tube's outer radius (1/4" bore, 1/32" wall) leaves ~3.97 mm all round
    outer = TUBE_INNER_RADIUS_MM + TUBE_THICKNESS_MM
    assert BRAID_INNER_RADIUS_AS_PRINTED_MM - outer == pytest.approx(3.975, abs=1e-9)


def test_the_peak_comes_before_contact_and_the_fill_is_the_wider_envelope(pair):
    diameters, radius = pair
    assert radius.curve().peak.p_kpa == pytest.approx(diameters.curve().peak.p_kpa, rel=1e-12)
    # the tube fills the 7.94 mm elastica at the peak's length: its volume less the wall
    length = radius.peak_stretch * radius.l_tube_mm
    envelope = elastica.envelope_volume_mm3(length, 46.0, 7.94)
    inner_ml = (envelope - radius.wall_volume_mm3) / 1000
    assert radius.bulge.fill_ml == pytest.approx(inner_ml - radius.V0_ml, rel=1e-9)
    assert radius.bulge.fill_ml > diameters.bulge.fill_ml + 5
