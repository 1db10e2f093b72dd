"""Every actuator of two segments of a library (the paper's 630), its inflation
transitions counted as the paper counts them (``labrig.model.paper.counting``).

The reference path (``quasi_static_path``), one actuator after another in this process:
about 0.3 s an actuator, so a library takes a few minutes of one core. Fig. 3's pattern
and Fig. 4's statements read it, and the movies whose pairs are among the 630 too.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from itertools import combinations

from labrig.errors import LabrigError
from labrig.model.actuator.transitions import Transition
from labrig.model.segments.curve import SegmentCurve

Library = Callable[[str], SegmentCurve]


@dataclass(frozen=True)
class PairScan:
    """The transitions of each pair (names in the library's order) and the pairs whose
    path could not be followed, with the reason."""

    transitions: dict[tuple[str, str], list[Transition]]
    failed: dict[tuple[str, str], str]


def actuator_transitions(library: Library, names) -> list[Transition]:
    """The inflation transitions, by the paper's counting, of the actuator ``names``."""
    from labrig.model.actuator.equilibria import Actuator
    from labrig.model.actuator.path import quasi_static_path
    from labrig.model.paper.counting import paper_transitions

    return paper_transitions(quasi_static_path(Actuator([library(n) for n in names])))


def scan_pairs(library: Library, names, progress: Callable[[int], None] | None = None) -> PairScan:
    """Every pair of ``names``; ``progress(done)`` after each."""
    found, failed = {}, {}
    for done, pair in enumerate(combinations(names, 2), start=1):
        try:
            found[pair] = actuator_transitions(library, pair)
        except LabrigError as exc:
            failed[pair] = str(exc)
        if progress is not None:
            progress(done)
    return PairScan(found, failed)
