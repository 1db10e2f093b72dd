"""Decision record 0013's rule for the paper-numbers segments without a pressure peak,
against an independent computation: a segment peaks exactly where the free tube under
the braids' force F reaches its own peak before the length at which it meets the strips
(once the strips are straight the tube is held at a fixed length, with no pressure
maximum). The free tube's peak is found here in the hoop stretch from the membrane's two
equilibrium equations (S16, S33 with plane-stress neo-Hookean stresses), not from the
S37/S38 root the segment uses. The tube with its ends held at their radius
(``clamped_tube``) against the same uniform membrane far from its ends, and against the
virtual work of its own energy, free and held at a length by straight braids (there
against S23 at the middle's own axial stretch)."""

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.optimize import brentq, minimize_scalar

from labrig.model.segments.catalog import library_names, library_segment
from labrig.model.segments.clamped_tube import ClampedTube
from labrig.model.segments.paper_braided import capped_pressure_ratio


def axial_stretch(seg, hoop: float) -> float:
    """lambda_z of the free tube under F at hoop stretch ``hoop``: the axial equilibrium
    sigma_z - sigma_theta/2 = F/(2 pi r h) (S33 with S16), F/(2 pi r h) = F lambda_z/(2 pi R H)."""
    force = seg.axial_force_n / (2 * np.pi * seg.radius_mm * seg.thickness_mm)

    def balance(lz):
        radial_sq = 1 / (hoop * lz) ** 2
        sigma_theta = seg.shear_modulus_mpa * (hoop**2 - radial_sq)
        sigma_z = seg.shear_modulus_mpa * (lz**2 - radial_sq)
        return sigma_z - 0.5 * sigma_theta - force * lz

    return brentq(balance, 0.5, 20.0, xtol=1e-14)


def pressure_mpa(seg, hoop: float) -> float:
    """p = sigma_theta h / r (S16) on the free tube's branch."""
    lz = axial_stretch(seg, hoop)
    radial = 1 / (hoop * lz)
    sigma_theta = seg.shear_modulus_mpa * (hoop**2 - radial**2)
    return sigma_theta * seg.thickness_mm * radial / (hoop * seg.radius_mm)


def free_peak_stretch(seg) -> float:
    """lambda_z at the free tube's pressure peak, maximised over the hoop stretch."""
    found = minimize_scalar(
        lambda hoop: -pressure_mpa(seg, hoop), bounds=(1.0, 3.0), method="bounded"
    )
    assert 1.01 < found.x < 2.99  # an interior maximum
    return axial_stretch(seg, float(found.x))


@pytest.fixture(scope="module")
def segments():
    return [library_segment(name) for name in library_names("paper")]


def test_a_segment_peaks_exactly_where_its_free_peak_comes_before_the_strips(segments):
    peaks = []
    for seg in segments:
        before_strips = free_peak_stretch(seg) < seg.free_end_stretch
        assert (seg.peak_stretch is not None) == before_strips, seg
        peaks.append(before_strips)
    assert any(peaks) and not all(peaks)  # both kinds occur: the rule separates something


def test_a_tube_held_at_a_fixed_length_has_no_pressure_maximum():
    hoops = np.linspace(1.0, 6.0, 2001)
    for stretch_z in (1.0, 1.5, 2.5):
        assert np.all(np.diff(capped_pressure_ratio(hoops, stretch_z)) > 0)


def _tube(l_tube_mm: float, l_braid_mm: float = 40.0) -> ClampedTube:
    seg = library_segment(f"paper:B{l_braid_mm:g}-T20")
    return ClampedTube(
        SimpleNamespace(
            radius_mm=seg.radius_mm,
            thickness_mm=seg.thickness_mm,
            shear_modulus_mpa=seg.shear_modulus_mpa,
            axial_force_n=seg.axial_force_n,
            l_tube_mm=l_tube_mm,
        )
    )


def test_far_from_its_clamped_ends_the_tube_is_the_uniform_membrane():
    tube = _tube(150.0)  # the ends' zones are a few radii long: its middle is far from them
    seg = library_segment("paper:B40-T20")
    solution = None
    for hoop in np.linspace(0.8, 1.3, 6):
        solution = tube.solve(hoop, solution)
        assert solution.p[0] == pytest.approx(pressure_mpa(seg, hoop), rel=1e-6)


def test_the_clamped_tubes_pressure_is_the_virtual_work_of_its_energy():
    """dW = p dv + F dl along the branch (F pushes the ends apart), by central differences
    of the membrane's energy, volume and length between neighbouring states."""
    tube = _tube(24.0)
    force = tube.segment.axial_force_n
    for middle in (1.2, 1.5):  # before and near the peak
        before, here, after = tube.branch([middle - 0.005, middle, middle + 0.005])
        work = after.energy_mj - before.energy_mj - force * (after.l_mm - before.l_mm)
        dv_ml = (after.volume_mm3 - before.volume_mm3) / 1000
        assert work / dv_ml == pytest.approx(here.p_kpa, rel=1e-4)


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
    dv_ml = (after.volume_mm3 - before.volume_mm3) / 1000  # mm^3 to mL
    assert (after.energy_mj - before.energy_mj) / dv_ml == pytest.approx(here.p_kpa, rel=1e-4)
