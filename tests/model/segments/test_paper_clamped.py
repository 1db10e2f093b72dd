"""The segment clamped at its couplings (docs/decisions/0014) against independent
computations (tests/model/segments/test_no_peak.py checks the clamped tube itself, held
at a length too): the curve's work int p dv against the clamped membrane's energy less F times its
lengthening, the rest volume between the bounds its shape allows, and a long tube's peak
against the free uniform tube's (the clamp's boundary layers matter less the longer the
tube). The join at contact adds no pressure maximum."""

import numpy as np
import pytest

from labrig.model.segments.catalog import load_segment
from labrig.model.segments.paper_clamped import ClampedPaperSegment

MM3_PER_ML = 1000.0


@pytest.fixture(scope="module")
def bulging():
    return ClampedPaperSegment(46, 20)


def test_the_curves_work_before_the_peak_is_the_membranes_energy_less_the_braids(bulging):
    """int p dv along the curve's rising tables (trapezoids on its states) against
    W(peak) - W(rest) - F (l(peak) - l(rest)) of the clamped membrane."""
    curve = bulging.curve()
    branch = bulging.branch
    rest, peak = branch.states[0], branch.peak
    count = len(branch.states)
    work_mj = np.trapezoid(curve.p_kpa[:count], curve.v_ml[:count])
    energy_mj = peak.energy_mj - rest.energy_mj - bulging.axial_force_n * (peak.l_mm - rest.l_mm)
    assert work_mj == pytest.approx(energy_mj, rel=2e-3)
    assert curve.p_kpa[count - 1] == pytest.approx(peak.p_kpa)


def test_the_rest_volume_lies_between_the_shapes_bounds(bulging):
    """Every section's radius lies between the middle's and R: pi (h R)^2 l <= V0 <= pi R^2 l."""
    rest = bulging.branch.states[0]
    r = bulging.radius_mm
    low = np.pi * (rest.mid_hoop * r) ** 2 * rest.l_mm / MM3_PER_ML
    high = np.pi * r**2 * rest.l_mm / MM3_PER_ML
    assert low < bulging.curve().V0_ml < high
    assert rest.p_kpa == pytest.approx(0.0, abs=1e-4)


def test_a_long_tubes_peak_is_the_free_tubes():
    """The boundary layers are a few millimetres long: the clamped peak tends to the free
    uniform tube's as L_tube grows (braids long enough not to be met, the force given)."""
    force_n = ClampedPaperSegment(46, 20).axial_force_n
    gaps = {}
    for l_tube in (20.0, 100.0):
        seg = ClampedPaperSegment(400.0, l_tube, force_n=force_n)
        free = seg.free_peak_stretch
        free_kpa = float(seg.tube_state(free)[1])
        peak = seg.branch.peak
        gaps[l_tube] = peak.p_kpa - free_kpa
        assert peak.l_mm / l_tube == pytest.approx(free, rel=0.05)
    assert 0 < gaps[100.0] < gaps[20.0] / 3


def test_straight_braids_hold_with_at_most_f_and_the_contact_adds_no_maximum():
    seg = ClampedPaperSegment(40, 30)  # the braids' force stretches it past 40 mm at rest
    states = seg.branch.states
    assert seg.branch.peak is None
    assert all(s.l_mm == pytest.approx(40.0) for s in states)
    assert all(0 < s.force_n <= seg.axial_force_n for s in states)
    for name in ("paper-clamped:B40-T30", "paper-clamped:B44-T28"):
        curve = load_segment(name)
        below = curve.p_kpa <= 100.0
        assert np.all(np.diff(curve.p_kpa[below]) > 0), name


def test_the_clamp_gives_movie_s4s_segment_a_peak_that_the_free_tube_lacks():
    assert (
        load_segment("paper:B48-T30").p_kpa.argmax() == len(load_segment("paper:B48-T30").p_kpa) - 1
    )
    seg = ClampedPaperSegment(48, 30)
    assert seg.branch.peak is not None and seg.bulge is not None
    p_kpa = seg.curve().p_kpa
    top = int(np.argmax(p_kpa > seg.branch.peak.p_kpa - 1e-9))
    assert np.all(np.diff(p_kpa[: top + 1]) > 0) and p_kpa[top + 1] < p_kpa[top]
