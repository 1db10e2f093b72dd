"""A clean staircase's stair edges and the peak and valley estimated from them
(labrig.model.segments.stair_edges), checked against the analytical segments the tables
were sampled from (an independent computation, not the module's own output)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from support.measured_tables import sample_table

from labrig.model.segments.catalog import BRAID_LENGTHS_MM, TUBE_LENGTHS_MM, analytical_segment
from labrig.model.segments.stair_edges import refine_extrema, shows_dip, stair_edges

NAMES = [f"SI-B{b}-T{t}" for b in BRAID_LENGTHS_MM for t in TUBE_LENGTHS_MM]
WITH_DIP = [n for n in NAMES[::3] if analytical_segment(n).peak is not None]


@settings(max_examples=10, deadline=None, derandomize=True)
@given(
    name=st.sampled_from(NAMES),
    spacing_ml=st.floats(0.01, 0.5),
    step_kpa=st.sampled_from([0.01, 0.1, 0.27, 0.5]),
    uniform=st.booleans(),
    seed=st.integers(0, 100),
)
def test_the_clean_curve_crosses_each_edge_level_within_its_gap(
    name, spacing_ml, step_kpa, uniform, seed
):
    """Every row is within half a step of its stair, so between an edge's two rows the
    curve passes the level half-way between the stairs (intermediate value theorem)."""
    curve = analytical_segment(name)
    table = sample_table(curve, spacing_ml, uniform=uniform, round_to_kpa=step_kpa, seed=seed)
    ve, pe, gap, direction, _ = stair_edges(table[:, 0], table[:, 1])
    below = curve.pressure_kpa(ve - gap / 2) - pe
    above = curve.pressure_kpa(ve + gap / 2) - pe
    assert len(ve) > 10
    assert np.all(below * above <= 1e-9), (ve[below * above > 1e-9], pe[below * above > 1e-9])
    assert np.all(np.sign(above - below) == direction)


def test_extrema_from_the_edges_are_nearer_the_clean_curves_than_the_stairs():
    """On every library segment with a dip (a third of the library, 0.1 mL rows, uniform
    and jittered by +-45 %, at 0.27 and 0.5 kPa), the refined peak and valley: their
    mean error at most 0.2 step and a quarter below the stair values' and their worst
    within the stair's half-step band."""
    for step in (0.27, 0.5):
        errors, stair_errors = [], []
        for name in WITH_DIP:
            curve = analytical_segment(name)
            for uniform in (True, False):
                table = sample_table(curve, 0.1, uniform=uniform, round_to_kpa=step, seed=1)
                v, p = table[:, 0], table[:, 1]
                refined = refine_extrema(v, p, v, p)
                if refined is None:  # a dip of a few steps: no two edges per side
                    continue
                v_r, p_r = refined
                i_peak = int(np.argmax(p_r[v_r < curve.valley.v_ml]))
                i_valley = i_peak + int(
                    np.argmin(p_r[i_peak:][v_r[i_peak:] < curve.valley.v_ml + 2])
                )
                for point, i in ((curve.peak, i_peak), (curve.valley, i_valley)):
                    errors.append(abs(p_r[i] - point.p_kpa))
                    stair = p[np.argmin(np.abs(v - point.v_ml))]
                    stair_errors.append(abs(stair - point.p_kpa))
        assert len(errors) >= 20
        assert np.mean(errors) <= 0.2 * step, (step, np.mean(errors))
        assert np.mean(errors) <= 0.75 * np.mean(stair_errors), (step, np.mean(stair_errors))
        assert max(errors) <= 0.75 * step, step


def test_an_undithered_staircase_shows_every_dip_a_step_deep_and_a_noisy_one_none():
    """Rounding is monotone, so an undithered staircase of a rise-fall-rise curve rises,
    falls and rises again, and does so wherever the dip is at least a step deep (plus
    what 0.1 mL rows can miss of a corner valley: 0.1 kPa); a monotone segment's never
    falls. With noise of half a step the rows flicker between levels where the curve
    crosses one: no clean staircase, whatever the dip. Against the library's own dips."""
    for step in (0.27, 0.5):
        for name in NAMES[::2]:
            curve = analytical_segment(name)
            dip = 0.0 if curve.peak is None else curve.peak.p_kpa - curve.valley.p_kpa
            for uniform in (True, False):
                table = sample_table(curve, 0.1, uniform=uniform, round_to_kpa=step, seed=2)
                shown = shows_dip(table[:, 0], table[:, 1])
                if dip >= step + 0.1 or curve.peak is None:
                    assert shown == (curve.peak is not None), (name, step, uniform, dip)
                noisy = sample_table(
                    curve, 0.1, uniform=uniform, round_to_kpa=step, noise_kpa=step / 2, seed=2
                )
                assert not shows_dip(noisy[:, 0], noisy[:, 1]), (name, step, uniform)


def test_a_corner_inside_a_row_gap_keeps_the_plateaus_row_at_the_jump():
    """A curve flat at 10.03 kPa up to a corner at 5.0 mL, then 2 kPa/mL (a braid
    contact), rows every 0.15 mL rounded to 0.1 kPa: the plateau at 10.0 kPa ends at
    the row before the corner and the next row is two steps up. The row at the jump is
    kept a quarter step up (10.025 kPa, within 0.005 kPa of the clean curve there),
    so a line from it to the next row has the steep slope of the clean curve after
    the corner, not the plateau centre's spread one."""
    from labrig.model.segments.measured import collapse_plateaus, keep_corner_rows

    v = np.arange(0.0, 8.0, 0.15)
    clean = np.where(v < 5.0, 10.03, 10.03 + 2.0 * (v - 5.0))
    p = np.round(clean / 0.1) * 0.1
    length = np.ones_like(v)
    last = int(np.flatnonzero(v < 5.0)[-1])  # the plateau's row before the corner
    assert p[last] == pytest.approx(10.0) and p[last + 1] - p[last] >= 0.2 - 1e-9
    v_c, p_c, _, _ = collapse_plateaus(v, p, length)
    v_k, p_k, _, _ = keep_corner_rows(v, p, length, 0.1)
    assert v[last] in v_k and v[last] not in v_c
    kept = p_k[np.flatnonzero(v_k == v[last])[0]]
    assert kept == pytest.approx(10.025) and abs(kept - clean[last]) <= 0.006
    assert np.all(np.diff(p_k) > 0)
    # the slope into the first row after the corner: from the kept row as the clean
    # curve's within a row's rounding; from the plateau's centre spread well below it
    i = int(np.flatnonzero(v_k == v[last + 1])[0])
    kept_slope = (p_k[i] - p_k[i - 1]) / (v_k[i] - v_k[i - 1])
    j = int(np.flatnonzero(v_c == v[last + 1])[0])
    centre_slope = (p_c[j] - p_c[j - 1]) / (v_c[j] - v_c[j - 1])
    clean_slope = (clean[last + 1] - clean[last]) / (v[last + 1] - v[last])
    assert abs(kept_slope - clean_slope) <= 0.1 / 0.15
    assert centre_slope < 0.3 * clean_slope
