"""A curve's PCHIP evaluated from its pieces with numpy (``PiecewisePolynomial``) gives
scipy's ``PPoly`` bits: values, slopes and the energy, at the samples, between them,
outside the table and for non-finite volumes; and a curve given its pieces is evaluated
without importing scipy's interpolation."""

import subprocess
import sys

import numpy as np
import pytest
from scipy.interpolate import PchipInterpolator

from labrig.model.segments.catalog import load_segment
from labrig.model.segments.curve import PiecewisePolynomial, SegmentCurve


def wavy_curve() -> SegmentCurve:
    """Uneven samples, a peak, a valley and a flat run: every kind of PCHIP piece."""
    v = np.cumsum(np.random.default_rng(7).uniform(0.05, 1.0, 60))
    v -= v[0]
    p = 30 * np.sin(v / 4) + 2 * v
    p[20:24] = p[20]
    return SegmentCurve("wavy", v, p, 40 + np.sqrt(v), V0_ml=3.0)


CURVES = {
    "wavy": wavy_curve,
    "B48-T30": lambda: load_segment("B48-T30"),
    "B50-T20": lambda: load_segment("B50-T20"),
}


def volumes(curve: SegmentCurve) -> np.ndarray:
    v = curve.v_ml
    inside = np.random.default_rng(3).uniform(v[0], v[-1], 5000)
    outside = [v[0] - 1.0, -1e-12, v[-1] + 1e-12, v[-1] + 2.0]
    edges = [np.nextafter(v[-1], -np.inf), np.nextafter(v[1], -np.inf)]
    return np.concatenate([v, 0.5 * (v[1:] + v[:-1]), inside, outside, edges, [np.nan, np.inf]])


@pytest.mark.parametrize("name", CURVES)
def test_values_slopes_and_energy_are_scipys_bits(name):
    curve = CURVES[name]()
    v = volumes(curve)
    for table in (curve.p_kpa, curve.l_mm):
        scipy_pchip = PchipInterpolator(curve.v_ml, table, extrapolate=False)
        ours = PiecewisePolynomial(scipy_pchip.x, scipy_pchip.c)
        pairs = (
            (ours, scipy_pchip),
            (ours.derivative(), scipy_pchip.derivative()),
            (ours.antiderivative(), scipy_pchip.antiderivative()),
        )
        for mine, theirs in pairs:
            assert np.array_equal(mine(v), theirs(v), equal_nan=True)
            assert np.array_equal(mine(v[7]), theirs(v[7]))  # one volume: a 0-d array


@pytest.mark.parametrize("name", CURVES)
def test_the_curve_reads_the_same_pieces_and_end_slopes_as_scipy(name):
    curve = CURVES[name]()
    pressure = PchipInterpolator(curve.v_ml, curve.p_kpa)
    assert np.array_equal(curve.pieces.p_coefficients, pressure.c)
    assert np.array_equal(curve.pieces.l_coefficients, PchipInterpolator(curve.v_ml, curve.l_mm).c)
    slope = pressure.derivative()
    assert curve.pieces.start_slope_kpa_per_ml == float(slope(curve.v_ml[0]))
    assert curve.pieces.end_slope_kpa_per_ml == float(slope(curve.v_max_ml))
    inside = volumes(curve)[: 2 * len(curve.v_ml) - 1]
    assert np.array_equal(curve.pressure_kpa(inside), pressure(inside))
    assert np.array_equal(curve.slope_kpa_per_ml(inside), slope(inside))
    assert np.array_equal(curve.energy_mj(inside), pressure.antiderivative()(inside))


SCRIPT = """
import sys
import numpy as np
from labrig.model.segments.curve import PchipPieces, SegmentCurve
stored = np.load(sys.argv[1])
slopes = float(stored["k0"]), float(stored["k1"])
pieces = PchipPieces(stored["x"], stored["p"], stored["l"], *slopes)
curve = SegmentCurve.with_pieces(
    pieces, name="wavy", v_ml=stored["v"], p_kpa=stored["pk"], l_mm=stored["lm"], V0_ml=3.0
)
v = np.linspace(-1.0, curve.v_max_ml + 1.0, 7)
values = [curve.pressure_kpa(v), curve.slope_kpa_per_ml(v), curve.energy_mj(v), curve.length_mm(v)]
values.append(curve.volumes_at_pressure(5.0)[0])
assert all(np.isfinite(x).any() for x in values)
print(",".join(sorted(m for m in sys.modules if m.startswith("scipy"))))
"""


def test_a_curve_given_its_pieces_never_imports_scipy(tmp_path):
    curve = wavy_curve()
    stored = tmp_path / "pieces.npz"
    pieces = curve.pieces
    np.savez(
        stored,
        x=pieces.x,
        p=pieces.p_coefficients,
        l=pieces.l_coefficients,
        k0=pieces.start_slope_kpa_per_ml,
        k1=pieces.end_slope_kpa_per_ml,
        v=curve.v_ml,
        pk=curve.p_kpa,
        lm=curve.l_mm,
    )
    done = subprocess.run(
        [sys.executable, "-c", SCRIPT, str(stored)], capture_output=True, text=True, check=True
    )
    assert done.stdout.strip() == ""
