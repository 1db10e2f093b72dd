"""Every actuator of two segments of a library (the paper's 630), its inflation
transitions counted as the paper counts them (``labrig.model.actuator.paper_counting``).

The reference path (``quasi_static_path``), one actuator after another in this process:
a few milliseconds an actuator once the curves' kernels are compiled, so a library takes
a few seconds. Fig. 3's pattern and Fig. 4's statements read it, and the movies whose
pairs are among the 630 too.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from itertools import combinations

from labrig.errors import LabrigError
from labrig.model.actuator.paper_counting import PaperTransition
from labrig.model.segments.curve import SegmentCurve

Library = Callable[[str], SegmentCurve]


@dataclass(frozen=True)
class PairScan:
    """The transitions of each pair (names in the library's order) and the pairs whose
    path could not be followed, with the reason."""

    transitions: dict[tuple[str, str], list[PaperTransition]]
    failed: dict[tuple[str, str], str]


def actuator_transitions(library: Library, names) -> list[PaperTransition]:
    """The inflation transitions, by the paper's counting, of the actuator ``names``."""
    from labrig.model.actuator.equilibria import Actuator
    from labrig.model.actuator.paper_counting import paper_transitions
    from labrig.model.actuator.path import quasi_static_path
    from labrig.model.actuator.transitions import transitions

    path = quasi_static_path(Actuator([library(n) for n in names]))
    return [t for t in paper_transitions(transitions(path)) if t.direction_name == "inflate"]


def scan_pairs(library: Library, names) -> PairScan:
    """Every pair of ``names``, in the order of ``itertools.combinations``."""
    found, failed = {}, {}
    for pair in combinations(names, 2):
        try:
            found[pair] = actuator_transitions(library, pair)
        except LabrigError as exc:
            failed[pair] = str(exc)
    return PairScan(found, failed)
