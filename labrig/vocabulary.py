"""Column names: one name for one quantity in every table the Python API returns and in
``labrig compare --json``'s rows.

The command line's JSON, the CSV export and the run file keep the names their readers
rely on (``phase``, ``v_meas_ml``, ``direction`` as +1/-1, ...); a table made of them
carries those and, beside them, the names below, so a notebook can join and filter the
tables of a run, a campaign and the model on the same columns. The Python API
reference's table is this one. A leaf module: the analysis and the API both read it.
"""

from __future__ import annotations

import re
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import pandas as pd

INFLATE, DEFLATE = "inflate", "deflate"

#: name -> what it is (units in the name); the API reference prints this table
VOCABULARY: dict[str, str] = {
    "direction": 'the phase: "inflate" or "deflate"',
    "direction_sign": "the phase as +1 (inflate) or -1 (deflate), the files' `direction`",
    "volume_ml": "supplied volume along a curve or path (mL)",
    "pressure_kpa": "gauge pressure along a curve or path (kPa)",
    "length_mm": "length between the markers: the segments and the fittings (mm)",
    "segments_length_mm": "the segments' lengths summed, without the fittings (mm)",
    "v_ml": "a transition's supplied volume (mL), measured or (in the model's tables) model",
    "dp_kpa": "a transition's pressure jump (kPa)",
    "dl_mm": "a transition's length jump (mm)",
    "v_model_ml": "a compared transition's volume, the model's (mL)",
    "v_measured_ml": "a compared transition's volume, measured (mL)",
    "dp_model_kpa": "a compared transition's pressure jump, the model's (kPa)",
    "dp_measured_kpa": "a compared transition's pressure jump, measured (kPa)",
    "dl_model_mm": "a compared transition's length jump, the model's (mm)",
    "dl_measured_mm": "a compared transition's length jump, measured (mm)",
    "type": '"snap" (at constant volume), "stable", or "unpredicted" (measured alone)',
    "on_model_curve": "a measured transition no predicted one explains is on the model's curve",
    "rate_ml_min": "the protocol's infusion rate (mL/min; NaN where its steps differ)",
    "withdraw_rate_ml_min": "the protocol's withdrawal rate (mL/min; NaN where they differ)",
    "max_volume_ml": "the largest volume the protocol supplies (mL)",
    "fittings_length_mm": "the specimen's fittings between the markers (mm)",
    "alpha": "segments right of their pressure peak before the transition",
    "beta": "segments right of their pressure peak after the transition",
    "stable": "False for a snap at constant volume",
    "dE": "(E_after - E_before) / E_before of the model (see Energy)",
    "dv": "the fraction of the supplied volume that changes segment",
    "dl": "(l_after - l_before) / l_before, l the segments' lengths",
    "dp": "(p_after - p_before) / p_before",
    "dE_model": "the model's dE of a compared transition",
    "energy_before_model_mj": "the model's stored energy before the transition (mJ)",
    "energy_after_model_mj": "the model's stored energy after the transition (mJ)",
    "cycle_energy_before_measured_mj": "the inflation's work up to the transition (mJ)",
    "cycle_energy_before_model_mj": "the same on the model's curve (mJ)",
    "cycle_energy_returned_measured_mj": "the work deflation returns from there (mJ)",
    "cycle_energy_returned_model_mj": "the same on the model's curve (mJ)",
    "cycle_dE_measured": "(returned - before) / before, measured (see Energy)",
    "cycle_dE_model": "the same on the model's curves",
    "v_i_ml": "the segments' volumes along a path, one list per segment (mL): a table's v1_ml, ...",
    "events": "the path's events a transition counted as the paper counts is made of",
    "n_events": "how many of the path's events a transition is made of",
    "actuator": "a scanned actuator's rank among the combinations",
    "first": "the scan's row of a transition's first event",
    "repetition": "the repetition's number, from 1",
    "time_s": "time on the run's clock (s)",
    "pressure_measured_kpa": "the averaged repetitions' pressure on the grid (kPa)",
    "pressure_model_kpa": "the model's pressure on the grid (kPa)",
    "length_measured_mm": "the averaged repetitions' length on the grid (mm)",
    "length_model_mm": "the model's length on the grid (mm)",
    "out_of_range": "the sensor's reading was outside its band",
    "infused_ml": "volume the pump infused so far (mL)",
    "withdrawn_ml": "volume the pump withdrew so far (mL)",
    "state": "the pump's state",
    "ok": "both markers were found in the frame",
    "v_start_ml": "where a measured transition starts (mL)",
    "v_end_ml": "where a measured transition ends (mL)",
    "v_std_ml": "the spread of a transition's volume over the repetitions (mL)",
    "by_pressure": "the transition was seen in the pressure",
    "by_length": "the transition was seen in the length",
    "seen": "repetitions that saw the transition",
    "of": "repetitions averaged",
    "status": "how a run or repetition ended: running, complete, aborted, faulted",
    "reason": "why it ended so",
    "t_start_s": "a repetition's start on the run's clock (s)",
    "t_end_s": "a repetition's end on the run's clock (s)",
}

#: numbered names, and a campaign's columns, as patterns
PATTERNS: dict[str, str] = {
    r"file|title|protocol|specimen|seed|date|repetitions|writer_open|live|note|error": (
        "a campaign's run: what ``Run.metadata`` holds (date a datetime)"
    ),
    r"rmse_(inflate|deflate)_(pressure_kpa|length_mm)": "RMSE of the mean against the model",
    r"energy_(stored|released)_(measured|model)_mj|energy_released_by_snaps_model_mj": (
        "the cycle's energies (see Energy)"
    ),
    r"snap\d+_(phase|(v|dp|dl)(_model|_error)?_(ml|kpa|mm)|dE_model|cycle_dE_(measured|model))": (
        "the k-th snap's fields: compare --json's row names, measured plain"
    ),
    r"n_(pressure|pump|length|force)": "samples a log holds",
    r"v\d+_ml": "the i-th segment's volume (mL)",
    r"segment\d+": "the i-th segment's name",
    r"[xy][12]_px": "a marker's position in the frame (pixels)",
    r"rep_\d+_(pressure_kpa|length_mm)": "one repetition's curve on the grid",
    r"std_(pressure_kpa|length_mm)": "the averaged repetitions' spread on the grid",
}

#: a table's name kept for the command line's JSON -> its vocabulary name, beside it
ALIASES: dict[str, dict[str, str]] = {
    "comparison": {
        "phase": "direction",
        "v_ml": "v_model_ml",
        "v_meas_ml": "v_measured_ml",
        "dp_kpa": "dp_model_kpa",
        "dp_meas_kpa": "dp_measured_kpa",
        "dl_mm": "dl_model_mm",
        "dl_meas_mm": "dl_measured_mm",
    },
    "model path": {"v_ml": "volume_ml", "p_kpa": "pressure_kpa", "l_mm": "segments_length_mm"},
    "model curve": {"v_ml": "volume_ml", "p_kpa": "pressure_kpa", "l_mm": "segments_length_mm"},
    "scan": {"events": "n_events"},
    "transitions": {"t_s": "time_s"},
    "curves": {
        "mean_pressure_kpa": "pressure_measured_kpa",
        "mean_length_mm": "length_measured_mm",
        "model_pressure_kpa": "pressure_model_kpa",
        "model_length_mm": "length_model_mm",
    },
}


def known(name: str) -> bool:
    """Whether ``name`` is a vocabulary name (or one of its numbered patterns)."""
    return name in VOCABULARY or any(re.fullmatch(p, name) for p in PATTERNS)


def beside(table: pd.DataFrame, aliases: dict[str, str]) -> pd.DataFrame:
    """``table`` with each aliased column's vocabulary name inserted right after it."""
    for old, new in aliases.items():
        if old in table.columns and new not in table.columns:
            table.insert(table.columns.get_loc(old) + 1, new, table[old])
    return table


def beside_fields(row: dict, aliases: dict[str, str]) -> dict:
    """A JSON row with each aliased field's vocabulary name right after it."""
    out = {}
    for name, value in row.items():
        out[name] = value
        if name in aliases:
            out[aliases[name]] = value
    return out


def with_direction_names(table: pd.DataFrame) -> pd.DataFrame:
    """A table whose ``direction`` is +1/-1 (as the files have it): ``direction`` as
    "inflate"/"deflate", the sign kept as ``direction_sign`` beside it."""
    import numpy as np

    if "direction" in table.columns and table["direction"].dtype.kind in "iuf":
        sign = table["direction"].to_numpy()
        at = table.columns.get_loc("direction")
        table["direction"] = np.where(sign > 0, INFLATE, DEFLATE)
        table.insert(at + 1, "direction_sign", sign)
    return table
