"""The segment clamped at its couplings (docs/decisions/0014) against independent
computations: the tube held at a fixed length far from its ends against S23 at that
axial stretch, its pressure against the virtual work of its own energy at fixed length,
the curve's work int p dv against the clamped membrane's energy less F times its
lengthening, the rest volume between the bounds its shape allows, and a long tube's peak
against the free uniform tube's (the clamp's boundary layers matter less the longer the
tube). The join at contact adds no pressure maximum."""

from types import SimpleNamespace

import numpy as np
import pytest

from labrig.model.segments.catalog import load_segment
from labrig.model.segments.clamped_tube import ClampedTube
from labrig.model.segments.paper_braided import capped_pressure_ratio
from labrig.model.segments.paper_clamped import ClampedPaperSegment

MM3_PER_ML = 1000.0


def _tube(l_tube_mm: float) -> ClampedTube:
    seg = ClampedPaperSegment(46, 20)
    return ClampedTube(
        SimpleNamespace(
            radius_mm=seg.radius_mm,
            thickness_mm=seg.thickness_mm,
            shear_modulus_mpa=seg.shear_modulus_mpa,
            axial_force_n=seg.axial_force_n,
            l_tube_mm=l_tube_mm,
        )
    )


def test_held_at_a_length_far_from_its_ends_the_tube_is_s23_at_that_stretch():
    tube = _tube(150.0)
    stretch_z = 1.4
    seg = tube.segment
    scale_mpa = seg.shear_modulus_mpa * seg.thickness_mm / seg.radius_mm
    solution = None
    for hoop in (0.9, 1.1, 1.3):  # below the free peak, where its end zones stay short
        solution = tube.solve(hoop, solution, length_mm=stretch_z * 150.0)
        # the middle of a long tube is uniform: S23 at the length the ends impose there
        middle = tube.state(solution)
        assert middle.l_mm == pytest.approx(stretch_z * 150.0, rel=1e-9)
        # dz/dX at the middle, where phi = 0: the meridian's stretch, the local lambda_z
        local_z = float(solution.yp[1][0])
        expected = capped_pressure_ratio(hoop, local_z) * scale_mpa
        assert solution.p[0] == pytest.approx(expected, rel=1e-6)


def test_held_at_a_length_the_pressure_is_the_virtual_work_of_the_energy():
    """dW = p dv at a fixed length, by central differences between neighbouring states."""
    tube = _tube(26.0)
    solution = None
    states = []
    for hoop in (1.195, 1.2, 1.205):
        solution = tube.solve(hoop, solution, length_mm=40.0)
        states.append(tube.state(solution))
    before, here, after = states
    dv_ml = (after.volume_mm3 - before.volume_mm3) / MM3_PER_ML
    assert (after.energy_mj - before.energy_mj) / dv_ml == pytest.approx(here.p_kpa, rel=1e-4)


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
