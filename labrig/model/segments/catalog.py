"""Segments by name: the 36 braided segments of three libraries, the Gent membranes,
measured segments and CSV files.

``load_segment`` is what every command that takes a ``SEG`` argument calls. A braided
segment's name is its geometry (``B46-T20``: L_braid = 46 mm, L_tube = 20 mm) with the
library as a prefix (docs/reference/segments.md):

- ``paper:B46-T20``: the SI's segment from the paper's own numbers, tubing read as
  diameters, nothing fitted (``labrig.model.segments.paper_braided``);
- ``paper-r:B46-T20``: the same segment with the braid tubing's inner radius read as
  the paper prints it, a radius (7.94 mm), the latex tube still read as diameters
  (docs/decisions/0009);
- ``paper-gent:B46-T20``: the paper's numbers with Gent's latex past the peak (J_m =
  97.2 from Gent 1996, not fitted) and the bulge held by the strips or free of them
  (docs/decisions/0011, 0012; ``labrig.model.segments.free_bulge``);
- ``paper-clamped:B46-T20``: the ``paper:`` segment with the tube's radius held at R
  where it is glued to the couplings, over its whole curve (docs/decisions/0014;
  ``labrig.model.segments.paper_clamped``);
- ``calibrated:B46-T20``: the calibrated form, eight fitted constants
  (``labrig.model.segments.calibrated``);
- ``si:B46-T20`` (also ``SI-B46-T20``): the SI as printed, R = 6.35 mm
  (``labrig.model.segments.braided``).

A bare ``B46-T20`` is the default library's (``DEFAULT_LIBRARY``). The others are a Gent
membrane of Fig. S1 (``gent-a``, ``gent-b``, ``gent-c``) or a measured curve (CSV).
Analytical curves are built once per process and cached, because scans build all 36 again
and again.
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
PAPER, PAPER_RADIUS, CALIBRATED, SI = "paper", "paper-r", "calibrated", "si"
PAPER_GENT, PAPER_CLAMPED = "paper-gent", "paper-clamped"
LIBRARIES = (PAPER, PAPER_RADIUS, CALIBRATED, SI, PAPER_GENT, PAPER_CLAMPED)
# The library bare names resolve to, and so the simulated rig's and the demo's: the one
# that holds more of the paper's statements with fewer fitted constants
# (docs/explanation/calibration.md).
DEFAULT_LIBRARY = CALIBRATED
SI_PREFIX = "SI-"
SI_NAMES: tuple[str, ...] = tuple(SI_PREFIX + name for name in LIBRARY_NAMES)
# the prefixes longest first, so that "paper-r:" is not read as "paper:" and a rest
_PREFIXES = "|".join(map(re.escape, sorted(LIBRARIES, key=len, reverse=True)))
_NAME = re.compile(rf"(?:({_PREFIXES}):|(si-))?(B(\d+)-T(\d+))", re.IGNORECASE)
MEASURED_ENV_VAR = "LABRIG_LIBRARY"
MEASURED_DEFAULT_DIR = Path("library")
_MEASURED_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}")
_VALID = (
    f"B{BRAID_LENGTHS_MM[0]}..B{BRAID_LENGTHS_MM[-1]} x T{TUBE_LENGTHS_MM[0]}.."
    f"T{TUBE_LENGTHS_MM[-1]} in steps of 2, e.g. B46-T20, or with a library: "
    f"{LIBRARIES[0]}:B46-T20, " + ", ".join(f"{library}:" for library in LIBRARIES[1:])
)


def library_names(library: str | None = None) -> tuple[str, ...]:
    """The 36 names of ``library`` (``LIBRARIES``) with its prefix;
    bare names (the default library) for None."""
    if library is None:
        return LIBRARY_NAMES
    return tuple(f"{library}:{name}" for name in LIBRARY_NAMES)


def parse_library_name(name: str) -> tuple[str, int, int] | None:
    """(library, L_braid, L_tube) of a braided segment's name, or None."""
    found = _NAME.fullmatch(name.strip())
    if found is None:
        return None
    prefix, legacy, geometry, braid, tube = found.groups()
    if geometry.upper() not in LIBRARY_NAMES:
        return None
    library = prefix.lower() if prefix else (SI if legacy else DEFAULT_LIBRARY)
    return library, int(braid), int(tube)


def library_geometry(name: str) -> tuple[int, int]:
    """(L_braid, L_tube) in mm of a library name; InputError for anything else."""
    parsed = parse_library_name(name)
    if parsed is None:
        raise InputError(f"unknown segment {name!r}: library names are {_VALID}")
    return parsed[1], parsed[2]


def library_segment(name: str):
    """The segment object behind a library name (``paper:`` a ``PaperBraidedSegment``,
    ``paper-r:`` one with the braid tubing's radius as printed, ``paper-gent:`` a
    ``GentBulgeSegment``, ``paper-clamped:`` a ``ClampedPaperSegment``, ``si:`` the SI's
    ``BraidedSegment``, ``calibrated:`` an ``OgdenBraidedSegment``)."""
    braid, tube = library_geometry(name)
    library = parse_library_name(name)[0]
    if library == PAPER_CLAMPED:
        from labrig.model.segments.paper_clamped import ClampedPaperSegment

        return ClampedPaperSegment(braid, tube)
    if library == PAPER_GENT:
        from labrig.model.segments.free_bulge import GentBulgeSegment

        return GentBulgeSegment(braid, tube)
    if library in (PAPER, PAPER_RADIUS):
        from labrig.model.segments import paper_braided

        radius = {
            PAPER: paper_braided.BRAID_INNER_RADIUS_MM,
            PAPER_RADIUS: paper_braided.BRAID_INNER_RADIUS_AS_PRINTED_MM,
        }[library]
        return paper_braided.PaperBraidedSegment(braid, tube, envelope_radius_mm=radius)
    if library == SI:
        from labrig.model.segments.braided import BraidedSegment

        return BraidedSegment(braid, tube)
    from labrig.model.segments.calibrated import calibrated_segment

    return calibrated_segment(braid, tube)


def is_library_name(name: str) -> bool:
    return parse_library_name(name) is not None


def _canonical(name: str) -> str:
    """``paper:B46-T20``, ``SI-B46-T20``, ``B46-T20``: the prefix as the library spells
    it, the geometry in capitals."""
    found = _NAME.fullmatch(name.strip())
    prefix, legacy, geometry = found.group(1), found.group(2), found.group(3).upper()
    if prefix:
        return f"{prefix.lower()}:{geometry}"
    return (SI_PREFIX if legacy else "") + geometry


@cache
def _analytical(canonical: str) -> SegmentCurve:
    """The segment, tabulated once per install (``curve_cache``): a command that needs
    two segments otherwise spends most of its time importing scipy's solvers and
    tabulating them."""
    from labrig.model.segments.curve_cache import cached_curves

    label = "segment-" + canonical.replace(":", "-")  # a file's name on every system
    (curve,) = cached_curves(label, [canonical], lambda: (_tabulated(canonical),))
    return curve


def _tabulated(canonical: str) -> SegmentCurve:
    library, braid, tube = parse_library_name(canonical)
    if library == CALIBRATED:
        from labrig.model.segments.calibrated import calibrated_curve

        return calibrated_curve(braid, tube, canonical)
    return library_segment(canonical).curve(canonical)


def analytical_segment(name: str) -> SegmentCurve:
    """The braided segment ``name`` (case-insensitive, any library), built once."""
    if not is_library_name(name):
        raise InputError(f"unknown segment {name!r}: library names are {_VALID}")
    return _analytical(_canonical(name))


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


def looks_like_path(spec: str) -> bool:
    """Whether a segment name is meant as a CSV file's path."""
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
    if measured is not None or looks_like_path(text):
        from labrig.model.segments.measured import load_csv

        return load_csv(measured, name=text) if measured else load_csv(Path(text))
    raise InputError(
        f"unknown segment {spec!r}: a library name ({_VALID}), gent-a/b/c, a measured "
        f"segment in {resolve_library_dir(library_dir)}/ (labrig library add), or a CSV "
        "file with the header volume_ml,pressure_kpa,length_mm"
    )
