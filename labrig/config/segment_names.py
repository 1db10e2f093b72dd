"""A specimen's segment names against the model's: what a misspelt name was meant to be.

A specimen with a model (``specimen.model: segments``) names each segment by a library
name, a measured segment or a CSV path, and a name that is none of these is refused
before anything moves; the refusal says which name was probably meant. A specimen with
no model (``model: none``) names its segments by the lab's own labels, which nothing
resolves; a label that looks like a model's name (``B46-T2O``, ``B46T20``, ``gent-d``)
is most likely a typo in a protocol that meant to have the model, so it is warned
about, never silently taken either way.

Labels are compared with the analytical names only (the 36 braided segments of every
library and the Gent membranes), not with measured ones: a lab numbers its specimens
(LAB-S37, LAB-S38), and one number from the next is no typo.
"""

from __future__ import annotations

import difflib
from collections.abc import Sequence
from pathlib import Path

# How alike two names must be (difflib's ratio) to be a near miss: B46-T2O and B46-T28
# are 0.86, B52-T20 and B50-T20 0.86; LAB-S37 and any library name at most 0.43.
NEAR_MISS_RATIO = 0.75
# Characters a geometry is mistyped with that look or sit alike: O for 0, I or l for 1,
# underscore or space for the dash.
_CONFUSABLE = str.maketrans({"O": "0", "I": "1", "L": "1", "_": "-", " ": "-"})


def _analytical_names() -> list[str]:
    from labrig.model.segments.catalog import LIBRARIES, SI_NAMES, library_names
    from labrig.model.segments.gent import GENT_NAMES

    names = [*library_names(), *SI_NAMES, *GENT_NAMES]
    for library in LIBRARIES:
        names += library_names(library)
    return names


def suggestion(name: str, extra: Sequence[str] = ()) -> str | None:
    """The model's name ``name`` most likely meant (an analytical name, or one of
    ``extra``), or None when it is like none of them."""
    names = [*_analytical_names(), *extra]
    by_key = {candidate.upper(): candidate for candidate in names}
    key = name.strip().upper()
    # the geometry (B46-T20) is where digits belong: the library prefix keeps its I
    start = key.rfind("B")
    fixed = key[:start] + key[start:].translate(_CONFUSABLE) if start >= 0 else key
    if fixed != key and fixed in by_key:
        return by_key[fixed]
    close = difflib.get_close_matches(key, list(by_key), n=1, cutoff=NEAR_MISS_RATIO)
    return by_key[close[0]] if close else None


def names_a_model(name: str, library_dir: Path | None = None) -> str | None:
    """What ``name`` names in the model (a library segment, a Gent membrane, a measured
    segment, a CSV file), or None when it names nothing there."""
    from labrig.model.segments.catalog import find_measured, is_library_name, looks_like_path
    from labrig.model.segments.gent import GENT_NAMES

    text = name.strip()
    if is_library_name(text):
        return "a library segment"
    if text.lower() in GENT_NAMES:
        return "a Gent membrane"
    if find_measured(text, library_dir) is not None:
        return "a measured segment in the library"
    if looks_like_path(text):
        return "a CSV file"
    return None


def label_warnings(segments: Sequence[str], library_dir: Path | None = None) -> list[str]:
    """For a specimen with ``model: none``: each label that names a model or nearly
    names an analytical segment, and what to do about it."""
    warnings = []
    for index, label in enumerate(segments):
        where = f"specimen.segments[{index}] {label!r}"
        named = names_a_model(label, library_dir)
        if named is not None:
            warnings.append(
                f"{where} is {named}, but specimen.model: none makes it a label only: the "
                "run has no model; drop model: none to predict and compare"
            )
            continue
        meant = suggestion(label)
        if meant is not None:
            warnings.append(
                f"{where} looks like {meant!r} misspelt; with specimen.model: none it is "
                f"a label and the run has no model (for {meant}'s model, name it and drop "
                "model: none)"
            )
    return warnings


def name_warnings(specimen, library_dir: Path | None = None) -> list[str]:
    """What ``labrig protocol validate`` warns of in a specimen's names: labels that
    look like a model's names (``model: none``: ``label_warnings``), or names that
    name no segment here (with a model: ``labrig run`` will refuse them)."""
    if not specimen.has_model:
        return label_warnings(specimen.segments, library_dir)
    return [
        f"specimen.segments[{index}] {name!r} names no segment here (no library name, Gent "
        "membrane, measured segment or CSV path): labrig run refuses it; "
        + unknown_segment_hint(name, library_dir)
        for index, name in enumerate(specimen.segments)
        if names_a_model(name, library_dir) is None
    ]


def unknown_segment_hint(name: str, library_dir: Path | None = None) -> str:
    """What to add to "unknown segment NAME" for a specimen that should have a model:
    the name probably meant, and how to run a specimen that has no model yet."""
    from labrig.model.segments.catalog import resolve_library_dir

    folder = resolve_library_dir(library_dir)
    measured = sorted(p.stem for p in folder.glob("*.csv")) if folder.is_dir() else []
    meant = suggestion(name, measured)
    did_you_mean = f"did you mean {meant!r}? " if meant else ""
    return (
        f"{did_you_mean}a specimen nothing models yet (one to characterise) has "
        "specimen.model: none, and its segments' names are then labels"
    )
