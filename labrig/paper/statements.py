"""What the paper reports about its segments and actuators, checked against a library.

Each statement has the paper's value, labrig's, a two-sided tolerance (a magnitude the
paper gives as "about x" or "up to x" holds within a factor of two of x, a volume within
3 mL; decision record 0006 fixed them before the paper-numbers library was computed),
its role (``input``: a constant the paper gives; ``fitted``: in the subset a library was
fitted to; ``selected on``: used to choose between fits that met that subset equally;
``prediction``: the rest) and the library it was computed on
(``labrig.model.segments.catalog``: ``paper``, ``paper-r``, ``calibrated``, ``si``).

This module holds what the statements share (their record, the paper's names and
ranges, reading a library's snaps); the statements live in ``segment_statements``
(Fig. 1C, D, Fig. S4, the paper's constants), ``actuator_statements`` (Movies S3-S6,
Fig. 3, Fig. 4) and ``actuation_statements`` (Movie S7, on the simulated plumbing), and
``checker`` gathers them for a library; transitions are counted as the paper counts
them (``labrig.model.actuator.paper_counting``).

The calibration's objective (``labrig.paper.fit``) reads a library through the
helpers here with the path's fine-grained events, as when it was fitted.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass

from labrig.model.segments.curve import SegmentCurve

Library = Callable[[str], SegmentCurve]

BRAIDS_MM = tuple(range(40, 51, 2))
TUBES_MM = tuple(range(20, 31, 2))
PEAK_RANGE_KPA = (65.0, 85.0)
MIN_SPREAD_KPA = 10.0

MOVIE_S3 = ("B46-T20", "B46-T22")
MOVIE_S4 = ("B48-T30", "B50-T20")
MOVIE_S5 = ("B44-T30", "B48-T26")
MOVIE_S6 = ("B40-T28", "B44-T30", "B50-T24")
VOLUME_TOLERANCE_ML = 3.0

INPUT, FITTED, SELECTED, PREDICTION = "input", "fitted", "selected on", "prediction"
ROLES = (INPUT, FITTED, SELECTED, PREDICTION)

# the types the paper reports for n = 2 (Fig. 4); a statement about pairs is judged on
# transitions of these types only, so that none passes through a type it never shows
PAPER_TYPES = frozenset({(0, 1), (1, 1), (1, 2)})
# an unstable transition releases at least this share of the stored energy: far above
# the solver's noise (a stable transition's dE over labrig's 1e-4 mL window is at most
# 5.8e-5 on every library, the paper's up to 4e-5), far below the smallest release the
# paper quotes (an unstable (1, 2)'s "up to 2.5 %")
MIN_RELEASE = 1e-3


@dataclass(frozen=True)
class Snap:
    v_ml: float
    alpha: int
    beta: int
    dE: float
    dl: float
    moved_ml: float

    def describe(self) -> str:
        return (
            f"({self.alpha},{self.beta}) snap at {self.v_ml:.1f} mL: dl {self.dl:+.1%}, "
            f"{-self.dE:.1%} of the energy released, {self.moved_ml:.1f} mL moved"
        )


@dataclass(frozen=True)
class Outcome:
    """One statement: what the paper says, what the library gives, and whether it holds
    within ``tolerance``."""

    key: str
    statement: str
    paper: str
    labrig: str
    holds: bool
    role: str  # one of ROLES
    why: str  # for a statement that does not hold: what the model does instead
    tolerance: str = ""
    library: str = ""

    def as_dict(self) -> dict:
        return {**asdict(self), "holds": bool(self.holds)}


def within(value: float, low: float, high: float) -> bool:
    return low <= value <= high


def library_names(prefix: str = "") -> list[str]:
    return [f"{prefix}B{braid}-T{tube}" for braid in BRAIDS_MM for tube in TUBES_MM]


def peak_pressures(library: Library, prefix: str = "") -> dict[str, float | None]:
    """Each of the 36 segments' pressure peak (None where p(v) only rises)."""
    found = {}
    for name in library_names(prefix):
        peak = library(name).peak
        found[name] = None if peak is None else peak.p_kpa
    return found


def inflation_transitions(library: Library, names, prefix: str = "") -> list:
    """The path's fine-grained transitions on inflation of the actuator ``names``."""
    from labrig.model.actuator.equilibria import Actuator
    from labrig.model.actuator.path import quasi_static_path
    from labrig.model.actuator.transitions import transitions

    actuator = Actuator([library(prefix + name) for name in names])
    return [t for t in transitions(quasi_static_path(actuator)) if t.direction_name == "inflate"]


def snaps_of(transitions) -> list[Snap]:
    """The unstable ones of ``transitions`` as snaps."""
    return [
        Snap(t.v_ml, t.alpha, t.beta, t.dE, t.dl, t.dv * t.v_ml)
        for t in transitions
        if not t.stable
    ]


def inflation_snaps(library: Library, names, prefix: str = "") -> list[Snap]:
    """The snaps of the actuator made of ``names`` under inflation (fine-grained)."""
    return snaps_of(inflation_transitions(library, names, prefix))


def second_peak_crossings(library: Library, names, prefix: str = "") -> list[float]:
    """Volumes at which a second segment crosses its peak on inflation ((1, 2), stable or
    not): where a lengthening snap of two segments happens when there is one."""
    return [
        t.v_ml for t in inflation_transitions(library, names, prefix) if (t.alpha, t.beta) == (1, 2)
    ]


def nearest(snaps: list, v_ml: float):
    return min(snaps, key=lambda s: abs(s.v_ml - v_ml), default=None)


def snaps_text(snaps: list[Snap]) -> str:
    return "; ".join(s.describe() for s in snaps) or "no snap on inflation"
