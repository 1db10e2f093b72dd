"""Measured tables as other tools and rigs write them, made from known clean curves:
resampled at any spacing (uniform or not), rounded to decimals or to an ADC's step,
with sensor noise. Shared by the property tests, the scan test and the benchmark."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.interpolate import PchipInterpolator

from labrig.model.actuator.equilibria import Actuator
from labrig.model.actuator.path import quasi_static_path
from labrig.model.actuator.transitions import fold_slope_deficit, transitions
from labrig.model.segments.curve import SegmentCurve
from labrig.model.segments.measured import HEADER

# the USB-6009's 14-bit step (differential, ±10 V) through the MPX5100: 20 V / 2^14 over
# 45 mV/kPa (the 0.009 x 5 V sensitivity)
ADC_STEP_KPA = 20.0 / 2**14 / 0.045


def rise_fall_rise(
    name: str,
    peak_v_ml: float,
    peak_kpa: float,
    dip_kpa: float,
    valley_v_ml: float,
    end_v_ml: float,
) -> SegmentCurve:
    """A synthetic segment: monotone PCHIP from (0, 0) up to the peak, down to the
    valley and up to 300 kPa at ``end_v_ml`` (the extrema sit exactly on the nodes, so
    the shape is rise-fall-rise by construction), sampled on 400 rows."""
    v_nodes = [0.0, 0.35 * peak_v_ml, peak_v_ml, valley_v_ml, 0.5 * (valley_v_ml + end_v_ml)]
    p_nodes = [0.0, 0.8 * peak_kpa, peak_kpa, peak_kpa - dip_kpa, peak_kpa + 10.0]
    shape = PchipInterpolator([*v_nodes, end_v_ml], [*p_nodes, 300.0])
    v = np.linspace(0.0, end_v_ml, 400)
    return SegmentCurve(name, v, shape(v), 30.0 + 0.5 * v, V0_ml=2.5, source="synthetic")


def sample_table(
    curve: SegmentCurve,
    spacing_ml: float,
    *,
    uniform: bool = True,
    round_to_kpa: float | None = None,
    noise_kpa: float = 0.0,
    seed: int = 0,
    max_rows: int = 50_000,
) -> np.ndarray:
    """Rows (volume_ml, pressure_kpa, length_mm) of ``curve`` every ``spacing_ml`` on
    average (jittered by up to +-45 % of it if not ``uniform``), with Gaussian noise and
    then rounding to a multiple of ``round_to_kpa`` (as an ADC quantises noisy input)."""
    rng = np.random.default_rng(seed)
    v_end = curve.v_max_ml
    rows = int(min(max_rows, max(20, round(v_end / spacing_ml) + 1)))
    v = np.linspace(0.0, v_end, rows)
    if not uniform:
        step = v[1] - v[0]
        v[1:-1] += rng.uniform(-0.45, 0.45, rows - 2) * step
    p = curve.pressure_kpa(v) + (rng.normal(0.0, noise_kpa, rows) if noise_kpa else 0.0)
    if round_to_kpa:
        p = np.round(p / round_to_kpa) * round_to_kpa
    return np.column_stack([v, p, curve.length_mm(v)])


def write_table(table: np.ndarray, path: Path) -> Path:
    lines = [",".join(HEADER)]
    lines += [f"{float(v)!r},{float(p)!r},{float(length)!r}" for v, p, length in table]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def snap_volumes(curves) -> list[float]:
    """Volumes of the unstable transitions (snaps) on the inflation path."""
    return [v for v, _ in snaps(curves)]


def unresolved_fold_pair(snap, tables) -> bool:
    """Whether a clean snap (``snap_details``) is a fold pair whose slope deficit the
    measured tables (``transitions.table_resolution``) do not resolve over its flow: not
    a snap those tables can show (the criterion of ``transitions``)."""
    _, _, flow_ml, same_branches, deficit = snap
    return same_branches and not tables.resolves_fold_pair(deficit, flow_ml)


def dip_hidden_by_step(clean_curves, step_kpa: float) -> bool:
    """Whether a clean segment's dip (peak minus valley) is shallower than the tables'
    rounding step: then no level need lie between its peak and its valley, and its
    staircase may rise all along (SI-B40-T26's 0.05 kPa dip at 0.27 or 0.5 kPa). The
    table does not hold the dip, and an actuator of that segment is another actuator:
    its snaps are not asked of it. A dip at least a step deep always shows in a
    staircase (rounding is monotone: values a step apart round to different levels)."""
    return any(
        c.peak is not None and c.peak.p_kpa - c.valley.p_kpa < step_kpa for c in clean_curves
    )


def snaps(curves) -> list[tuple[float, float]]:
    """(volume, size of the pressure jump in kPa) of each snap on the inflation path."""
    return [(v, dp) for v, dp, *_ in snap_details(curves)]


def snap_details(curves) -> list[tuple[float, float, float, bool, float]]:
    """(volume, size of the pressure jump in kPa, internal flow in mL, whether it lands
    on the branches it left, its slope deficit in kPa/mL: ``fold_slope_deficit``) of
    each snap on the inflation path."""
    path = quasi_static_path(Actuator(list(curves)))
    return [
        (
            t.v_ml,
            abs(t.post.p_kpa - t.pre.p_kpa),
            max(b - a for a, b in zip(t.pre.v_i_ml, t.post.v_i_ml, strict=True)),
            t.pre.branches == t.post.branches,
            fold_slope_deficit(curves, t.pre, t.post),
        )
        for t in transitions(path)
        if not t.stable
    ]


def noisy_synthetic_pair(seed: int, case: int):
    """The ``case``-th random noisy pair of the generator seeded ``seed`` (the
    benchmark's and the regression tests' draws): the clean curves and the table settings."""
    rng = np.random.default_rng(seed)
    for k in range(case + 1):
        shapes = []
        for name in "AB":
            peak_v, peak_kpa = rng.uniform(3, 8), rng.uniform(30, 45)
            dip, valley_after, end_after = (
                rng.uniform(2, 10),
                rng.uniform(3, 15),
                rng.uniform(20, 30),
            )
            shapes.append(
                rise_fall_rise(
                    name, peak_v, peak_kpa, dip, peak_v + valley_after, peak_v + end_after
                )
            )
        if abs(shapes[0].peak.p_kpa - shapes[1].peak.p_kpa) < 0.4:
            assert k != case, "a pair with equal peaks (skipped by the benchmark)"
            continue
        noise = rng.choice([0.1, 0.3])
        spacing = max(
            min(10 ** rng.uniform(np.log10(0.0005), np.log10(0.5)), (0.02 / noise) ** 2), 0.0005
        )
        rounding = rng.choice([0, 0.027, 0.27])
    return shapes, float(noise), float(spacing), float(rounding) or None, 2 * case
