"""Segments by name: the 36 braided segments (calibrated and the SI's), the Gent
membranes, CSV files.

``load_segment`` is what every command that takes a ``SEG`` argument calls: a library
name (``B46-T20``: L_braid = 46 mm, L_tube = 20 mm, the calibrated segment of
``labrig.model.segments.calibrated``), the SI's uncalibrated segment of the same
geometry (``SI-B46-T20``), a Gent membrane of Fig. S1 (``gent-a``, ``gent-b``,
``gent-c``) or a path to a measured curve (CSV). Analytical curves are built once per
process and cached, because scans build all 36 again and again.
"""

from __future__ import annotations

import os
import re
from functools import cache
from pathlib import Path

from labrig.errors import InputError
from labrig.model.segments.curve import SegmentCurve

BRAID_LENGTHS_MM = tuple(range(40, 51, 2))
TUBE_LENGTHS_MM = tuple(range(20, 31, 2))
LIBRARY_NAMES: tuple[str, ...] = tuple(
    f"B{braid}-T{tube}" for braid in BRAID_LENGTHS_MM for tube in TUBE_LENGTHS_MM
)
SI_PREFIX = "SI-"
SI_NAMES: tuple[str, ...] = tuple(SI_PREFIX + name for name in LIBRARY_NAMES)
_NAME = re.compile(r"(?:SI-)?B(\d+)-T(\d+)")
MEASURED_ENV_VAR = "LABRIG_LIBRARY"
MEASURED_DEFAULT_DIR = Path("library")
_MEASURED_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}")
_VALID = (
    f"B{BRAID_LENGTHS_MM[0]}..B{BRAID_LENGTHS_MM[-1]} x T{TUBE_LENGTHS_MM[0]}.."
    f"T{TUBE_LENGTHS_MM[-1]} in steps of 2, e.g. B46-T20 (calibrated) or SI-B46-T20 (the SI's)"
)


def library_geometry(name: str) -> tuple[int, int]:
    """(L_braid, L_tube) in mm of a library name; InputError for anything else."""
    canonical = name.strip().upper()
    if canonical not in LIBRARY_NAMES and canonical not in SI_NAMES:
        raise InputError(f"unknown segment {name!r}: library names are {_VALID}")
    braid, tube = _NAME.fullmatch(canonical).groups()
    return int(braid), int(tube)


def library_segment(name: str):
    """The segment object behind a library name: ``SI-B46-T20`` the SI's
    ``BraidedSegment``, ``B46-T20`` the calibrated one."""
    braid, tube = library_geometry(name)
    if name.strip().upper().startswith(SI_PREFIX):
        from labrig.model.segments.braided import BraidedSegment

        return BraidedSegment(braid, tube)
    from labrig.model.segments.calibrated import calibrated_segment

    return calibrated_segment(braid, tube)


def is_library_name(name: str) -> bool:
    canonical = name.strip().upper()
    return canonical in LIBRARY_NAMES or canonical in SI_NAMES


@cache
def _analytical(canonical: str) -> SegmentCurve:
    if canonical.startswith(SI_PREFIX):
        return library_segment(canonical).curve(canonical)
    from labrig.model.segments.calibrated import calibrated_curve

    return calibrated_curve(*library_geometry(canonical), canonical)


def analytical_segment(name: str) -> SegmentCurve:
    """The braided segment ``name`` (case-insensitive; calibrated or ``SI-``), built once."""
    return _analytical(name.strip().upper())


def resolve_library_dir(explicit: str | Path | None = None) -> Path:
    """The measured-segment directory: the explicit one, $LABRIG_LIBRARY, or ./library."""
    if explicit is not None:
        return Path(explicit)
    return Path(os.environ.get(MEASURED_ENV_VAR) or MEASURED_DEFAULT_DIR)


def is_measured_name(text: str) -> bool:
    """Whether ``text`` can name a measured segment (and so looks nothing like a path)."""
    return _MEASURED_NAME.fullmatch(text) is not None and not text.lower().endswith(".csv")


def find_measured(name: str, directory: str | Path | None = None) -> Path | None:
    """The CSV of measured segment ``name`` (exact name first, then ignoring case), or
    None if the library has no such segment. Here rather than in
    ``labrig.analysis.measured_library`` (which adds segments from runs, through the
    analysis): the model only reads them."""
    if not is_measured_name(name):
        return None
    folder = resolve_library_dir(directory)
    exact = folder / f"{name}.csv"
    if exact.is_file():
        return exact
    if folder.is_dir():
        for candidate in folder.glob("*.csv"):
            if candidate.stem.lower() == name.lower():
                return candidate
    return None


def _looks_like_path(spec: str) -> bool:
    return spec.lower().endswith(".csv") or "/" in spec or "\\" in spec or Path(spec).exists()


def load_segment(spec: str, library_dir: Path | None = None) -> SegmentCurve:
    """A segment from a library name, a Gent membrane name, the name of a measured
    segment (``labrig.analysis.measured_library``: ``library_dir``, else $LABRIG_LIBRARY, else
    ./library) or a CSV path."""
    from labrig.model.segments.gent import GENT_NAMES, gent_membrane

    text = spec.strip()
    if text.lower() in GENT_NAMES:
        return gent_membrane(text.lower())
    if is_library_name(text):
        return analytical_segment(text)
    measured = find_measured(text, library_dir)
    if measured is not None or _looks_like_path(text):
        from labrig.model.segments.measured import load_csv

        return load_csv(measured, name=text) if measured else load_csv(Path(text))
    raise InputError(
        f"unknown segment {spec!r}: use a library name ({_VALID}), gent-a/b/c, a measured "
        f"segment in {resolve_library_dir(library_dir)}/ (labrig library add), or a path to a CSV "
        "file with the header volume_ml,pressure_kpa,length_mm"
    )
