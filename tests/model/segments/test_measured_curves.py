"""Measured curves from anywhere: tables of known curves written the way other
tools and rigs write them (any spacing, uniform or not, rounded, quantised, noisy) must
give the actuators of the clean curves: the same snaps at nearly the same volumes, no
spurious snap, never an exception. The reference is always the clean curve's own path,
an independent table of the same physics; the tolerances are the issue's."""

from __future__ import annotations

import functools
import itertools
import json

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, example, given, settings
from hypothesis import strategies as st
from support.measured_tables import (
    ADC_STEP_KPA,
    dip_hidden_by_step,
    noisy_synthetic_pair,
    rise_fall_rise,
    sample_table,
    snap_details,
    snap_volumes,
    unresolved_fold_pair,
    write_table,
)

from labrig.model.actuator.equilibria import Actuator
from labrig.model.actuator.transitions import table_resolution
from labrig.model.scan.scan import ScanLibrary, load_library, scan_actuator
from labrig.model.segments.catalog import BRAID_LENGTHS_MM, TUBE_LENGTHS_MM, analytical_segment
from labrig.model.segments.measured import curve_from_table, load_csv
from labrig.model.segments.resolution import ROUTE_FITTED, ROUTE_TABULATED, resolution_of

PROPERTY = settings(
    max_examples=5,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
ROUNDINGS = [None, 1e-6, 1e-5, 1e-3, 0.01, ADC_STEP_KPA, 0.1, 0.27, 0.5]


@functools.cache
def clean_snaps(names: tuple[str, ...]) -> tuple[tuple[float, float, float, bool, float], ...]:
    return tuple(snap_details([analytical_segment(n) for n in names]))


def measured(curves, spacing_ml, *, uniform=True, round_to_kpa=None, noise_kpa=0.0, seed=0):
    return [
        curve_from_table(
            sample_table(
                c,
                spacing_ml,
                uniform=uniform,
                round_to_kpa=round_to_kpa,
                noise_kpa=noise_kpa,
                seed=seed + k,
            ),
            name=c.name,
            where=f"table of {c.name}",
        )
        for k, c in enumerate(curves)
    ]


def dip_kpa(curve) -> float:
    return 0.0 if curve.peak is None else curve.peak.p_kpa - curve.valley.p_kpa


def check_same_snaps(
    clean, got, tolerance_ml: float, resolvable: bool, unseen_kpa=0.0, curves=()
) -> None:
    """``clean``: the clean path's snaps as (volume, pressure jump, internal flow, lands
    on the branches it left, slope deficit) (``snap_details``); ``got``: the volumes of the measured
    path's. Every snap found is one of the clean ones, within the tolerance (no spurious
    snap, ever). Every clean snap is found, except where a dip is not resolvable at the
    table's resolution, except a snap whose pressure jump is at most ``unseen_kpa`` (the
    table's step or noise: a jump of 0.001 kPa at a valley, which no table of that
    resolution shows), and except a fold pair whose slope deficit the measured
    ``curves``' rows do not resolve: the clean path's own deficit (how far its rising
    segments in series are softer than the falling one, computed on the clean curves),
    against the standard error of a slope that the measured rows give over the clean
    snap's flow (the criterion of ``transitions``, applied to the clean snap: where the
    clean path is marginally stable, a table off by a few per cent in slope decides
    whether it folds at all: SI-B40-T28's lowest slope within 0.14 kPa/mL of SI-B44-T20's
    fall, 2.9 standard errors of rows every 0.01 mL at 0.006-0.012 kPa). Two snaps
    within 1e-3 mL are one (the path reports a snap that ends on a state lost at once
    as two events at the same volume, to 1e-6 mL)."""
    got = [v for k, v in enumerate(got) if k == 0 or v - got[k - 1] > 1e-3]
    unmatched = list(clean)
    for v in got:
        nearest = min(unmatched, key=lambda c: abs(c[0] - v), default=None)
        assert nearest is not None and abs(nearest[0] - v) <= tolerance_ml, (clean, got)
        unmatched.remove(nearest)
    if resolvable:
        tables = table_resolution(Actuator(list(curves))) if curves else None
        shown = [c for c in unmatched if tables is None or not unresolved_fold_pair(c, tables)]
        assert all(c[1] <= unseen_kpa for c in shown), (clean, got)


def issue_tolerance(step_kpa: float, curves) -> float:
    """The issue's tolerance on a snap's volume: max(0.05 mL, 2 x spacing) for a clean
    table, 0.5 mL for a quantised one, the larger of the two for a table both sparse
    and rounded. The spacing is the tables' widest gap between rows: where rows are not
    evenly spaced (jittered by up to +-45 %) the peak may fall into it. Staircases up
    to 0.5 kPa keep to it since a dip they show, however shallow, is kept and its peak
    and valley come from the stair edges (``labrig.model.segments.stair_edges``); a dip
    shallower than the step they need not show (``dip_hidden_by_step``)."""
    widest = max(c.measured.resolution.spacing_max_ml for c in curves)
    return max(0.05 if step_kpa <= 1e-6 else 0.5, 2 * widest)


def unseen(step_kpa: float, curves) -> float:
    """The largest pressure jump of a clean snap that the tables need not show: their
    rounding step or their noise (for a sparse clean table, its interpolation error:
    the residual of each row from the cubic through its neighbours), never less than
    0.01 kPa (a snap of 0.004 kPa at a valley is below any measurement)."""
    noise = max(c.measured.resolution.noise_kpa for c in curves)
    return max(step_kpa, noise, 0.01)


# --- the issue's failing tables, kept as regression tests -------------------------------
PAIR = ("SI-B42-T24", "SI-B50-T22")  # the library's snap at 25.600 mL


def pair_curves():
    return [analytical_segment(n) for n in PAIR]


@pytest.mark.parametrize(("rows", "decimals"), [(8000, 5), (2000, 5), (8000, 9), (500, 5), (40, 9)])
def test_dense_tables_rounded_to_decimals_give_the_librarys_snap(tmp_path, rows, decimals):
    curves = []
    for clean in pair_curves():
        v = np.linspace(0.0, clean.v_max_ml, rows)
        table = np.column_stack([v, np.round(clean.pressure_kpa(v), decimals), clean.length_mm(v)])
        curves.append(load_csv(write_table(table, tmp_path / f"{clean.name}.csv")))
        # 9 decimals of 300 kPa are float rounding: full precision as far as it can tell
        step = 10.0**-decimals if decimals <= 6 else 0.0
        assert curves[-1].measured.resolution.step_kpa == pytest.approx(step)
    spacing = pair_curves()[1].v_max_ml / (rows - 1)
    (snap,) = snap_volumes(curves)
    assert snap == pytest.approx(25.600, abs=max(0.05, 2 * spacing))


@pytest.mark.parametrize(
    ("spacing_ml", "round_to_kpa"), [(0.002, 0.01), (0.05, 0.27), (0.05, ADC_STEP_KPA)]
)
def test_quantised_tables_give_the_librarys_snap(spacing_ml, round_to_kpa):
    curves = measured(pair_curves(), spacing_ml, round_to_kpa=round_to_kpa)
    for curve in curves:
        assert curve.measured.resolution.step_kpa == pytest.approx(round_to_kpa, rel=1e-6)
    (snap,) = snap_volumes(curves)
    assert snap == pytest.approx(25.600, abs=0.5)


# What the fit reaches on this pair (measured over ten noise seeds): exactly the one
# snap (no spurious one, none missed, the issue's complaint), within 0.46 mL of the
# clean 25.6 mL at 50 rows/mL and 0.3 kPa (rms 0.23 mL), 0.40 mL at 0.2 kPa, 0.19 mL
# at 1,000 rows/mL. SI-B50-T22's falling branch (-0.5 kPa/mL) turns every 0.1 kPa of
# error in SI-B42-T24's fitted valley into 0.2 mL (docs/explanation/measured-curves.md);
# the offset at v = 0 is removed only where it stands out of its own uncertainty:
# extrapolated from four noisy bins it is uncertain by ~0.3 kPa, and removing that would
# shift the whole curve
NOISY_TOLERANCE_ML = {50: 0.5, 1000: 0.5}


@pytest.mark.parametrize(
    ("rows_per_ml", "noise_kpa", "round_to_kpa"),
    [(50, 0.2, None), (50, 0.3, None), (1000, 0.25, 0.27), (1000, 0.3, ADC_STEP_KPA)],
)
def test_noisy_raw_rows_give_the_librarys_snap_and_no_spurious_one(
    rows_per_ml, noise_kpa, round_to_kpa
):
    for seed in (0, 10):
        curves = measured(
            pair_curves(),
            1.0 / rows_per_ml,
            round_to_kpa=round_to_kpa,
            noise_kpa=noise_kpa,
            seed=seed,
        )
        assert all(c.measured.route == ROUTE_FITTED for c in curves)
        for curve in curves:  # the noise estimate is the noise put in (and quantisation)
            assert curve.measured.resolution.noise_kpa == pytest.approx(noise_kpa, rel=0.25)
        (snap,) = snap_volumes(curves)  # one snap: no spurious one, the real one kept
        assert snap == pytest.approx(25.600, abs=NOISY_TOLERANCE_ML[rows_per_ml])


# --- what the resolution estimates say -----------------------------------------------------
def test_the_step_is_found_on_an_offset_adc_lattice_and_plateaus_never_stay():
    clean = analytical_segment("SI-B46-T22")
    v = np.linspace(0.0, clean.v_max_ml, 5000)
    counts = np.round((clean.pressure_kpa(v) + 0.1234) / ADC_STEP_KPA)
    p = counts * ADC_STEP_KPA - 0.1234  # an offset lattice: no decimal rounding
    res = resolution_of(v, p)
    assert res.step_kpa == pytest.approx(ADC_STEP_KPA, rel=1e-6)
    assert res.uniform and res.spacing_ml == pytest.approx(v[1])
    assert res.quantised
    curve = curve_from_table(np.column_stack([v, p, clean.length_mm(v)]), name="q", where="q")
    # no flat run is left (a zero slope would make a fold): same branches as the clean one
    assert np.all(np.diff(curve.p_kpa) != 0)
    assert len(curve.branches) == len(clean.branches) == 3
    assert curve.peak.v_ml == pytest.approx(clean.peak.v_ml, abs=0.2)


@pytest.mark.parametrize("lowest", [0, 17, 38])
def test_the_rise_of_one_minimum_slope_is_the_constrained_least_squares_solution(lowest):
    """Against an independent solver of the same problem: the values written out row by
    row as y0 + the integral of slopes that are the smallest plus non-negative
    increments away from it, solved with the intercept free by scipy's bounded least
    squares (BVLS; the code eliminates the intercept and uses NNLS)."""
    from scipy.optimize import lsq_linear

    from labrig.model.segments.shape_fit import curvature_constrained_rise

    rng = np.random.default_rng(lowest)
    n = 40
    x = np.sort(rng.uniform(0.0, 10.0, n))
    w = rng.uniform(0.5, 2.0, n)
    y = np.where(x < 5, 30 * np.sqrt(x), 30 * np.sqrt(5) + (x - 5) ** 2) + rng.normal(0, 1, n)
    got = curvature_constrained_rise(x, y, w, lowest)
    # unknowns: y0, s_min, then one increment per interval other than the lowest
    design = np.zeros((n, n))
    design[:, 0] = 1.0
    for i in range(n):
        for k in range(i):  # interval k (x_k .. x_k+1) lies below x_i
            h = x[k + 1] - x[k]
            design[i, 1] += h
            others = range(k, lowest) if k < lowest else range(lowest, k)
            for j in others:  # increments between interval k and the lowest
                design[i, 2 + j] += h
    root_w = np.sqrt(w)
    lower = np.r_[-np.inf, np.zeros(n - 1)]
    want = lsq_linear(design * root_w[:, None], y * root_w, bounds=(lower, np.inf))
    slopes = np.diff(got) / np.diff(x)
    assert np.all(slopes >= -1e-9)
    assert np.all(np.diff(slopes)[:lowest] <= 1e-9)
    assert np.all(np.diff(slopes)[lowest:] >= -1e-9)
    assert np.sum(w * (y - got) ** 2) == pytest.approx(np.sum(w * (y - design @ want.x) ** 2))
    np.testing.assert_allclose(got, design @ want.x, atol=1e-6)


def test_full_precision_values_have_no_step_and_a_sparse_table_no_noise():
    clean = analytical_segment("SI-B44-T24")
    v = np.linspace(0.0, clean.v_max_ml, 40)
    res = resolution_of(v, clean.pressure_kpa(v))
    assert res.step_kpa == 0.0
    # the cubic through the neighbours follows the curvature of a sparse table, which
    # then tabulates as is
    curve = curve_from_table(
        np.column_stack([v, clean.pressure_kpa(v), clean.length_mm(v)]), name="s", where="s"
    )
    assert curve.measured.route == ROUTE_TABULATED
    np.testing.assert_array_equal(curve.v_ml, v)


def test_a_dip_of_a_few_rounding_steps_is_not_a_peak():
    # SI-B44-T30's dip is 0.007 kPa: at 0.01 kPa rounding at most two steps, not a feature
    clean = analytical_segment("SI-B44-T30")
    (curve,) = measured([clean], 0.01, round_to_kpa=0.01)
    assert dip_kpa(clean) < 3 * 0.01
    assert curve.peak is None and not curve.measured.peak_kept
    (kept,) = measured([clean], 0.01, round_to_kpa=1e-5)  # resolvable at 1e-5 kPa
    assert kept.peak is not None and dip_kpa(kept) == pytest.approx(dip_kpa(clean), abs=1e-3)


# --- properties ------------------------------------------------------------------------------
def library_actuators():
    """2 or 3 segments with different braid lengths (equal ones peak at exactly the same
    pressure, where which segment snaps first is decided by rounding)."""
    return (
        st.integers(2, 3)
        .flatmap(
            lambda n: st.tuples(
                st.lists(st.sampled_from(BRAID_LENGTHS_MM), min_size=n, max_size=n, unique=True),
                st.lists(st.sampled_from(TUBE_LENGTHS_MM), min_size=n, max_size=n),
            )
        )
        .map(lambda bt: tuple(f"SI-B{b}-T{t}" for b, t in zip(*bt, strict=True)))
    )


spacings = st.floats(np.log10(0.0005), np.log10(0.5)).map(lambda x: 10.0**x)


# found by this property with more examples: a sparse table rounded to 0.1 kPa, used
# as tabulated, had slopes off by up to 70 % on its falling branch (5 snaps for 2); the
# clean path's snap of 0.004 kPa; a jittered sparse table's peak in a 0.46 mL gap; a
# 0.5 kPa staircase whose step, taken as 0.5 kPa, made SI-B40-T22's 1.8 kPa dip no peak
# (the snap moved by 3 mL: that step estimate is not used); staircases at 0.27-0.5 kPa
# whose stair values put the snap beyond 1.5 mL per kPa of step or made a snap vanish
# (found by a sweep of 80 random draws; within it with the stair-edge extrema); a
# monotone segment beside a snapping one at 0.1 kPa, 0.51 mL off: a test below (its
# corner rows kept); with 40 examples, a dense table rounded to 0.001 kPa whose real
# snaps at 17.5 and 30.4 mL were each followed by a train of unresolved 0.001 kPa fold
# pairs within a bin, and dropped as 'one snap in two steps' (both missed)
@example(names=("SI-B40-T28", "SI-B42-T20", "SI-B44-T20"), spacing_ml=0.001, uniform=False,
         round_to_kpa=0.001, seed=0)  # fmt: skip
# found with 40 examples instead of 5 (a local run): a clean fold pair of 0.042 kPa
# at 26.24 mL, missed, whose slope deficit (0.094 kPa/mL) is 0.8 standard errors of
# the slope the ADC staircase's rows give over its 0.087 mL flow (not resolvable)
@example(names=("SI-B44-T20", "SI-B40-T22", "SI-B42-T30"), spacing_ml=10.0**-1.921875, uniform=True,
         round_to_kpa=ADC_STEP_KPA, seed=0)  # fmt: skip
# found by a sweep of 200 random draws of staircases at 0.27/0.5 kPa every 0.05-0.5 mL:
# a dip of one or two steps (SI-B40-T24's 0.73 kPa, SI-B42-T26's 0.61, SI-B44-T28's 0.51 at 0.5
# kPa) fell under the 3-step prominence and the partner's snap moved by 0.7-1.8 mL; an
# undithered staircase that falls shows a real dip (``stair_edges.shows_dip``), and
# its peak and valley come from its edges: 0.05-0.2 mL. The last: SI-B40-T26's 0.05 kPa
# dip, under the step, which the table does not hold (``dip_hidden_by_step``)
@example(names=("SI-B40-T24", "SI-B48-T24"), spacing_ml=0.3030689851144785, uniform=False,
         round_to_kpa=0.5, seed=263)  # fmt: skip
@example(names=("SI-B42-T26", "SI-B46-T20"), spacing_ml=0.1539189974542332, uniform=True,
         round_to_kpa=0.5, seed=767)  # fmt: skip
@example(names=("SI-B44-T28", "SI-B48-T24", "SI-B40-T22"), spacing_ml=0.10281950495084123,
         uniform=True, round_to_kpa=0.5, seed=178)  # fmt: skip
@example(names=("SI-B48-T26", "SI-B40-T26", "SI-B42-T24"), spacing_ml=0.11078768967212878,
         uniform=True, round_to_kpa=0.5, seed=36)  # fmt: skip
@example(names=("SI-B40-T22", "SI-B42-T20"), spacing_ml=0.1, uniform=False, round_to_kpa=0.5,
         seed=0)  # fmt: skip
@example(names=("SI-B44-T20", "SI-B48-T20", "SI-B46-T26"), spacing_ml=0.1, uniform=False,
         round_to_kpa=0.27, seed=744)  # fmt: skip
@example(names=("SI-B40-T24", "SI-B46-T26", "SI-B42-T22"), spacing_ml=0.1, uniform=False,
         round_to_kpa=0.27, seed=623)  # fmt: skip
@example(names=("SI-B50-T20", "SI-B48-T20", "SI-B44-T28"), spacing_ml=0.1, uniform=False,
         round_to_kpa=0.5, seed=820)  # fmt: skip
@example(names=("SI-B44-T28", "SI-B50-T20"), spacing_ml=0.003224633495381667, uniform=False,
         round_to_kpa=0.27, seed=863)  # fmt: skip
@example(names=("SI-B42-T20", "SI-B48-T20"), spacing_ml=0.15736293507864732, uniform=False,
         round_to_kpa=0.5, seed=316)  # fmt: skip
@example(names=("SI-B44-T22", "SI-B46-T28", "SI-B42-T30"), spacing_ml=10.0**-0.5, uniform=True,
         round_to_kpa=0.1, seed=962)  # fmt: skip
@example(names=("SI-B40-T20", "SI-B42-T20"), spacing_ml=10.0**-2.5, uniform=False,
         round_to_kpa=0.1, seed=0)  # fmt: skip
@example(names=("SI-B40-T28", "SI-B50-T28", "SI-B42-T20"), spacing_ml=10.0**-0.5, uniform=False,
         round_to_kpa=None, seed=0)  # fmt: skip
@example(names=("SI-B42-T20", "SI-B40-T20"), spacing_ml=10.0**-0.5, uniform=False,
         round_to_kpa=None, seed=0)  # fmt: skip
@PROPERTY
@given(
    names=library_actuators(),
    spacing_ml=spacings,
    uniform=st.booleans(),
    round_to_kpa=st.sampled_from(ROUNDINGS),
    seed=st.integers(0, 1000),
)
def test_clean_and_quantised_library_tables_snap_like_the_clean_curves(
    names, spacing_ml, uniform, round_to_kpa, seed
):
    """The clean snaps, none spurious, within the issue's tolerance (``issue_tolerance``:
    0.5 mL for a quantised table, or twice its widest gap), but for an actuator with a
    dip shallower than the step, which the tables need not hold (``dip_hidden_by_step``):
    it only runs."""
    clean = [analytical_segment(n) for n in names]
    curves = measured(clean, spacing_ml, uniform=uniform, round_to_kpa=round_to_kpa, seed=seed)
    got = snap_volumes(curves)
    step = round_to_kpa or 0.0
    if dip_hidden_by_step(clean, step):
        return
    tolerance = issue_tolerance(step, curves)
    resolvable = all(dip_kpa(c) > 10 * step or c.peak is None for c in clean)
    check_same_snaps(clean_snaps(names), got, tolerance, resolvable, unseen(step, curves), curves)


def test_a_monotone_segment_rounded_to_a_tenth_beside_a_snapping_one():
    """Found by the property above: SI-B44-T30 (no peak) + SI-B46-T20
    every 0.1 mL (jittered), rounded to 0.1 kPa, must snap near the clean 15.594 mL.
    SI-B44-T30's braid contact is a corner inside one row gap (39.1 kPa up to 8.357 mL,
    39.3 at 8.513); the plateau's centre joined to the next row would spread it and move
    the fold to 39.30 kPa (clean 39.09), 0.51 mL of snap. The plateau's row at the jump is
    kept (``keep_corner_rows``): the fold at 39.13 kPa, the snap 0.39 mL off."""
    names = ("SI-B44-T30", "SI-B46-T20")
    clean = [analytical_segment(n) for n in names]
    curves = measured(clean, 0.1, uniform=False, round_to_kpa=0.1, seed=1)
    tolerance = issue_tolerance(0.1, curves)
    got = snap_volumes(curves)
    check_same_snaps(clean_snaps(names), got, tolerance, True, unseen(0.1, curves), curves)


# found by this property with 25 examples: SI-B40-T20 + SI-B42-T26 + SI-B44-T20 at 1,000 rows/mL,
# 0.5 kPa noise on a 0.27 kPa step snapped 1.17 mL off: SI-B42-T26's 0.6 kPa dip, within
# three steps, was taken for rounding although the noise dithers the steps (its bins'
# means resolve it by 10 standard errors); its peak lost, the path was another one.
# The valleys fitted are within 0.1 kPa (docs/explanation/measured-curves.md)
@example(names=("SI-B40-T20", "SI-B42-T26", "SI-B44-T20"), noise_kpa=0.5, averaging=0.015625,
         round_to_kpa=0.27, seed=0)  # fmt: skip
@PROPERTY
@given(
    names=library_actuators(),
    noise_kpa=st.floats(0.05, 0.5),
    averaging=st.floats(0.004, 0.05),
    round_to_kpa=st.sampled_from([None, ADC_STEP_KPA, 0.27]),
    seed=st.integers(0, 1000),
)
def test_noisy_library_tables_snap_like_the_clean_curves(
    names, noise_kpa, averaging, round_to_kpa, seed
):
    """``averaging`` is the noise left in a 1 mL average (noise / sqrt(rows per mL)):
    up to 0.02 kPa, with noise enough to dither the quantisation (at least half a
    step), the clean snaps are found, none spurious, at any noise of 0.05-0.5 kPa,
    within the issue's 0.5 mL; beyond, the fit still gives a valid curve and the path
    no exception (docs/performance.md, measured curves)."""
    spacing_ml = max((averaging / noise_kpa) ** 2, 0.00053)
    clean = [analytical_segment(n) for n in names]
    curves = measured(clean, spacing_ml, round_to_kpa=round_to_kpa, noise_kpa=noise_kpa, seed=seed)
    got = snap_volumes(curves)
    dithered = round_to_kpa is None or noise_kpa >= 0.5 * round_to_kpa
    if noise_kpa * np.sqrt(spacing_ml) <= 0.02 and dithered:
        check_same_snaps(clean_snaps(names), got, 0.5, True, unseen(noise_kpa, curves), curves)


synthetic_shapes = st.fixed_dictionaries(
    {
        "peak_v_ml": st.floats(3.0, 8.0),
        "peak_kpa": st.floats(30.0, 45.0),
        "dip_kpa": st.floats(2.0, 10.0),
        "valley_after_ml": st.floats(3.0, 15.0),
        "end_after_ml": st.floats(20.0, 30.0),
    }
)


def synthetic(name: str, shape: dict):
    return rise_fall_rise(
        name,
        peak_v_ml=shape["peak_v_ml"],
        peak_kpa=shape["peak_kpa"],
        dip_kpa=shape["dip_kpa"],
        valley_v_ml=shape["peak_v_ml"] + shape["valley_after_ml"],
        end_v_ml=shape["peak_v_ml"] + shape["end_after_ml"],
    )


# found with more examples: a spurious fold pair at 16.96 mL (0.54 kPa over 0.29 mL).
# The clean path is marginally stable (A's rising slope 1.9-2.0 kPa/mL against B's
# steepest fall, -1.99); A, a 0.27 kPa staircase tabulated at its plateau centres, put
# its slope 10 % low there: a deficit of 0.20 kPa/mL, 0.65 standard errors of the
# slope its rows resolve over 0.29 mL, so not reported (``fold_slope_deficit``)
@example(
    shape_a={"peak_v_ml": 3.0, "peak_kpa": 30.0, "dip_kpa": 2.0, "valley_after_ml": 3.0,
             "end_after_ml": 20.0},
    shape_b={"peak_v_ml": 3.0, "peak_kpa": 37.0, "dip_kpa": 4.0, "valley_after_ml": 3.0,
             "end_after_ml": 20.0},
    spacing_ml=10.0**-1.5, uniform=False, round_to_kpa=0.27, noise_kpa=0.0, seed=0,
)  # fmt: skip
@PROPERTY
@given(
    shape_a=synthetic_shapes,
    shape_b=synthetic_shapes,
    spacing_ml=spacings,
    uniform=st.booleans(),
    round_to_kpa=st.sampled_from(ROUNDINGS),
    noise_kpa=st.sampled_from([0.0, 0.0, 0.1, 0.3]),
    seed=st.integers(0, 1000),
)
def test_random_rise_fall_rise_shapes_snap_like_their_clean_curves(
    shape_a, shape_b, spacing_ml, uniform, round_to_kpa, noise_kpa, seed
):
    a, b = synthetic("A", shape_a), synthetic("B", shape_b)
    # peaks apart by at least the library's closest (0.45 kPa, braid lengths 2 mm
    # apart): equal peaks make the snap's order a matter of rounding, not of the curves
    assume(abs(a.peak.p_kpa - b.peak.p_kpa) >= 0.4)
    if noise_kpa:  # rows dense enough for the noise to average out (see above)
        spacing_ml = max(min(spacing_ml, (0.02 / noise_kpa) ** 2), 0.0005)
    clean = snap_details([a, b])
    curves = measured(
        [a, b],
        spacing_ml,
        uniform=uniform,
        round_to_kpa=round_to_kpa,
        noise_kpa=noise_kpa,
        seed=seed,
    )
    got = snap_volumes(curves)
    step = round_to_kpa or 0.0
    tolerance = 0.5 if noise_kpa else issue_tolerance(step, curves)
    resolvable = all(dip_kpa(c) > 10 * max(step, noise_kpa) for c in (a, b))
    check_same_snaps(
        clean, got, tolerance, resolvable, unseen(max(step, noise_kpa), curves), curves
    )


@pytest.mark.parametrize("case", [5, 6, 10, 28, 30, 39])
def test_noisy_synthetic_pairs_that_had_spurious_snaps(case):
    """Pairs whose fit took the isotonic blocks (their slopes flicker from bin to bin)
    would, where a tangent clamped flat repeats a value, show 2 to 16 spurious snaps; the
    fit is smooth there and finds the clean snaps."""
    shapes, noise, spacing, rounding, seed = noisy_synthetic_pair(1, case)
    curves = measured(shapes, spacing, round_to_kpa=rounding, noise_kpa=noise, seed=seed)
    assert all(len(c.v_ml) >= 200 for c in curves)  # the smooth fit on the bins, not blocks
    check_same_snaps(snap_details(shapes), snap_volumes(curves), 0.5, True, 0.01, curves)


def test_a_noisy_library_triple_at_half_a_kpa_has_no_fold_pairs():
    """A spline fitted to SI-B40-T26's rising branch (no peak at 0.5 kPa noise) lets its
    slope flicker by up to 1.5 kPa/mL from bin to bin, below the falling SI-B42-T20's
    0.44 kPa/mL: four fold pairs of 0.02-0.05 kPa. A rising branch is fitted with a slope
    of one minimum (``one_minimum_slope_rise``)."""
    names = ("SI-B42-T20", "SI-B44-T20", "SI-B40-T26")
    clean = [analytical_segment(n) for n in names]
    curves = measured(clean, (0.015625 / 0.5) ** 2, noise_kpa=0.5, seed=0)
    got = snap_volumes(curves)
    assert len(got) == 3  # the clean path's three snaps, none spurious
    check_same_snaps(clean_snaps(names), got, 0.5, True, 0.5, curves)


def test_a_marginal_noisy_library_pair_reports_no_fold_pair_its_rows_cannot_resolve():
    """SI-B42-T30's smallest slope (0.5 kPa/mL just before its braids'
    contact) is within a few hundredths of SI-B44-T24's falling 0.44 kPa/mL: the clean path
    is marginally stable, and at 0.21 kPa noise the fit's slope there dips below it, a
    fold pair of 0.09 kPa over 0.22 mL of flow. Even its whole slope, 0.42 kPa/mL (its
    slope deficit is less), is within 1.2 standard errors of the slope that the rows
    over 0.22 mL resolve (0.35 kPa/mL): not a snap those tables can show
    (``transitions``)."""
    names = ("SI-B42-T30", "SI-B44-T24")
    noise_kpa = 0.21295878053605966
    spacing_ml = (0.010472597057400279 / noise_kpa) ** 2
    clean = [analytical_segment(n) for n in names]
    curves = measured(clean, spacing_ml, noise_kpa=noise_kpa, seed=796)
    assert clean_snaps(names) == ()
    assert snap_volumes(curves) == []
    tables = table_resolution(Actuator(curves))
    slope_error = tables.slope_error_kpa_per_ml(0.22)  # independently: e sqrt(12 dv / W^3)
    assert slope_error == pytest.approx(noise_kpa * np.sqrt(12 * spacing_ml / 0.22**3), rel=0.1)
    assert not tables.resolves_fold_pair(0.092 / 0.22, 0.22)
    assert tables.resolves_fold_pair(0.5, 4.0)  # a real snap: 0.5 kPa/mL over 4 mL


def test_a_fold_pairs_slope_deficit_is_the_falling_slope_less_the_rising_ones_in_series():
    """Against slopes known by construction: straight pieces (PCHIP through collinear
    rows is the line), rising at 2 and 4 kPa/mL where the states lie, one falling at
    -1.5 kPa/mL: the rising pair in series is 1 / (1/2 + 1/4) = 4/3 kPa/mL stiff, the
    deficit 1.5 - 4/3 = 1/6 kPa/mL; with only the 2 kPa/mL one, 0 (stable: no deficit)."""
    from labrig.model.actuator.path import State
    from labrig.model.actuator.transitions import fold_slope_deficit
    from labrig.model.segments.curve import SegmentCurve

    def line(name, v_start, p_start, slope):
        """Rows on the line from v_start to v_start + 6 mL (interior intervals: linear)."""
        run = np.arange(7.0)
        v = np.r_[0.0, v_start + run, v_start + 12.0]
        p = np.r_[0.0, p_start + slope * run, p_start + 6 * slope + 300.0]
        return SegmentCurve(name, v, p, np.full(len(v), 30.0), V0_ml=2.5)

    rising_2, rising_4 = line("r2", 2.0, 10.0, 2.0), line("r4", 2.0, 5.0, 4.0)
    falling = line("f", 3.0, 40.0, -1.5)
    pre = State((1, 1, 1), 20.0, (4.5, 4.5, 5.0), (2.0, 4.0, -1.5))
    post = State((1, 1, 1), 20.0, (4.8, 4.7, 5.5), (2.0, 4.0, -1.5))
    assert fold_slope_deficit([rising_2, rising_4, falling], pre, post) == pytest.approx(1 / 6)
    pair_pre = State((1, 1), 20.0, (4.5, 5.0), (2.0, -1.5))
    pair_post = State((1, 1), 20.0, (4.8, 5.5), (2.0, -1.5))
    assert fold_slope_deficit([rising_2, falling], pair_pre, pair_post) == 0.0


@pytest.mark.parametrize(("seed", "case"), [(1, 11), (1, 13), (2, 21), (2, 30), (3, 33), (3, 37)])
def test_noisy_synthetic_pairs_with_fold_pairs_below_their_resolution(seed, case):
    """Found by the benchmark once rising branches were fitted with a slope of one
    minimum: fold pairs of 0.03-0.3 kPa just before a real snap (the state they land on
    lost again within 0.04 mL, less than the fitted curve's bin: one snap in two steps)
    or with a slope the rows do not resolve. Now the clean snaps, within 0.5 mL, but a
    clean fold pair whose slope deficit the rows do not resolve (case 11's at 32.68 mL:
    0.59 kPa over 0.29 mL of a path 0.007 kPa/mL from stable, which no noisy table
    tells from a stable one; ``check_same_snaps``)."""
    shapes, noise, spacing, rounding, table_seed = noisy_synthetic_pair(seed, case)
    curves = measured(shapes, spacing, round_to_kpa=rounding, noise_kpa=noise, seed=table_seed)
    tables = table_resolution(Actuator(curves))
    clean = [c for c in snap_details(shapes) if c[1] > 0.01 and not unresolved_fold_pair(c, tables)]
    got = snap_volumes(curves)
    assert len([v for k, v in enumerate(got) if k == 0 or v - got[k - 1] > 1e-3]) == len(clean)
    check_same_snaps(clean, got, 0.5, True, 0.01, curves)


# how other tools write numbers, with the rounding each means for pressures up to
# 300 kPa (%g keeps 6 significant digits, %.6e 7)
FORMATS = {"%.2f": 0.01, "%.5f": 1e-5, "%.9f": 0.0, "%g": 1e-3, "%.6e": 1e-4}


# found by this property: volumes written to 2 decimals repeat (refused, then averaged);
# a merged table's slopes hidden by its noise (tabulated, 16 snaps); a fold pair of
# 0.007 kPa and 0.007 mL at a valley's exit (below the tables' resolution, not reported)
@example(names=("SI-B40-T20", "SI-B42-T20"), spacing_ml=0.01, uniform=False, fmt="%.2f", adc=False,
         seed=0)  # fmt: skip
@example(names=("SI-B40-T20", "SI-B42-T20", "SI-B44-T20"), spacing_ml=0.001, uniform=False,
         fmt="%.2f", adc=False, seed=0)  # fmt: skip
@example(names=("SI-B40-T20", "SI-B42-T20", "SI-B44-T20"), spacing_ml=10.0**-1.3125, uniform=False,
         fmt="%.2f", adc=False, seed=0)  # fmt: skip
@example(names=("SI-B40-T20", "SI-B42-T20"), spacing_ml=10.0**-0.5, uniform=False, fmt="%.2f",
         adc=False, seed=0)  # fmt: skip
@example(names=("SI-B40-T20", "SI-B42-T20"), spacing_ml=0.1, uniform=False, fmt="%.5f", adc=True,
         seed=0)  # fmt: skip
# two valleys 0.006 kPa apart, swapped by an offset of -0.04 kPa that the quadratic
# through the first rows' steep start made up (a spurious snap at 41.46 mL): the
# quadratic's misfit counts in the offset's uncertainty (``zero_offset``)
@example(names=("SI-B50-T30", "SI-B40-T20", "SI-B46-T28"), spacing_ml=0.1, uniform=False,
         fmt="%.2f", adc=False, seed=0)  # fmt: skip
# the clean fold pair of 0.10 kPa at 14.93 mL, missed: its slope deficit (0.14
# kPa/mL) is 2.9 standard errors of the rows' slope over its 0.2 mL flow (``unseen``)
@example(names=("SI-B44-T20", "SI-B40-T28"), spacing_ml=0.01, uniform=False, fmt="%.2f", adc=False,
         seed=0)  # fmt: skip
@PROPERTY
@given(
    names=library_actuators(),
    spacing_ml=spacings,
    uniform=st.booleans(),
    fmt=st.sampled_from(sorted(FORMATS)),
    adc=st.booleans(),
    seed=st.integers(0, 1000),
)
def test_csvs_written_by_other_tools_through_model_path(
    tmp_path, capsys, names, spacing_ml, uniform, fmt, adc, seed
):
    """CSV files as another tool writes them (numbers formatted its way, pressures on
    the USB-6009's lattice or not), run through ``labrig model path A.csv B.csv
    --json``: exit 0 and the clean curves' snaps (the issue's tolerances)."""
    from labrig.cli import main

    clean = [analytical_segment(n) for n in names]
    files = []
    for k, curve in enumerate(clean):
        table = sample_table(
            curve, spacing_ml, uniform=uniform, round_to_kpa=ADC_STEP_KPA if adc else None,
            seed=seed + k,
        )  # fmt: skip
        path = tmp_path / f"{curve.name}-{seed}-{k}.csv"
        with path.open("w") as out:
            out.write("volume_ml,pressure_kpa,length_mm\n")
            np.savetxt(out, table, delimiter=",", fmt=fmt)
        files.append(str(path))
    with pytest.raises(SystemExit) as exited:
        main(["model", "path", *files, "--json"])
    out, err = capsys.readouterr()
    assert exited.value.code == 0, err
    got = [
        t["v_ml"]
        for t in json.loads(out)["transitions"]
        if not t["stable"] and t["direction"] == "inflate"
    ]
    written = [load_csv(f) for f in files]
    step = max(FORMATS[fmt], ADC_STEP_KPA if adc else 0.0)
    tolerance = issue_tolerance(step, written)
    resolvable = all(dip_kpa(c) > 10 * step or c.peak is None for c in clean)
    check_same_snaps(clean_snaps(names), got, tolerance, resolvable, unseen(step, written), written)


# --- scans of measured libraries -----------------------------------------------------------
SCAN_SEGMENTS = ("SI-B42-T24", "SI-B46-T28", "SI-B50-T22")


def snapping_actuators(library, n: int) -> dict[tuple[int, ...], int]:
    """Each actuator of n segments of the library with the number of its snaps."""
    out = {}
    for combo in itertools.combinations(range(len(library.curves)), n):
        out[combo] = sum(not t.stable for t in scan_actuator(library, combo))
    return out


@pytest.mark.parametrize(("spacing_ml", "round_to_kpa"), [(0.002, 1e-5), (0.05, 0.27)])
def test_a_scan_of_measured_csvs_snaps_like_the_scan_of_the_clean_curves(
    tmp_path, spacing_ml, round_to_kpa
):
    """Three segments written as CSVs at two resolutions (dense and rounded to 5
    decimals; sparse and quantised at 0.27 kPa), scanned with ``--library DIR``: the
    same actuators snap, as often, as in the scan of the clean curves."""
    clean = ScanLibrary("clean", tuple(analytical_segment(n) for n in SCAN_SEGMENTS))
    for k, curve in enumerate(clean.curves):
        table = sample_table(curve, spacing_ml, round_to_kpa=round_to_kpa, seed=k)
        write_table(table, tmp_path / f"{curve.name}.csv")
    library = load_library(str(tmp_path))
    assert library.names == list(SCAN_SEGMENTS)
    for n in (2, 3):
        want = snapping_actuators(clean, n)
        assert any(want.values())  # the scan has snapping actuators to find
        assert snapping_actuators(library, n) == want


def test_a_scan_of_mixed_resolutions_runs_through_the_command_line(tmp_path, capsys):
    """Measured CSVs of mixed resolutions in one folder: ``labrig model scan --library``
    computes every actuator (no failure recorded)."""
    from labrig.cli import main
    from labrig.model.scan.scan_file import read_scan

    folder = tmp_path / "lib"
    folder.mkdir()
    settings_by_segment = [(0.001, 1e-5, 0.0), (0.05, ADC_STEP_KPA, 0.0), (0.3, None, 0.0)]
    for (spacing, rounding, noise), name in zip(settings_by_segment, SCAN_SEGMENTS, strict=True):
        table = sample_table(
            analytical_segment(name), spacing, round_to_kpa=rounding, noise_kpa=noise
        )
        write_table(table, folder / f"{name}.csv")
    out = tmp_path / "scan.h5"
    with pytest.raises(SystemExit) as exited:
        main(["model", "scan", "--n", "2", "--library", str(folder), "--out", str(out),
              "--workers", "1"])  # fmt: skip
    capsys.readouterr()
    assert exited.value.code == 0
    data = read_scan(out)
    assert data.complete and data.actuators_done == 3
    assert len(data.failed_actuator) == 0, data.failed_error
