"""An actuator's quasi-static path as ``labrig model path`` and the Python API's
``labrig.actuator(...).path()`` give it: solved with its events and its samples in one
call (``solve_path``), and written as the JSON object scripts read from
``labrig model path --json`` (``path_document``). Both callers use these, so the
command's JSON and the API's tables cannot drift apart.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from typing import NamedTuple

from labrig.errors import InputError
from labrig.model.actuator.equilibria import Actuator
from labrig.model.actuator.paper_counting import paper_transitions
from labrig.model.actuator.path import Path, SampledPath, quasi_static_path, sample_path
from labrig.model.actuator.transitions import Transition, transitions
from labrig.model.segments.curve import SegmentCurve
from labrig.vocabulary import ALIASES, beside_fields


class SolvedPath(NamedTuple):
    """The path (pieces and events), it sampled in volume, and its transitions (every
    peak crossing and every snap, in order)."""

    path: Path
    sampled: SampledPath
    found: tuple[Transition, ...]


def checked_end_volume_ml(v_end_ml: object, *, named: str) -> float | None:
    """``v_end_ml`` as an end volume of inflation (mL), or an InputError naming the input
    as the caller's user wrote it (``named``): a path to infinity or to NaN would run the
    solver until it gives up with a message about its bracket, not about the input."""
    if v_end_ml is None:
        return None
    if (
        isinstance(v_end_ml, numbers.Real)
        and not isinstance(v_end_ml, bool)
        and math.isfinite(v_end_ml)
        and v_end_ml > 0
    ):
        return float(v_end_ml)
    raise InputError(f"{named}={v_end_ml!r}: the end volume of inflation, mL, > 0 and finite")


def solve_path(
    curves: Sequence[SegmentCurve], v_end_ml: float | None, *, deflate: bool
) -> SolvedPath:
    """The quasi-static path of the segments ``curves`` in series under volume control:
    inflation to ``v_end_ml`` (mL; None: where no further transition is possible) and,
    with ``deflate``, back to zero."""
    path = quasi_static_path(Actuator(list(curves)), v_end_ml, deflate=deflate)
    return SolvedPath(path, sample_path(path), tuple(transitions(path)))


def _round(values, digits: int = 6) -> list[float]:
    return [round(float(x), digits) for x in values]


def _significant(x: float) -> float:
    return float(f"{x:.6g}")


def _numbers(t) -> dict:
    return {
        "v_ml": round(t.v_ml, 6),
        "alpha": t.alpha,
        "beta": t.beta,
        "stable": t.stable,
        "dE": _significant(t.dE),
        "dv": _significant(t.dv),
        "dl": _significant(t.dl),
        "dp": _significant(t.dp),
        "direction": t.direction_name,
    }


def path_document(names: Sequence[str], sampled: SampledPath, found: Sequence[Transition]) -> dict:
    """The JSON scripts read from ``labrig model path --json``: segments, path arrays
    (v_ml and ``v_i_ml`` in mL, p_kpa in kPa, l_mm in mm, rounded to 1e-6),
    ``transitions`` (the path's events: every peak crossing and every snap; v_ml in mL,
    dE, dv, dl, dp normalised as in the paper, to 6 significant digits) and
    ``paper_transitions`` (those counted as the paper counts them, each with
    ``events``, the indices into ``transitions`` it is made of), each with its
    ``direction`` ("inflate" or "deflate"). ``v_i_ml`` holds one list per segment,
    parallel to ``v_ml``. Each path array also appears under its vocabulary name right
    after it (``volume_ml``, ``pressure_kpa``, ``segments_length_mm``), so a script can
    use the names the Python API's tables use."""
    index = {id(t): k for k, t in enumerate(found)}
    return {
        "segments": list(names),
        "path": beside_fields(
            {
                "v_ml": _round(sampled.v_ml),
                "p_kpa": _round(sampled.p_kpa),
                "l_mm": _round(sampled.l_mm),
                "v_i_ml": [_round(v) for v in sampled.v_i_ml],
            },
            ALIASES["model path"],
        ),
        "transitions": [_numbers(t) for t in found],
        "paper_transitions": [
            {**_numbers(t), "events": [index[id(e)] for e in t.events]}
            for t in paper_transitions(found)
        ],
    }
