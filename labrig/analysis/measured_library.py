"""A directory of measured segments: curves from earlier single-segment runs, by name.

The paper predicts combined actuators from the measured curves of their segments. A
single-segment run becomes such a segment with ``labrig library add RUN.h5 --name NAME``:
the mean inflation curve of its averaged repetitions is fitted to the segment's
rise-fall-rise shape (``labrig.model.segments.measured``) and stored as ``NAME.csv`` (the
measured-curve format, ``volume_ml,pressure_kpa,length_mm``) beside ``NAME.json``, its
provenance: the run file (path and SHA-256), its title, start time and specimen, the
repetitions averaged, the labrig version, and the fit's notes.

Everywhere a SEG is accepted (``labrig model path``, scans, protocols), NAME then works
like a library name: ``load_segment`` looks it up here. The directory is the
``library_dir`` a command passes, else ``$LABRIG_LIBRARY``, else ``./library``. Names
cannot shadow the analytical library (B46-T20) or the Gent membranes, and look nothing
like a path.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from labrig._version import __version__
from labrig.errors import InputError
from labrig.model.segments.catalog import find_measured, is_measured_name, resolve_library_dir
from labrig.user_files import MAX_CONFIG_BYTES, read_text_file

LIBRARY_GRID_ML = 0.01


def check_new_name(name: str, directory: Path, replace: bool) -> None:
    """InputError unless ``name`` can be added to the library at ``directory``."""
    from labrig.model.segments.catalog import is_library_name
    from labrig.model.segments.gent import GENT_NAMES

    if not is_measured_name(name):
        raise InputError(
            f"--name {name!r}: use 1-64 letters, digits, '_', '-' or '.', starting with a "
            "letter or digit, not ending in .csv"
        )
    if is_library_name(name) or name.lower() in GENT_NAMES:
        raise InputError(
            f"--name {name!r} is the name of an analytical segment; choose another "
            "(e.g. add the date or the specimen number)"
        )
    existing = find_measured(name, directory)
    if existing is not None and not replace:
        raise InputError(
            f"--name {name!r}: {existing} already exists; choose another name or pass --replace"
        )


@dataclass(frozen=True)
class MeasuredSegment:
    name: str
    csv_path: Path
    provenance_path: Path
    provenance: dict


def sha256_of(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def add_measured(
    name: str,
    v_ml,
    p_kpa,
    l_mm,
    provenance: dict,
    directory: str | Path | None = None,
    *,
    replace: bool = False,
    where: str | None = None,
) -> MeasuredSegment:
    """Fit a measured mean curve to the segment's shape and store it with its provenance.

    The raw mean goes the one route every table takes (``curve_from_table``: resolution,
    tabulated or fitted, zero at v = 0, linear extension), so a library segment is what
    a CSV of the same data would give; what was done is recorded in the provenance.
    ``where`` names the data's origin in errors (the run file).
    """
    from labrig.model.segments.measured import curve_from_table, write_csv

    folder = resolve_library_dir(directory)
    check_new_name(name, folder, replace)
    table = np.column_stack([np.asarray(x, dtype=float) for x in (v_ml, p_kpa, l_mm)])
    curve = curve_from_table(table, name=name, where=where or f"measured segment {name}")
    folder.mkdir(parents=True, exist_ok=True)
    csv_path = folder / f"{name}.csv"
    provenance_path = folder / f"{name}.json"
    write_csv(curve, csv_path)
    record = dict(provenance)
    record["curve"] = {
        "samples": len(curve.v_ml),
        "v_max_ml": float(curve.v_max_ml),
        "peak": None if curve.peak is None else vars(curve.peak),
        "valley": None if curve.valley is None else vars(curve.valley),
        "fit": curve.source.split(" (", 1)[-1].rstrip(")"),
    }
    provenance_path.write_text(json.dumps(record, indent=2) + "\n", encoding="utf-8")
    return MeasuredSegment(name, csv_path, provenance_path, record)


def list_measured(directory: str | Path | None = None) -> list[MeasuredSegment]:
    """Every measured segment in the library, by name."""
    folder = resolve_library_dir(directory)
    out = []
    for csv_path in sorted(folder.glob("*.csv")) if folder.is_dir() else []:
        provenance_path = csv_path.with_suffix(".json")
        try:
            text = read_text_file(provenance_path, what="provenance", max_bytes=MAX_CONFIG_BYTES)
            provenance = json.loads(text)
        except (InputError, ValueError):
            provenance = {}
        out.append(MeasuredSegment(csv_path.stem, csv_path, provenance_path, provenance))
    return out


def add_from_run(
    run_path: Path, name: str, directory: str | Path | None = None, *, replace: bool = False
) -> MeasuredSegment:
    """``labrig library add``: the mean inflation curve of a single-segment run, stored
    as measured segment ``name`` (see the module docstring)."""
    from dataclasses import replace as with_changes

    from labrig.analysis.analyse import analyse, settings_for
    from labrig.analysis.curves import INFLATE
    from labrig.analysis.results import now_iso
    from labrig.analysis.runfile import load_run

    record = load_run(run_path)
    specimen = record.protocol.specimen.segments
    if len(specimen) != 1:
        raise InputError(
            f"{run_path}: the specimen has {len(specimen)} segments ({' + '.join(specimen)}); "
            "a measured segment comes from a single-segment run"
        )
    check_new_name(name, resolve_library_dir(directory), replace)
    # a finer grid than the review's: the shape fit bins the table again, and its zero
    # at v = 0 is extrapolated from the first bins, which must be narrow where the
    # pressure rises steeply
    settings = with_changes(settings_for(record), compare_model=False, grid_step_ml=LIBRARY_GRID_ML)
    result = analyse(run_path, record=record, settings=settings)
    if result.mean_p is None:
        raise InputError(f"{run_path}: no repetition completed; nothing to average")
    if result.mean_l is None:
        raise InputError(
            f"{run_path}: the run has no length (camera) log; a segment needs l(v) as well"
        )
    fittings_mm = record.protocol.specimen.fittings_length_mm
    p = result.mean_p[INFLATE].mean
    # the segment's own length: the model adds the fittings of the actuator it builds
    length = result.mean_l[INFLATE].mean - fittings_mm
    # The camera sees far fewer points than the 1 kHz pressure (2 frames per second at
    # 60 mL/min is one every 0.5 mL, the paper's every 2 mL): the length is interpolated
    # between frames and held at the nearest frame's value beyond them, so the table
    # keeps every pressure point from v = 0.
    seen = np.isfinite(length)
    if seen.sum() < 2:
        raise InputError(f"{run_path}: fewer than two camera frames in the averaged inflation")
    grid = result.grid_ml
    length = np.interp(grid, grid[seen], length[seen])
    usable = np.isfinite(p)
    provenance = {
        "name": name,
        "created": now_iso(),
        "labrig": __version__,
        "run": {
            "path": str(Path(run_path).resolve()),
            "sha256": sha256_of(Path(run_path)),
            "title": record.title,
            "start_time": record.start_time,
            "status": record.status,
            "specimen": list(specimen),
            "fittings_length_mm": fittings_mm,
        },
        "repetitions_averaged": list(result.averaged),
        "grid_step_ml": result.settings.grid_step_ml,
        "length": "the marker distance minus the run's fittings_length_mm",
    }
    return add_measured(
        name,
        result.grid_ml[usable].tolist(),
        p[usable].tolist(),
        length[usable].tolist(),
        provenance,
        directory,
        replace=replace,
        where=f"{run_path} (mean inflation curve)",
    )
