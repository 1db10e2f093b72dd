"""Equilibria and stability of an actuator: the stability criterion against the explicit
Hessian's eigenvalues and the paper's Sylvester minors (Eq. 10), the equilibrium grid
against closed-form roots of the segments' cubics."""

import itertools

import numpy as np
import pytest
from support.actuator_curves import cubic_pressure, cubic_segment, random_cubic

from labrig.model.actuator.equilibria import Actuator, hessian, is_stable, stable_scalar
from labrig.model.actuator.kernel import CurveKernel


def explicit_hessian(k):
    """Eq. 9 written out entry by entry (independent of ``hessian``)."""
    n = len(k)
    h = np.empty((n - 1, n - 1))
    for i in range(n - 1):
        for j in range(n - 1):
            h[i, j] = k[i] + k[-1] if i == j else k[-1]
    return h


def sylvester_eq10(k):
    """The paper's Eq. 10: every leading minor of the Hessian positive."""
    n = len(k)
    for m in range(1, n):
        head = k[:m]
        product = np.prod(head)
        cross = sum(np.prod(np.delete(head, i)) for i in range(m))
        if not product + k[-1] * cross > 0:
            return False
    return True


def random_slopes(rng, n, count):
    """Slopes with every sign pattern, magnitudes over four decades, some exact zeros."""
    k = rng.choice([-1.0, 1.0], size=(count, n)) * 10.0 ** rng.uniform(-2, 2, size=(count, n))
    k[rng.random((count, n)) < 0.05] = 0.0
    return k


@pytest.mark.parametrize("n", [2, 3, 4, 5])
def test_stability_matches_the_eigenvalues_of_the_hessian(n):
    rng = np.random.default_rng(n)
    k = random_slopes(rng, n, 4000)
    smallest = np.array([np.linalg.eigvalsh(explicit_hessian(row)).min() for row in k])
    decided = np.abs(smallest) > 1e-9  # exactly singular Hessians are neither
    assert decided.mean() > 0.9
    expected = smallest > 0
    np.testing.assert_array_equal(is_stable(k)[decided], expected[decided])
    assert [stable_scalar(row) for row in k] == is_stable(k).tolist()
    np.testing.assert_allclose(hessian(k[0]), explicit_hessian(k[0]))


@pytest.mark.parametrize("n", [2, 3, 4])
def test_stability_matches_the_papers_sylvester_minors(n):
    rng = np.random.default_rng(10 + n)
    k = random_slopes(rng, n, 3000)
    k = k[np.all(k != 0, axis=1)]  # Eq. 10's minors are silent on the degenerate cases
    # Sylvester's criterion holds in any order of the segments, Eq. 10 is one order
    assert [sylvester_eq10(row) for row in k] == is_stable(k).tolist()


def test_the_known_special_cases():
    # two segments: H = k1 + k2 (paper SI S12)
    assert is_stable([[3.0, -2.0]])[0] and not is_stable([[2.0, -3.0]])[0]
    # one segment exactly at its peak among rising ones: stable
    assert is_stable([[0.0, 1.0, 2.0]])[0]
    # two segments past their peaks: never
    assert not is_stable([[-1e-3, -1e-3, 100.0]])[0]
    # one softening segment: held by stiff enough others in series, sum 1/k < 0
    assert is_stable([[-1.0, 3.0, 3.0]])[0] and not is_stable([[-1.0, 1.5, 1.5]])[0]


def test_equilibria_are_the_closed_form_roots_of_the_cubics():
    a = cubic_segment("A", 4.0, 10.0, 30.0)
    b = cubic_segment("B", 5.0, 13.0, 33.0)
    actuator = Actuator([a, b])
    pressures = np.linspace(0.0, 60.0, 241)
    eq = actuator.equilibria(pressures)

    def roots(p, peak, valley, peak_kpa):
        alpha = peak_kpa / (peak**2 * (1.5 * valley - 0.5 * peak))
        coefficients = [alpha, -1.5 * alpha * (peak + valley), 3 * alpha * peak * valley, -p]
        r = np.roots(coefficients)
        return np.sort(r[(np.abs(r.imag) < 1e-9) & (r.real >= -1e-9)].real)

    for p in pressures[::10]:
        rows = np.isclose(eq.p_kpa, p)
        ra, rb = roots(p, 4.0, 10.0, 30.0), roots(p, 5.0, 13.0, 33.0)
        # every combination of every root of each segment, nothing else
        expected = sorted(itertools.product(ra, rb))
        found = sorted(map(tuple, eq.v_i_ml[rows]))
        assert len(found) == len(expected)
        np.testing.assert_allclose(found, expected, atol=1e-6)
    np.testing.assert_allclose(
        cubic_pressure(eq.v_i_ml[:, 0], 4.0, 10.0, 30.0), eq.p_kpa, atol=1e-3
    )
    np.testing.assert_allclose(eq.v_ml, eq.v_i_ml.sum(axis=1))
    # stability from the slopes of the closed form
    alpha_a = 30.0 / (16 * (15 - 2))
    alpha_b = 33.0 / (25 * (19.5 - 2.5))
    k = np.column_stack(
        [
            3 * alpha_a * (eq.v_i_ml[:, 0] - 4) * (eq.v_i_ml[:, 0] - 10),
            3 * alpha_b * (eq.v_i_ml[:, 1] - 5) * (eq.v_i_ml[:, 1] - 13),
        ]
    )
    clear = np.abs(k.sum(axis=1)) > 1e-2
    np.testing.assert_array_equal(eq.stable[clear], (k.sum(axis=1) > 0)[clear])


def test_equilibria_of_three_segments_on_the_papers_grid():
    rng = np.random.default_rng(3)
    actuator = Actuator([random_cubic(rng, name) for name in "ABC"])
    eq = actuator.equilibria(actuator.pressure_grid(1000, 100.0))
    assert eq.branches.shape[1] == 3 and set(np.unique(eq.branches)) == {0, 1, 2}
    for i, seg in enumerate(actuator.segments):
        np.testing.assert_allclose(seg.pressure_kpa(eq.v_i_ml[:, i]), eq.p_kpa, atol=1e-9)
    k = np.column_stack(
        [s.slope_kpa_per_ml(eq.v_i_ml[:, i]) for i, s in enumerate(actuator.segments)]
    )
    np.testing.assert_array_equal(eq.stable, is_stable(k))
    # never two segments past their peaks in a stable state
    assert np.all((eq.branches[eq.stable] == 1).sum(axis=1) <= 1)


def test_branch_inversion_agrees_with_a_bracketed_root_and_between_implementations():
    from scipy.optimize import brentq

    seg = cubic_segment("A", 4.0, 10.0, 30.0, samples=97)
    kernel = CurveKernel(seg)
    rng = np.random.default_rng(0)
    for branch in seg.branches:
        hi = branch.p_hi_kpa if np.isfinite(branch.p_hi_kpa) else 80.0
        pressures = rng.uniform(branch.p_lo_kpa, hi, 200)
        v_vec, k_vec = seg.volume_on_branch(branch.index, pressures)
        v_end = branch.v_hi_ml if np.isfinite(branch.p_hi_kpa) else 3 * seg.v_max_ml
        for p, v, k in zip(pressures, v_vec, k_vec, strict=True):
            exact = brentq(
                lambda x, p=p: float(seg.pressure_kpa(x)) - p, branch.v_lo_ml, v_end, xtol=1e-14
            )
            assert v == pytest.approx(exact, abs=1e-10)
            assert k == pytest.approx(float(seg.slope_kpa_per_ml(exact)), rel=1e-7, abs=1e-9)
            v_scalar, k_scalar = kernel.volume_on_branch(branch.index, p)
            assert v_scalar == pytest.approx(v, abs=1e-12) and k_scalar == pytest.approx(
                k, rel=1e-9, abs=1e-12
            )
    # outside a branch's pressure range there is no volume
    assert np.isnan(seg.volume_on_branch(1, 5.0)[0])


def test_kernel_energy_differences_are_the_integral_of_pressure():
    from scipy.integrate import quad

    seg = cubic_segment("A", 4.0, 10.0, 30.0, samples=97)
    kernel = CurveKernel(seg)
    for a, b in [(0.0, 3.3), (3.3, 3.3 + 1e-7), (-0.5, 2.0), (20.0, 60.0), (12.0, 5.0)]:
        exact = quad(
            lambda x: float(seg.pressure_kpa(x)),
            a,
            b,
            points=seg.v_ml[(seg.v_ml > min(a, b)) & (seg.v_ml < max(a, b))][:50],
            limit=200,
        )[0]
        assert kernel.energy_between(a, b) == pytest.approx(exact, rel=1e-9, abs=1e-15)
        assert kernel.energy(b) - kernel.energy(a) == pytest.approx(exact, rel=1e-8, abs=1e-12)
    assert kernel.energy(25.0) == pytest.approx(float(seg.energy_mj(25.0)), rel=1e-12)
    assert kernel.length(7.5) == pytest.approx(float(seg.length_mm(7.5)), rel=1e-12)


def test_slope_profiles_are_the_weighted_inverse_slopes_at_every_sample():
    """Each branch's slope profile, from the compiled tables, against the curve itself
    (scipy's PCHIP and its derivative): sorted in p, every value sqrt(d(p)) / k(v) with d
    the distance to the branch's extremum ends, and every sample of the branch in it."""
    rng = np.random.default_rng(3)
    for seg in [cubic_segment("A", 4.0, 10.0, 30.0, samples=97), random_cubic(rng, "B")]:
        kernel = CurveKernel(seg)
        for branch in seg.branches:
            p, r = kernel.slope_profile(branch.index)
            assert np.all(np.diff(p) >= 0.0) and len(p) >= branch.last - branch.first
            ends = [seg.p_kpa[i] for i in (branch.first, branch.last)]
            extremum = [branch.first > 0, branch.last < len(seg.v_ml) - 1]
            d = np.min(
                [
                    np.abs(p - e) if x else np.full(len(p), np.inf)
                    for e, x in zip(ends, extremum, strict=True)
                ],
                axis=0,
            )
            d = np.where(np.isinf(d), 1.0, d)
            _, k = seg.volume_on_branch(branch.index, p)
            keep = np.abs(k) > 1e-6  # at an extremum sample itself k is 0 to rounding
            # p -> v is ill-conditioned next to an extremum (k -> 0): 1e-4, not rounding
            np.testing.assert_allclose(r[keep], np.sqrt(d[keep]) / k[keep], rtol=1e-4)
            samples = seg.p_kpa[branch.first : branch.last + 1]
            inner = samples[1:-1] if branch.first > 0 else samples[:-1]
            assert np.all(np.isin(inner, p))
