"""The live series against a direct computation: each pressure bin is the mean of its
samples, each point's volume the pump log interpolated at its time, however the
samples were split into appends; no point is shown before its volume is known."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from labrig.live.series import RepetitionSeries

BIN_S = 0.05


def direct(t, p, flagged, pump_t, pump_v):
    """Bins closed by a later sample, their means, at the bin centres; volumes by
    interpolation where the pump log covers the centre."""
    bins = {}
    for ti, pi, fi in zip(t, p, flagged, strict=True):
        if not fi:
            bins.setdefault(int(np.floor(ti / BIN_S)), []).append(pi)
    last_sample_bin = int(np.floor(t[~flagged][-1] / BIN_S)) if (~flagged).any() else None
    out = []
    for b in sorted(bins):
        centre = (b + 0.5) * BIN_S
        if b == last_sample_bin or centre > pump_t[-1]:
            continue  # still filling, or no volume yet
        out.append((centre, float(np.interp(centre, pump_t, pump_v)), float(np.mean(bins[b]))))
    return out


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(20, 400),
    cuts=st.lists(st.integers(1, 399), max_size=8),
    pump_cut=st.integers(1, 9),
    seed=st.integers(0, 2**16),
)
def test_points_match_a_direct_computation(n, cuts, pump_cut, seed):
    rng = np.random.default_rng(seed)
    t = np.sort(rng.uniform(0.0, 2.0, n))
    p = rng.normal(10.0, 1.0, n)
    flagged = rng.random(n) < 0.1
    pump_t = np.linspace(0.0, 2.2, 10)
    pump_v = np.cumsum(rng.uniform(0.0, 0.2, 10))

    series = RepetitionSeries(1, bin_s=BIN_S)
    edges = sorted({c for c in cuts if c < n})
    for block in np.split(np.arange(n), edges):
        series.add_pressure(t[block], p[block], flagged[block])
    # no pump reading yet: nothing has a volume
    assert series.pressure_points == []
    series.add_pump(pump_t[:pump_cut], pump_v[:pump_cut])
    series.add_pump(pump_t[pump_cut:], pump_v[pump_cut:])

    expected = direct(t, p, flagged, pump_t, pump_v)
    got = series.pressure_points
    assert len(got) == len(expected)
    if expected:
        np.testing.assert_allclose(np.array(got), np.array(expected), rtol=1e-12, atol=1e-12)


def test_length_keeps_only_frames_with_both_markers():
    series = RepetitionSeries(2)
    series.add_length(
        np.array([0.1, 0.6, 1.1]), np.array([70.0, np.nan, 71.0]), [True, False, True]
    )
    series.add_pump(np.array([0.0, 1.0]), np.array([0.0, 1.0]))
    assert series.length_points == [(0.1, 0.1, 70.0)]  # 1.1 s waits for a later reading
    series.add_pump(np.array([2.0]), np.array([3.0]))
    assert np.allclose(series.length_points, [(0.1, 0.1, 70.0), (1.1, 1.2, 71.0)])
