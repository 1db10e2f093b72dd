"""What the paper reports about its segments and actuators, checked against a library.

Nine statements with a number and a tolerance (Fig. 1C, Movies S3-S6); the first three
groups' subset (the 36 peaks, Movie S3) is what the calibrated library was fitted to,
the rest are predictions. A segment library is any function from a name (``B46-T20``)
to a ``SegmentCurve``, so the same table is made for the calibrated library, the SI's
(``SI-B46-T20``) or a trial calibration inside the fit.

Transitions come from the model's quasi-static path (``labrig.model.actuator``): a snap
is an unstable inflation transition, its volume the supplied volume before it, its
elongation dl = (l_post - l_pre)/l_pre, its released energy -dE, the volume it moves
dv * v (dv is relative to the supplied volume).
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
    """One statement: what the paper says, what the library gives, and whether it holds."""

    key: str
    statement: str
    paper: str
    labrig: str
    holds: bool
    role: str  # "fitted" (in the calibration subset) or "prediction"
    why: str  # for a statement that does not hold: what the model does instead

    def as_dict(self) -> dict:
        return {**asdict(self), "holds": bool(self.holds)}


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
    """The transitions on inflation of the actuator made of ``names``."""
    from labrig.model.actuator.equilibria import Actuator
    from labrig.model.actuator.path import quasi_static_path
    from labrig.model.actuator.transitions import transitions

    actuator = Actuator([library(prefix + name) for name in names])
    return [t for t in transitions(quasi_static_path(actuator)) if t.direction_name == "inflate"]


def inflation_snaps(library: Library, names, prefix: str = "") -> list[Snap]:
    """The snaps of the actuator made of ``names`` under inflation."""
    return [
        Snap(t.v_ml, t.alpha, t.beta, t.dE, t.dl, t.dv * t.v_ml)
        for t in inflation_transitions(library, names, prefix)
        if not t.stable
    ]


def second_peak_crossings(library: Library, names, prefix: str = "") -> list[float]:
    """Volumes at which a second segment crosses its peak on inflation ((1, 2), stable or
    not): where a lengthening snap of two segments happens when there is one."""
    return [
        t.v_ml for t in inflation_transitions(library, names, prefix) if (t.alpha, t.beta) == (1, 2)
    ]


def nearest(snaps: list[Snap], v_ml: float) -> Snap | None:
    return min(snaps, key=lambda s: abs(s.v_ml - v_ml), default=None)


def _snaps_text(snaps: list[Snap]) -> str:
    return "; ".join(s.describe() for s in snaps) or "no snap on inflation"


def _peak_outcomes(peaks: dict[str, float | None]) -> list[Outcome]:
    values = [p for p in peaks.values() if p is not None]
    missing = [name for name, p in peaks.items() if p is None]
    low, high = (min(values), max(values)) if values else (float("nan"),) * 2
    within = not missing and PEAK_RANGE_KPA[0] <= low and high <= PEAK_RANGE_KPA[1]
    spread = high - low
    range_why = ""
    if missing:
        range_why = f"no peak (contact first): {', '.join(n.removeprefix('SI-') for n in missing)}"
    elif not within:
        range_why = "peaks outside 65-85 kPa"
    return [
        Outcome(
            "peaks-range",
            "the 36 segments peak between 65 and 85 kPa (Fig. 1C)",
            "65-85 kPa",
            f"{low:.1f}-{high:.1f} kPa ({len(values)} of 36 with a peak)",
            within,
            "fitted",
            range_why,
        ),
        Outcome(
            "peaks-spread",
            "the peaks spread over the range (Fig. 1C): at least 10 kPa",
            ">= 10 kPa",
            f"{spread:.1f} kPa",
            spread >= MIN_SPREAD_KPA,
            "fitted",
            "" if spread >= MIN_SPREAD_KPA else "the peak barely depends on the geometry",
        ),
    ]


def _volume_outcome(key, statement, snaps, v_paper, role) -> tuple[Outcome, Snap | None]:
    snap = nearest(snaps, v_paper)
    holds = snap is not None and abs(snap.v_ml - v_paper) <= VOLUME_TOLERANCE_ML
    return (
        Outcome(
            key,
            statement,
            f"{v_paper:g} ± {VOLUME_TOLERANCE_ML:g} mL",
            "none" if snap is None else f"{snap.v_ml:.1f} mL",
            holds,
            role,
            "" if holds else _snaps_text(snaps),
        ),
        snap,
    )


def _elongation_outcome(key, statement, snap, snaps, minimum, paper, role) -> Outcome:
    """The nearest snap's dl decides; where several snaps lie within the volume
    tolerance of it, their sum is shown too: a movie shows them as one event."""
    holds = snap is not None and snap.dl > minimum
    text = "none" if snap is None else f"{snap.dl:+.1%}"
    near = (
        [] if snap is None else [s for s in snaps if abs(s.v_ml - snap.v_ml) <= VOLUME_TOLERANCE_ML]
    )
    if len(near) > 1:
        together = sum(s.dl for s in near)
        text += f" (the {len(near)} snaps within {VOLUME_TOLERANCE_ML:g} mL: {together:+.1%})"
    return Outcome(
        key,
        statement,
        paper,
        text,
        holds,
        role,
        "" if holds else _snaps_text(snaps),
    )


def _lengthening_snap(library, prefix, names, volume, elongation, role) -> list[Outcome]:
    """A movie's snap: its volume (key, statement, paper's volume) and its elongation
    (statement, least dl, the paper's value as text)."""
    key, statement, v_paper = volume
    snaps = inflation_snaps(library, names, prefix)
    found, snap = _volume_outcome(f"{key}-volume", statement, snaps, v_paper, role)
    text, minimum, paper = elongation
    return [
        found,
        _elongation_outcome(f"{key}-elongation", text, snap, snaps, minimum, paper, role),
    ]


def evaluate(library: Library, prefix: str = "") -> list[Outcome]:
    """The nine statements for the library that ``library`` builds (names ``prefix`` +
    ``B46-T20``)."""
    outcomes = _peak_outcomes(peak_pressures(library, prefix))

    outcomes += _lengthening_snap(
        library,
        prefix,
        MOVIE_S3,
        ("S3", "Movie S3, (46,20)+(46,22): a snap at 23 mL", 23.0),
        ("Movie S3: the snap lengthens the actuator", 0.0, "dl > 0"),
        "fitted",
    )
    outcomes += _lengthening_snap(
        library,
        prefix,
        MOVIE_S4,
        ("S4", "Movie S4, (48,30)+(50,20): a snap at 26 mL", 26.0),
        ("Movie S4: the snap lengthens the actuator by 10 mm (11 %)", 0.05 - 1e-12, "dl >= +5 %"),
        "prediction",
    )

    s5 = inflation_snaps(library, MOVIE_S5, prefix)
    first, second = nearest(s5, 16.0), nearest(s5, 24.0)
    both = (
        first is not None
        and second is not None
        and first is not second
        and abs(first.v_ml - 16.0) <= VOLUME_TOLERANCE_ML
        and abs(second.v_ml - 24.0) <= VOLUME_TOLERANCE_ML
    )
    outcomes.append(
        Outcome(
            "S5-two-snaps",
            "Movie S5, (44,30)+(48,26): two snaps, at 16 and 24 mL",
            "16 and 24 ± 3 mL",
            ", ".join(f"{s.v_ml:.1f}" for s in s5) + " mL" if s5 else "none",
            both,
            "prediction",
            "" if both else _snaps_text(s5),
        )
    )
    released = first is not None and abs(first.v_ml - 16.0) <= VOLUME_TOLERANCE_ML
    released = released and -first.dE >= 0.05
    outcomes.append(
        Outcome(
            "S5-release",
            "Movie S5: the first snap releases ~10 % of the stored energy",
            ">= 5 %",
            "none" if first is None else f"{-first.dE:.1%}",
            released,
            "prediction",
            "" if released else _snaps_text(s5),
        )
    )

    s6 = inflation_snaps(library, MOVIE_S6, prefix)
    moving = [s for s in s6 if 27.5 <= s.v_ml <= 29.5 and s.moved_ml >= 10.0]
    best = moving[0] if moving else nearest(s6, 28.5)
    outcomes.append(
        Outcome(
            "S6-flow",
            "Movie S6, (40,28)+(44,30)+(50,24): at 28 mL, +1 mL moves ~20 mL",
            "a snap at 27.5-29.5 mL moving >= 10 mL",
            "none" if best is None else f"{best.v_ml:.1f} mL, {best.moved_ml:.1f} mL moved",
            bool(moving),
            "prediction",
            "" if moving else _snaps_text(s6),
        )
    )
    return outcomes
