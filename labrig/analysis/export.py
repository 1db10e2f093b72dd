"""A run as CSV files, for tools that do not read HDF5.

One file per raw log per repetition (``rep_01_pressure.csv``, ``rep_01_pump.csv``,
``rep_01_length.csv``) and, from the analysis, the curves on the volume grid per phase
(``curves_inflate.csv``, ``curves_deflate.csv``: every repetition, the mean and spread,
the model), the measured transitions and, with a model, the comparison of transitions.
Column names carry their units the way labrig's names do everywhere (``time_s``,
``pressure_kpa``, ``volume_ml``; ``_px`` for pixels); values are written at full
precision (the shortest text that reads back to the same number), NaN as ``nan``.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from labrig.analysis.curves import PHASES, last_reading, pump_path, volume_at
from labrig.analysis.results import AnalysisResult
from labrig.analysis.runfile import RunRecord

RAW_COLUMNS = {
    "pressure": [("value", "pressure_kpa"), ("out_of_range", "out_of_range")],
    "pump": [
        ("value", "volume_ml"),
        ("infused", "infused_ml"),
        ("withdrawn", "withdrawn_ml"),
        ("state", "state"),
    ],
    "length": [
        ("value", "length_mm"),
        ("x1", "x1_px"),
        ("y1", "y1_px"),
        ("x2", "x2_px"),
        ("y2", "y2_px"),
        ("ok", "ok"),
    ],
}


def _text(values: np.ndarray) -> list[str]:
    if values.dtype.kind == "S":
        return [v.decode() for v in values]
    if values.dtype.kind == "b":
        return ["1" if v else "0" for v in values]
    if values.dtype.kind in "iu":
        return [str(int(v)) for v in values]
    return [repr(float(v)) if math.isfinite(v) else "nan" for v in values.tolist()]


def write_columns(path: Path, columns: dict[str, np.ndarray]) -> None:
    """A CSV with one column per entry (all of one length)."""
    texts = [_text(np.asarray(values)) for values in columns.values()]
    with open(path, "w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(columns)
        writer.writerows(zip(*texts, strict=True))


def export_csv(record: RunRecord, result: AnalysisResult, directory: Path) -> list[Path]:
    """Write every CSV into ``directory`` (created if needed); returns the paths."""
    directory.mkdir(parents=True, exist_ok=True)
    written = []
    pump_before = None  # the previous repetition's last pump reading (``pump_path``)
    for rep in record.repetitions:
        logs = {"pressure": rep.pressure, "pump": rep.pump, "length": rep.length}
        for log, series in logs.items():
            if series is None:
                continue
            columns = {"time_s": series.time_s}
            for field, name in RAW_COLUMNS[log]:
                if field in series.fields:
                    columns[name] = series.fields[field]
            if log == "pressure":  # the supplied volume, aligned as the analysis does
                log_path = pump_path(rep.pump.time_s, rep.pump.fields["value"], pump_before)
                columns["volume_ml"] = volume_at(series.time_s, *log_path)
            path = directory / f"{rep.name}_{log}.csv"
            write_columns(path, columns)
            written.append(path)
        pump_before = last_reading(rep.pump.time_s, rep.pump.fields["value"]) or pump_before
    for phase, name in PHASES.items():
        path = directory / f"curves_{name}.csv"
        write_columns(path, curve_columns(result, phase))
        written.append(path)
    path = directory / "transitions.csv"
    write_columns(path, transition_columns(result))
    written.append(path)
    if result.comparison is not None:
        path = directory / "comparison.csv"
        write_columns(path, comparison_columns(result))
        written.append(path)
    return written


def curve_columns(result: AnalysisResult, phase: int) -> dict[str, np.ndarray]:
    columns = {"volume_ml": result.grid_ml}
    for rep in result.repetitions:
        columns[f"{rep.name}_pressure_kpa"] = rep.p_kpa[phase]
        if rep.l_mm is not None:
            columns[f"{rep.name}_length_mm"] = rep.l_mm[phase]
    for quantity, means in (("pressure_kpa", result.mean_p), ("length_mm", result.mean_l)):
        if means is not None:
            columns[f"mean_{quantity}"] = means[phase].mean
            columns[f"std_{quantity}"] = means[phase].std
    if result.comparison is not None:
        columns["model_pressure_kpa"] = result.comparison.model_p_kpa[phase]
        columns["model_length_mm"] = result.comparison.model_l_mm[phase]
    return columns


def transition_columns(result: AnalysisResult) -> dict[str, np.ndarray]:
    found = [t for rep in result.repetitions for t in rep.transitions]
    names = ("repetition", "direction", "t_s", "v_ml", "v_start_ml", "v_end_ml", "dp_kpa",
             "dl_mm", "by_pressure", "by_length")  # fmt: skip
    return {name: np.array([getattr(t, name) for t in found]) for name in names}


def comparison_columns(result: AnalysisResult) -> dict[str, np.ndarray]:
    matches = result.comparison.matches
    nan = float("nan")

    def column(side: str, name: str, default=nan):
        return np.array(
            [getattr(getattr(m, side), name) if getattr(m, side) else default for m in matches]
        )

    return {
        "direction": np.array([m.direction for m in matches], dtype=int),
        "model_v_ml": column("predicted", "v_ml"),
        "model_alpha": column("predicted", "alpha", -1).astype(int),
        "model_beta": column("predicted", "beta", -1).astype(int),
        "model_stable": column("predicted", "stable", False).astype(bool),
        "model_dp_kpa": column("predicted", "dp_kpa"),
        "model_dl_mm": column("predicted", "dl_mm"),
        "measured_v_ml": column("measured", "v_ml"),
        "measured_v_std_ml": column("measured", "v_std_ml"),
        "measured_dp_kpa": column("measured", "dp_kpa"),
        "measured_dl_mm": column("measured", "dl_mm"),
        "measured_seen": column("measured", "seen", 0).astype(int),
    }
