"""Measured curves: strict CSV validation, a noise-robust shape fit checked against the
clean curve the noise was added to, and a lossless CSV round trip."""

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from labrig.errors import InputError
from labrig.model.segments.catalog import analytical_segment
from labrig.model.segments.measured import load_csv, write_csv
from labrig.model.segments.shape_fit import (
    fit_rise_fall_rise,
    isotonic_blocks,
    prefix_isotonic_sse,
)

HEADER = "volume_ml,pressure_kpa,length_mm"
GAIN, OFFSET_KPA = 1.02, 0.8


def mpx5100_like(curve, seed, p_max_kpa=95.0, samples_per_ml=1000, spikes=0):
    """Samples of ``curve`` as the rig records them: 1 kHz at 60 mL/min, a gain and offset
    error (the sensor's +-2.5 %), white noise of 0.3 kPa, 0.3 kPa quantisation, camera
    noise on the length; recorded up to the sensor's range."""
    rng = np.random.default_rng(seed)
    v = np.arange(0, curve.v_max_ml, 1 / samples_per_ml)
    clean = curve.pressure_kpa(v)
    v = v[: np.argmax(clean > p_max_kpa)] if np.any(clean > p_max_kpa) else v
    p = GAIN * curve.pressure_kpa(v) + OFFSET_KPA + rng.normal(0, 0.3, len(v))
    p[rng.integers(0, len(v), spikes)] += 20.0
    p = np.round(p / 0.3) * 0.3
    length = curve.length_mm(v) + rng.normal(0, 0.05, len(v))
    return np.column_stack([v, p, length])


def write_table(path, table, fmt="%.6f"):
    with open(path, "w") as fh:
        fh.write(HEADER + "\n")
        np.savetxt(fh, table, delimiter=",", fmt=fmt)
    return path


@pytest.mark.parametrize(
    ("name", "seed"), [("SI-B46-T20", 1), ("SI-B46-T22", 2), ("SI-B50-T24", 3)]
)
def test_noisy_data_give_the_clean_peak_and_valley(tmp_path, name, seed):
    clean = analytical_segment(name)
    raw = mpx5100_like(clean, seed)
    # the raw data are full of spurious extrema
    assert np.count_nonzero(np.diff(np.sign(np.diff(raw[:, 1])))) > 100
    curve = load_csv(write_table(tmp_path / "run.csv", raw))
    assert len(curve.branch_bounds) == 3  # exactly one peak and one valley
    # the gain error cannot be seen in one curve; everything else must be removed
    assert curve.peak.v_ml == pytest.approx(clean.peak.v_ml, abs=0.6)
    assert curve.peak.p_kpa == pytest.approx(GAIN * clean.peak.p_kpa, abs=0.25)
    assert curve.valley.v_ml == pytest.approx(clean.valley.v_ml, abs=0.4)
    assert curve.valley.p_kpa == pytest.approx(GAIN * clean.valley.p_kpa, abs=0.25)
    assert curve.p_kpa[0] == 0.0 and curve.v_ml[0] == 0.0
    grid = np.linspace(0, raw[-1, 0] - 0.1, 300)  # the last bin is steep in l
    np.testing.assert_allclose(curve.length_mm(grid), clean.length_mm(grid), atol=0.1)


def test_spikes_and_a_rising_curve_give_no_spurious_peak(tmp_path):
    clean = analytical_segment("SI-B40-T30")  # contact before the peak: p(v) only rises
    curve = load_csv(write_table(tmp_path / "run.csv", mpx5100_like(clean, 4, spikes=30)))
    assert curve.peak is None and curve.branch_bounds == [(0, len(curve.v_ml) - 1)]
    grid = np.linspace(0.5, 12.0, 200)
    np.testing.assert_allclose(curve.pressure_kpa(grid), GAIN * clean.pressure_kpa(grid), atol=0.6)


def test_curve_is_extended_monotonically_past_the_last_sample(tmp_path):
    clean = analytical_segment("SI-B46-T20")
    raw = mpx5100_like(clean, 5)
    curve = load_csv(write_table(tmp_path / "run.csv", raw))
    assert curve.p_kpa[-1] == pytest.approx(300.0)
    beyond = np.linspace(raw[-1, 0], curve.v_max_ml + 1, 100)
    assert np.all(np.diff(curve.pressure_kpa(beyond)) > 0)
    assert "extended" in curve.source


def test_round_trip_is_lossless(tmp_path):
    clean = analytical_segment("SI-B46-T22")
    write_csv(clean, tmp_path / "b46.csv")
    assert (tmp_path / "b46.csv").read_text().splitlines()[0] == HEADER
    back = load_csv(tmp_path / "b46.csv", V0_ml=clean.V0_ml)
    assert back.name == "b46"
    for field in ("v_ml", "p_kpa", "l_mm"):
        np.testing.assert_array_equal(getattr(back, field), getattr(clean, field))
    assert back.peak == clean.peak and back.valley == clean.valley


def test_unknown_enclosed_volume_is_estimated_from_the_tube_bore(tmp_path):
    clean = analytical_segment("SI-B46-T22")
    write_csv(clean, tmp_path / "b46.csv")
    back = load_csv(tmp_path / "b46.csv")
    assert back.V0_ml == pytest.approx(np.pi * 6.35**2 * clean.l_mm[0] / 1000)


def test_a_curve_that_ends_while_falling_is_refused(tmp_path):
    clean = analytical_segment("SI-B46-T20")
    raw = mpx5100_like(clean, 6)
    raw = raw[raw[:, 0] < 15.0]  # stops on the softening branch
    with pytest.raises(InputError, match="still falls"):
        load_csv(write_table(tmp_path / "run.csv", raw))


GOOD_ROWS = [f"{0.1 * k:.1f},{2.0 * k:.1f},20.0" for k in range(12)]


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "the file is empty"),
        ("volume_ml,pressure_kpa\n" + "\n".join(GOOD_ROWS), "line 1: the header must be"),
        ("volume_ml,pressure_kpa,length_mm,t_s\n" + "\n".join(GOOD_ROWS), "header must be"),
        (HEADER + "\n" + "\n".join(GOOD_ROWS[:5]), "5 data rows; a curve needs at least 10"),
        (HEADER + "\n" + "\n".join([*GOOD_ROWS[:3], "0.3,abc,20"]), "line 5, column pressure_kpa"),
        (HEADER + "\n" + "\n".join([*GOOD_ROWS[:3], "0.3,nan,20"]), "not a finite number"),
        (HEADER + "\n" + "\n".join([*GOOD_ROWS[:3], "0.3,1,20,4"]), "line 5: expected 3 values"),
        (HEADER + "\n" + "\n".join([*GOOD_ROWS[:3], "0.1,6,20"]), "line 5: volume_ml 0.1 does not"),
        (
            HEADER + "\n" + "\n".join(f"{k // 2 * 0.1:.1f},{k},20" for k in range(12)),
            "6 distinct volumes; a curve needs at least 10",
        ),
        (HEADER + "\n3.0,0,20\n" + "\n".join(GOOD_ROWS[4:]), "first volume_ml must be"),
        (HEADER + "\n" + "\n".join([*GOOD_ROWS[:3], "0.3,6,-1"]), "column length_mm: must be > 0"),
        # long enough to be parsed at once: the line still named, blank lines counted
        (HEADER + "\n\n" + "\n".join([*GOOD_ROWS, "0.5,6,20"]), "line 15: volume_ml 0.5 does not"),
        (HEADER + "\n" + "\n".join([*GOOD_ROWS, "1.2,6,0"]), "line 14, column length_mm"),
    ],
)
def test_bad_files_are_refused_with_one_line(tmp_path, text, message):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(InputError, match=message) as info:
        load_csv(path)
    assert str(info.value).startswith(str(path)) and "\n" not in str(info.value)


def test_rows_at_a_repeated_volume_are_averaged(tmp_path):
    """A 1 kHz-like log whose volume was written to two decimals: each volume ten times,
    the pressures of one volume averaged into one row (their mean, checked here)."""
    clean = analytical_segment("SI-B46-T22")
    v = np.round(np.arange(0.0, clean.v_max_ml, 0.001), 2)
    rng = np.random.default_rng(7)
    p = clean.pressure_kpa(v) + rng.normal(0.0, 0.3, len(v))
    table = np.column_stack([v, p, clean.length_mm(v)])
    curve = load_csv(write_table(tmp_path / "run.csv", table, fmt="%.2f"))
    assert "rows at a repeated volume averaged" in curve.source
    assert len(curve.branch_bounds) == 3
    assert curve.valley.p_kpa == pytest.approx(clean.valley.p_kpa, abs=0.25)
    assert curve.peak.v_ml == pytest.approx(clean.peak.v_ml, abs=0.6)


def test_missing_file_is_an_input_error(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        load_csv(tmp_path / "nope.csv")


def test_isotonic_regression_matches_scipy():
    from scipy.optimize import isotonic_regression

    rng = np.random.default_rng(7)
    y = np.cumsum(rng.normal(0, 1, 300))
    w = rng.uniform(0.5, 3, 300)
    for increasing in (True, False):
        expected = isotonic_regression(y, weights=w, increasing=increasing).x
        fitted = np.empty_like(y)
        for first, end, value in isotonic_blocks(y, w, increasing):
            fitted[first:end] = value
        np.testing.assert_allclose(fitted, expected, rtol=1e-12, atol=1e-12)
        sse = prefix_isotonic_sse(y, w, increasing)
        for k in (1, 50, 299, 300):
            best = isotonic_regression(y[:k], weights=w[:k], increasing=increasing).x
            assert sse[k] == pytest.approx(np.sum(w[:k] * (y[:k] - best) ** 2), rel=1e-9)


def _isotonic_sse(y, w, increasing):
    from scipy.optimize import isotonic_regression

    if len(y) == 0:
        return 0.0
    best = isotonic_regression(y, weights=w, increasing=increasing).x
    return float(np.sum(w * (y - best) ** 2))


@pytest.mark.parametrize("seed", range(12))
def test_the_rise_fall_rise_fit_is_the_least_squares_one_of_all_breakpoints(seed):
    """The fit (whose search stops early where no breakpoint can do better) against every
    pair of breakpoints tried, each branch fitted by scipy's isotonic regression: the
    same least squared error, to rounding."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(12, 40))
    x = np.linspace(0, 1, n)
    peak, valley = np.sort(rng.uniform(0.2, 0.9, 2))  # a rise-fall-rise, noisy
    y = np.interp(x, [0, peak, valley, 1], [0, 3, 1, 4]) + rng.normal(0, 0.4, n)
    if seed % 2:
        y = np.round(y * 2) / 2  # quantised: ties everywhere
    w = rng.uniform(0.5, 3, n)
    fit = fit_rise_fall_rise(y, w, noise_kpa=0.0)  # three branches, whatever the dip
    assert len(fit.branches) == 3
    fitted = np.empty(n)
    for branch in fit.branches:
        for first, end, value in branch:
            fitted[first:end] = value
    found = float(np.sum(w * (y - fitted) ** 2))
    every = min(
        _isotonic_sse(y[:i], w[:i], True)
        + _isotonic_sse(y[i:j], w[i:j], False)
        + _isotonic_sse(y[j:], w[j:], True)
        for i in range(1, n - 1)
        for j in range(i + 1, n)
    )
    assert found == pytest.approx(every, rel=1e-9, abs=1e-12)


ODD_FIELDS = [
    "",
    " ",
    " 1.5 ",
    '"2.0"',
    "1_0",
    "nan",
    "inf",
    "-1",
    "0x10",
    "1e1",
    "1.0.0",
    "a",
    "\t3",
]
FIELDS = st.one_of(
    st.floats(0, 50, allow_nan=False).map(repr),
    st.integers(0, 50).map(str),
    st.sampled_from(ODD_FIELDS),
)
ROWS = st.lists(st.lists(FIELDS, min_size=2, max_size=4), min_size=0, max_size=14)


def _csv_text(rows, blank_every):
    lines = [HEADER] + [",".join(row) for row in rows]
    if blank_every:
        lines = [
            x for k, line in enumerate(lines) for x in ([line, ""] if k % blank_every else [line])
        ]
    return "\n".join(lines) + "\n"


def _monotone_rows(n):
    return [[repr(0.1 * k), repr(k * k / 10), repr(30 + k)] for k in range(n)]


@settings(max_examples=300)
@example(rows=_monotone_rows(10), blank_every=0, spoil=(4, 1, "nan"))
@example(rows=_monotone_rows(10), blank_every=3, spoil=(9, 1, "inf"))
@example(rows=_monotone_rows(10), blank_every=0, spoil=(6, 2, "-1"))
@given(
    rows=st.one_of(ROWS, st.integers(8, 14).map(_monotone_rows)),
    blank_every=st.sampled_from([0, 0, 3, 5]),
    spoil=st.one_of(
        st.none(), st.tuples(st.integers(0, 13), st.integers(0, 2), st.sampled_from(ODD_FIELDS))
    ),
)
def test_parsing_at_once_reads_what_the_row_by_row_reader_reads(rows, blank_every, spoil):
    """Two parsers of the same data rows: numpy's, at once, and the row-by-row reader
    that names faults. Whatever the first takes, the second takes to the same numbers;
    whatever the second refuses, the first leaves to it."""
    from labrig.model.segments.measured import _numbers_at_once, _numbers_row_by_row

    if spoil and spoil[0] < len(rows) and spoil[1] < len(rows[spoil[0]]):
        rows[spoil[0]][spoil[1]] = spoil[2]
    text = _csv_text(rows, blank_every)
    data = [(n, line) for n, line in enumerate(text.splitlines(), start=1) if line][1:]
    fast = _numbers_at_once(data)
    try:
        slow = _numbers_row_by_row(data, "t.csv")
    except InputError:
        assert fast is None
    else:
        assert fast is None or np.array_equal(fast, slow)
        if rows == _monotone_rows(len(rows)) and not blank_every % 5:
            assert fast is not None  # a clean file takes the fast path
