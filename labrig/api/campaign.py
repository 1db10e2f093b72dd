"""A campaign of runs as one table: ``labrig.open_runs`` and ``labrig runs DIR``.

One row per run file: what was run (title, protocol, specimen, seed, date), how it
ended (status, reason, the writer's flags), the RMSE against the model (kPa, mm) and,
for each snap-through the model predicts, the measured volume (mL), pressure jump (kPa)
and length jump (mm) beside the model's and the error (measured minus model), and the
energies of the cycle and of each snap, measured and model.

The snaps are counted as the paper counts transitions: they are the
``paper_transitions`` of ``labrig compare --json`` whose ``type`` is ``snap`` (the
unstable ones; the events at one supplied volume are one, with their relative jumps
compounded), in its order, numbered ``snap1_...``, ``snap2_...``; a
run with fewer snaps has nulls there. A run without a comparison says why in ``note``;
a file that cannot be read is a row with its ``error``, so one bad file does not hide
the rest.
"""

from __future__ import annotations

import glob
import math
import warnings
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from labrig.errors import InputError, LabrigError

from .run import Run, RunOpenWarning

if TYPE_CHECKING:
    import pandas as pd

# the measured quantity of ``compare --json`` -> (its model field, the row's suffix)
SNAP_FIELDS = {
    "v_meas_ml": ("v_ml", "v", "ml"),
    "dp_meas_kpa": ("dp_kpa", "dp", "kpa"),
    "dl_meas_mm": ("dl_mm", "dl", "mm"),
}

# the snap's energies of ``compare --json`` a row carries under their own names
SNAP_ENERGY = ("dE_model", "cycle_dE_measured", "cycle_dE_model")


def run_files(runs: str | Path | Iterable[str | Path]) -> list[Path]:
    """The run files named by a folder (its ``*.h5``), a glob pattern, a file, or a
    list of those, in sorted order per item; ``InputError`` if none is found."""
    items = [runs] if isinstance(runs, str | Path) else list(runs)
    found: list[Path] = []
    for item in items:
        path = Path(item)
        if path.is_dir():
            found += sorted(path.glob("*.h5"))
        elif glob.has_magic(str(item)):
            found += sorted(Path(p) for p in glob.glob(str(item)))
        elif path.is_file():
            found.append(path)
        elif path.exists():
            raise InputError(f"{item}: not a regular file or a folder (a device or a pipe)")
        else:
            raise InputError(f"{item}: no such file or folder")
    if not found:
        raise InputError(f"{', '.join(str(i) for i in items)}: no run files (*.h5) found")
    return found


def _opened(path: Path) -> tuple[dict[str, Any], Run | None]:
    """The run's columns of its rows (its metadata), and the run; or the file's
    ``error`` and None."""
    row: dict[str, Any] = {"file": str(path)}
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RunOpenWarning)  # the row carries the flags
            run = Run(path)
        meta = run.metadata
    except LabrigError as exc:
        row["error"] = str(exc)
        return row, None
    row.update(
        title=meta["title"],
        protocol=meta["protocol"],
        specimen=" + ".join(meta["specimen"]),
        seed=meta["seed"],
        date=meta["start_time"],
        status=meta["status"],
        reason=meta["reason"],
        repetitions=meta["repetitions"],
        writer_open=meta["writer_open"],
        live=meta["live"],
    )
    return row, run


def run_row(path: Path) -> dict[str, Any]:
    """One run's row of the campaign table (see the module docstring)."""
    row, run = _opened(path)
    if run is None:
        return row
    try:
        document = run.comparison_document
    except LabrigError as exc:  # no comparison (none asked for, no repetition done)
        row["note"] = str(exc)
        return row
    for name, value in document["rmse"].items():
        row[f"rmse_{name}"] = value
    for name, value in document["energy"].items():
        row[f"energy_{name}"] = value
    snaps = [t for t in document["paper_transitions"] if t["type"] == "snap"]
    for k, snap in enumerate(snaps, 1):
        row[f"snap{k}_phase"] = snap["phase"]
        for measured, (model, short, unit) in SNAP_FIELDS.items():
            seen, predicted = snap[measured], snap[model]  # compare's JSON: a number or null
            row[f"snap{k}_{short}_{unit}"] = seen
            row[f"snap{k}_{short}_model_{unit}"] = predicted
            error = None if seen is None or predicted is None else seen - predicted
            row[f"snap{k}_{short}_error_{unit}"] = error
        for name in SNAP_ENERGY:
            row[f"snap{k}_{name}"] = snap[name]
    return row


def campaign_rows(runs: str | Path | Iterable[str | Path]) -> list[dict[str, Any]]:
    """Every run's row, each with every column of the table (null where it has none),
    so that the JSON, the CSV and the DataFrame are the same rectangle."""
    return rectangle([run_row(path) for path in run_files(runs)])


def protocol_columns(run: Run) -> dict[str, Any]:
    """What a run's protocol asked for, to filter a campaign on: the infusions' and
    withdrawals' rate (mL/min; NaN where the steps' rates differ), the largest volume
    supplied (mL), the repetitions and the specimen's fittings (mm)."""
    from labrig.config.protocol import InfuseStep, WithdrawStep, iter_steps, plan

    protocol = run.protocol
    steps = [step for _, step in iter_steps(protocol.steps)]
    rates = {
        "rate_ml_min": {s.infuse.rate_ml_min for s in steps if isinstance(s, InfuseStep)},
        "withdraw_rate_ml_min": {
            s.withdraw.rate_ml_min for s in steps if isinstance(s, WithdrawStep)
        },
    }
    return {
        **{name: values.pop() if len(values) == 1 else math.nan for name, values in rates.items()},
        "max_volume_ml": plan(protocol).max_volume_ml,
        "repetitions": run.n_repetitions,
        "fittings_length_mm": protocol.specimen.fittings_length_mm,
    }


def transition_rows(path: Path) -> list[dict[str, Any]]:
    """A run's rows of the long campaign table: one per transition of ``compare
    --json``'s ``paper_transitions`` and ``unpredicted``, in the vocabulary's names,
    each with the run's metadata and its protocol's parameters; a run without any is
    one row with its ``note`` or ``error``."""
    from labrig.vocabulary import ALIASES

    head, run = _opened(path)
    if run is None:
        return [head]
    head.update(protocol_columns(run))
    try:
        document = run.comparison_document
    except LabrigError as exc:
        return [{**head, "note": str(exc)}]
    rename = ALIASES["comparison"]
    transitions = document["paper_transitions"] + [
        {"type": "unpredicted", **t} for t in document["unpredicted"]
    ]
    # compare's rows carry the vocabulary's names beside the JSON's: keep those alone
    rows = [{**head, **{k: v for k, v in t.items() if k not in rename}} for t in transitions]
    return rows or [{**head, "note": "the model predicts no transition and none was seen"}]


def rectangle(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Every row with every column (null where it has none), ``note`` and ``error``
    last and always there: the JSON, the CSV and the DataFrame are the same rectangle,
    whichever runs it holds."""
    columns: dict[str, None] = {}
    for row in rows:
        columns.update(dict.fromkeys(row))
    for rare in ("note", "error"):  # last: most rows have none
        columns.pop(rare, None)
        columns[rare] = None
    return [{name: row.get(name) for name in columns} for row in rows]


def open_runs(runs: str | Path | Iterable[str | Path], long: bool = False) -> pd.DataFrame:
    """A campaign as one DataFrame, one row a run (the table ``labrig runs`` prints):
    ``runs`` is a folder, a glob pattern (``"runs/*demo*.h5"``), a file or a list.

    Columns: file, title, protocol, specimen, seed, date (a UTC datetime), status,
    reason, repetitions, writer_open, live; ``rmse_<phase>_pressure_kpa`` (kPa) and
    ``rmse_<phase>_length_mm`` (mm); for the k-th snap-through the model predicts,
    counted as the paper counts transitions (``labrig compare --json``'s
    ``paper_transitions`` of type ``snap``: the events at one supplied volume are
    one), ``snapk_phase`` and the measured ``snapk_v_ml`` (mL), ``snapk_dp_kpa`` (kPa),
    ``snapk_dl_mm`` (mm), each with its ``_model_`` and ``_error_`` (measured minus
    model) twin, e.g. ``snap1_v_model_ml``, ``snap1_v_error_ml``; the snap's
    ``snapk_dE_model`` (the model's dE), ``snapk_cycle_dE_measured`` and
    ``snapk_cycle_dE_model`` (null for a deflation snap); the cycle's energies (mJ)
    ``energy_stored_measured_mj``, ``energy_released_measured_mj``, their ``_model_``
    twins and ``energy_released_by_snaps_model_mj`` (``compare --json``'s ``energy``,
    defined in the Python API reference); ``note`` (why a run has no comparison) and
    ``error`` (why a file could not be read). A missing value is NaN (None in a text
    column).

    ``long=True``: one row per transition of every run instead (``compare --json``'s
    ``paper_transitions``, then its ``unpredicted`` with type ``unpredicted``), in the
    vocabulary's names (direction, v_model_ml, v_measured_ml, dp_*, dl_*, dE_model, the
    energies), each with the run's metadata and its protocol's ``rate_ml_min``,
    ``withdraw_rate_ml_min``, ``max_volume_ml``, ``repetitions`` and
    ``fittings_length_mm``, to filter and group on."""
    import pandas as pd

    rows = (
        rectangle([row for path in run_files(runs) for row in transition_rows(path)])
        if long
        else campaign_rows(runs)
    )
    table = pd.DataFrame(rows)
    if "date" in table.columns:  # ISO 8601 text in the JSON, a datetime here
        table["date"] = pd.to_datetime(table["date"], utc=True, errors="coerce")
    return table
