"""The segment from the paper's numbers against independent computations: the
fixed-length branch's pressure as the derivative of the membrane energy, the straight
braids' force in the uniaxial limit, pressure continuity at both kinds of contact, the
energy after contact by quadrature of p dv, the peak by a second parametrisation (hoop
stretch, bisection) of the same membrane, and the bulge: the free tube's energy against
quadrature of p dv, Maxwell's equal areas by quadrature, and the bulged curve's plateau
and fill volume from the elastica envelope (tests/model/segments/test_elastica.py checks
the envelope itself, tests/model/segments/test_lobes.py the lobes past the fill)."""

import functools

import numpy as np
import pytest
from scipy.integrate import quad

from labrig.model.segments import elastica
from labrig.model.segments.braided import braid_force_n
from labrig.model.segments.ogden_braided import OgdenBraidedSegment
from labrig.model.segments.paper_braided import (
    BRAID_INNER_RADIUS_MM,
    TUBE_INNER_RADIUS_MM,
    TUBE_THICKNESS_MM,
    PaperBraidedSegment,
)

R, H, MU = TUBE_INNER_RADIUS_MM, TUBE_THICKNESS_MM, 0.49
GEOMETRIES = [(b, t) for b in range(40, 51, 2) for t in range(20, 31, 2)]


def membrane_energy_mj(seg, stretch_theta, stretch_z):
    """Neo-Hookean energy S14 of the thin wall, volume 2 pi R H L_tube."""
    invariant = stretch_theta**2 + stretch_z**2 + 1 / (stretch_theta * stretch_z) ** 2 - 3
    return 0.5 * MU * invariant * 2 * np.pi * R * H * seg.l_tube_mm


@pytest.fixture(scope="module")
def library():
    return {g: PaperBraidedSegment(*g) for g in GEOMETRIES}


def test_the_braid_tubing_fits_snugly_over_the_latex_tube():
    # read as diameters, the latex tube's outer radius is the braid tubing's inner one
    assert abs(R + H - BRAID_INNER_RADIUS_MM) < 0.01


def test_all_36_segments_build_and_rise_to_the_wall(library):
    for seg in library.values():
        curve = seg.curve()
        assert np.all(np.diff(curve.v_ml) > 0)
        assert curve.p_kpa[0] == 0 and curve.p_kpa[-1] == pytest.approx(300.0, rel=1e-6)


def test_short_braids_on_long_tubes_are_straight_at_rest(library):
    # F alone would stretch the tube past L_braid: the uniaxial neo-Hookean law
    # 2 pi R H mu (lambda - lambda^-2) = F, solved independently on a fine grid
    for (braid, tube), seg in library.items():
        grid = np.linspace(1.0, 3.0, 200001)
        force = 2 * np.pi * R * H * MU * (grid - grid**-2)
        stretch = grid[np.argmin(np.abs(force - braid_force_n(braid)))]
        if abs(stretch * tube - braid) > 0.01:
            assert seg.straight_at_rest == (stretch * tube > braid)
    assert sum(s.straight_at_rest for s in library.values()) == 6


def test_fixed_length_pressure_is_the_derivative_of_the_membrane_energy(library):
    seg = library[(40, 30)]
    lz = seg.cap_stretch
    for hoop in [0.9, 1.0, 1.1]:
        step = 1e-6
        dw = membrane_energy_mj(seg, hoop + step, lz) - membrane_energy_mj(seg, hoop - step, lz)
        dv = np.pi * R**2 * seg.l_braid_mm * ((hoop + step) ** 2 - (hoop - step) ** 2)
        assert seg.capped_state(hoop)[1] == pytest.approx(dw / dv * 1000, rel=1e-6)


def test_straight_braids_carry_the_tubes_tension_and_never_more_than_f(library):
    seg = library[(40, 30)]
    lz = seg.cap_stretch
    uniaxial = 2 * np.pi * R * H * MU * (lz - lz**-2)
    assert seg.braid_compression_n(lz**-0.5) == pytest.approx(uniaxial, rel=1e-12)
    for straight in (s for s in library.values() if s.meets_straight_braids):
        hoops = np.linspace(straight.capped_start_hoop, straight.contact_hoop, 50)
        assert np.all(straight.braid_compression_n(hoops) <= straight.axial_force_n * (1 + 1e-9))
        if not straight.straight_at_rest:  # the free branch ends in equilibrium with F
            start = straight.braid_compression_n(straight.capped_start_hoop)
            assert start == pytest.approx(straight.axial_force_n, rel=1e-6)


def test_pressure_is_continuous_at_both_kinds_of_contact(library):
    kinds = set()
    for seg in library.values():
        before = (
            seg.capped_state(seg.contact_hoop)
            if seg.meets_straight_braids
            else seg.tube_state(seg.free_end_stretch)
        )
        after = seg.contact_state(seg.contact_angle)
        assert after[0] == pytest.approx(before[0], abs=1e-6)
        # straight braids: the contact branch starts at 1e-4 rad, where the braids' own
        # energy already moves p by F L sin(theta) / (dV/dtheta), a few 1e-3 kPa
        assert after[1] == pytest.approx(before[1], abs=5e-3)
        kinds.add(seg.meets_straight_braids)
    assert kinds == {True, False}


def energy_after_contact_mj(seg, theta):
    """Membrane plus braid energy of the state at braid angle theta, from (v, l) alone."""
    v_ml, _, l_mm = seg.contact_state(theta)
    stretch_z = l_mm / seg.l_tube_mm
    hoop = np.sqrt((v_ml + seg.V0_ml) * 1000 / (np.pi * R**2 * l_mm))
    braids = seg.axial_force_n * (seg.l_braid_mm - l_mm)
    return membrane_energy_mj(seg, hoop, stretch_z) + braids


def pressure_times_volume_slope(seg, theta, step=1e-7):
    """p dv/dtheta after contact (the volume's slope by central differences)."""
    dv = seg.contact_state(theta + step)[0] - seg.contact_state(theta - step)[0]
    return seg.contact_state(theta)[1] * dv / (2 * step)  # kPa mL = mJ


@pytest.mark.parametrize("geometry", [(50, 20), (40, 30)])
def test_energy_after_contact_is_the_integral_of_p_dv(library, geometry):
    seg = library[geometry]
    th0, th1 = seg.contact_angle, 0.5 * (seg.contact_angle + seg.end_angle)
    work, _ = quad(lambda th: pressure_times_volume_slope(seg, th), th0, th1, limit=200)
    expected = energy_after_contact_mj(seg, th1) - energy_after_contact_mj(seg, th0)
    assert work == pytest.approx(expected, rel=1e-5)


@functools.cache
def _hoop_peak_kpa(braid: int) -> float:
    """The same neo-Hookean tube parametrised by its hoop stretch (axial equilibrium by
    bisection): its pressure maximum before contact. It depends on L_braid alone (the
    tube's length is fixed at 20 mm here), so each braid's is computed once."""
    other = OgdenBraidedSegment(braid, 20, radius_mm=R, thickness_mm=H, ogden_alpha=2.0)
    hoops = other.hoop_stretch0 * np.linspace(1.0, 2.5, 150001)
    return other.hoop_state(hoops)[1].max()


def test_peak_by_a_second_parametrisation(library):
    for (braid, _), seg in library.items():
        if seg.peak_stretch is None:
            continue
        assert seg.curve().peak.p_kpa == pytest.approx(_hoop_peak_kpa(braid), rel=1e-6)


def test_peaks_rise_with_l_braid_and_do_not_depend_on_l_tube(library):
    peaks = {g: s.curve().peak for g, s in library.items()}
    by_braid = {}
    for (braid, _), peak in peaks.items():
        if peak is not None:
            by_braid.setdefault(braid, set()).add(round(peak.p_kpa, 6))
    assert all(len(values) == 1 for values in by_braid.values())
    ordered = [next(iter(by_braid[b])) for b in sorted(by_braid)]
    assert np.all(np.diff(ordered) > 0)


def work_p_dv_mj(seg, lo, hi, pressure_offset_kpa=0.0):
    """int (p - offset) dv along the free tube's uniform branch, by quadrature in the
    axial stretch (dv/dlambda_z by central differences)."""

    def integrand(lz, h=1e-7):
        dv = (seg.tube_state(lz + h)[0] - seg.tube_state(lz - h)[0]) / (2 * h)
        return (seg.tube_state(lz)[1] - pressure_offset_kpa) * dv

    return quad(integrand, lo, hi, limit=400, epsabs=1e-8)[0]


@pytest.mark.parametrize("geometry", [(46, 20), (40, 22)])
def test_free_tube_energy_is_the_work_of_the_pressure(library, geometry):
    seg = library[geometry]
    lo, hi = seg.lambda_z0, seg.bulge.bulged_stretch
    expected = seg.free_energy_mj(hi) - seg.free_energy_mj(lo)
    assert work_p_dv_mj(seg, lo, hi) == pytest.approx(expected, rel=1e-7)


@pytest.mark.parametrize("geometry", [(46, 20), (50, 26), (40, 22)])
def test_maxwell_plateau_has_equal_areas_by_quadrature(library, geometry):
    seg = library[geometry]
    bulge = seg.bulge
    thin, bulged, p_m = bulge.thin_stretch, bulge.bulged_stretch, bulge.plateau_kpa
    assert seg.tube_state(thin)[1] == pytest.approx(p_m, rel=1e-9)
    above = work_p_dv_mj(seg, thin, seg.peak_stretch, p_m)  # the rising branch's lobe
    net = work_p_dv_mj(seg, thin, bulged, p_m)
    assert abs(net) < 1e-6 * above
    # the bulged phase's outer surface is at the strips' widest, at the peak's length
    widest = elastica.widest_radius_mm(seg.peak_stretch * seg.l_tube_mm, seg.l_braid_mm, 3.97)
    lt = np.sqrt(
        (seg.tube_state(bulged)[0] + seg.V0_ml) * 1000 / (np.pi * R**2 * seg.l_tube_mm * bulged)
    )
    assert lt * R + H / (lt * bulged) == pytest.approx(widest, rel=1e-9)


def test_bulged_curve_falls_to_the_plateau_and_fills_the_envelope(library):
    bulged = [s for s in library.values() if s.bulge is not None]
    assert len(bulged) == 23
    for seg in bulged:
        curve, bulge = seg.curve(), seg.bulge
        assert curve.peak.p_kpa > bulge.plateau_kpa > curve.valley.p_kpa - 1.0 - 1e-9
        # the tube fills the elastica at the peak's length (or its largest volume)
        length = max(seg.peak_stretch * seg.l_tube_mm, seg.l_braid_mm * np.cos(seg.wall_angle))
        inner = elastica.envelope_volume_mm3(length, seg.l_braid_mm, 3.97) - seg.wall_volume_mm3
        assert bulge.fill_ml == pytest.approx(inner / 1000 - seg.V0_ml, rel=1e-9)
        # the plateau ends where the lobes between the strips hold its pressure: near the
        # fill (gap membranes flatter than the filled envelope's circle below it)
        start_v, start_p = (float(x[0]) for x in seg.lobes.table[:2])
        assert curve.valley.v_ml == pytest.approx(start_v, abs=1e-12)
        assert curve.valley.p_kpa == pytest.approx(start_p, abs=1e-9)
        assert abs(start_v - bulge.fill_ml) < 0.5
        plateau = (curve.v_ml > curve.valley.v_ml - 1e-9) & (curve.v_ml < start_v - 0.005)
        assert np.all(np.abs(curve.p_kpa[plateau] - curve.valley.p_kpa) < 1e-9)


def test_lobes_start_at_first_contact_without_a_bulge(library):
    # where the uniform tube meets the strips the lobes take over at its pressure and
    # (the gaps still almost closed) at its volume
    plain = [s for s in library.values() if s.bulge is None]
    assert len(plain) == 13
    for seg in plain:
        before = (
            seg.capped_state(seg.contact_hoop)
            if seg.meets_straight_braids
            else seg.tube_state(seg.free_end_stretch)
        )
        v, p, _ = seg.lobes.table
        # on straight braids the gap is 2 pi/8 - w/r with r a few 1e-9 above w's radius:
        # rounding leaves the start's pressure good to about 1e-6
        assert p[0] == pytest.approx(float(before[1]), rel=1e-5)
        assert v[0] == pytest.approx(float(before[0]), abs=1e-3)
        assert np.all(np.diff(p) > 0)  # rising to 300 kPa, no second peak
