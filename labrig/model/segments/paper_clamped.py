"""The paper-numbers segment with its tube clamped at the couplings (docs/decisions/0014).

Record 0008's segment (``PaperBraidedSegment``) with one change: the latex tube's radius
is held at R where it is glued to the Luer couplings. Before its peak (or before it meets
the strips) the tube is the clamped membrane of ``labrig.model.segments.clamped_tube``,
its middle's hoop stretch stepped from the rest state (p = 0), held at L_braid by the
straight braids where it reaches them (the axial force then the braids' reaction). Its
rest volume is the segment's V0 and the supplied volume counts from it.

Past the peak the bulge is record 0007's: the plateau is the free tube's Maxwell
pressure, because the clamp's boundary layers lie in the unbulged phase at the ends and
do not change as the front between the phases moves; the unbulged phase at the plateau is
the clamped tube at that pressure. The fill and the lobes between the strips are record
0008's (the tube lies on the strips, its ends at the strips' own end radius), their
enclosed volumes counted from the clamped rest volume. Without a peak the lobes start at
the clamped tube's contact. Nothing is fitted and no constant is added.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.optimize import brentq, minimize_scalar

from labrig.model.segments.braided import MM3_PER_ML, interior_maximum
from labrig.model.segments.clamped_tube import ClampedState, ClampedTube
from labrig.model.segments.curve import SegmentCurve
from labrig.model.segments.lobe_branch import LobeBranch
from labrig.model.segments.paper_braided import STRAIGHT_ANGLE, Bulge, PaperBraidedSegment

# the middle's hoop stretch between the states of the clamped branch
HOOP_STEP = 0.02
# the rest state, the braids' straightening and contact to this in the middle's hoop
# stretch; the peak to _PEAK_XTOL (the pressure is flat there: 1e-5 moves it by < 1e-6 kPa)
_ROOT_XTOL = 1e-8
_PEAK_XTOL = 1e-5
# the free tube's own peak lies below this axial stretch for every F of S32
_STRETCH_BOUND = 3.0
# the clamped branch ends before this many states (a segment reaches its peak or the
# strips within about 60)
_MAX_STATES = 400


@dataclass(frozen=True)
class ClampedBranch:
    """The clamped tube from rest to its peak (where it bulges: ``bulge`` and the
    unbulged phase at the plateau's pressure, ``unbulged``) or to the strips (the braid
    angle at contact, ``contact_angle``); ``peak`` wherever it has one."""

    states: tuple[ClampedState, ...]
    peak: ClampedState | None = None
    bulge: Bulge | None = None
    unbulged: ClampedState | None = None
    contact_angle: float | None = None


class _Walker:
    """The clamped tube solved along the middle's hoop stretch, each solution from the
    last one (``solve_bvp`` needs a neighbouring guess past the first)."""

    def __init__(self, segment: ClampedPaperSegment):
        self.segment = segment
        self.tube = ClampedTube(segment)
        self.solution = None
        self.hoop = 0.0
        self.held_mm: float | None = None

    def at(self, hoop: float):
        """The state at middle hoop stretch ``hoop`` (the walker moves there)."""
        self.solution = self.tube.solve(hoop, self.solution, self.held_mm)
        self.hoop = hoop
        return self.tube.state(self.solution)

    def root(self, function, low: float, high: float) -> ClampedState:
        """The state where ``function(state)`` is zero between two hoop stretches."""
        brentq(lambda h: function(self.at(h)), low, high, xtol=_ROOT_XTOL)
        return self.tube.state(self.solution)

    def rest(self) -> ClampedState:
        """The state at p = 0, bracketed around the uniform tube's rest hoop stretch."""
        start = self.segment.lambda_z0**-0.5
        low, high = start - 0.05, start + 0.05
        while self.at(low).p_kpa > 0:
            low -= 0.05
        while self.at(high).p_kpa < 0:
            high += 0.05
        return self.root(lambda s: s.p_kpa, low, high)


@dataclass(frozen=True)
class ClampedPaperSegment(PaperBraidedSegment):
    """``PaperBraidedSegment`` whose tube's radius stays R at both couplings (module
    docstring)."""

    def _gap_mm3(self, state: ClampedState, held: bool) -> float:
        """The tube's outer volume less the strips' envelope at its length."""
        angle = STRAIGHT_ANGLE if held else np.arccos(min(state.l_mm / self.l_braid_mm, 1.0))
        return state.volume_mm3 + self.wall_volume_mm3 - float(self.braid_volume_mm3(angle))

    @cached_property
    def free_peak_stretch(self) -> float:
        """The free uniform tube's own peak under F (axial stretch), the strips ignored:
        the end of the rising branch of Maxwell's construction."""
        return interior_maximum(lambda lz: self.tube_state(lz)[1], self.lambda_z0, _STRETCH_BOUND)

    @cached_property
    def branch(self) -> ClampedBranch:
        """The clamped tube from rest (p = 0) to its peak, if it bulges there, or to its
        contact with the strips (record 0014, items 1-4)."""
        walker = _Walker(self)
        rest = walker.rest()
        if rest.l_mm >= self.l_braid_mm:  # straight at rest: held at L_braid
            walker.held_mm = self.l_braid_mm
            rest = walker.rest()
        states, solutions = [rest], [walker.solution]
        peak = None
        while len(states) < _MAX_STATES:
            held = walker.held_mm is not None
            below, top = walker.hoop, walker.hoop + HOOP_STEP
            state = walker.at(top)
            if not held and state.l_mm >= self.l_braid_mm:  # the braids straighten
                state = walker.root(lambda s: s.l_mm - self.l_braid_mm, below, top)
                top = state.mid_hoop
                if self._gap_mm3(state, True) < 0:  # before the tube meets them
                    walker.held_mm = self.l_braid_mm
                    states.append(state)
                    solutions.append(walker.solution)
                    continue
            if self._gap_mm3(state, held) >= 0:  # the tube meets the strips
                state = walker.root(lambda s, h=held: self._gap_mm3(s, h), below, top)
                states.append(state)
                angle = max(STRAIGHT_ANGLE, float(np.arccos(min(state.l_mm / self.l_braid_mm, 1))))
                return ClampedBranch(tuple(states), peak, contact_angle=angle)
            if peak is None and not held and state.p_kpa < states[-1].p_kpa:
                peak = self._peak(walker, below - HOOP_STEP, below + HOOP_STEP)
                if states[-1].mid_hoop > peak.mid_hoop:  # the last state was past it
                    states.pop()
                    solutions.pop()
                bulge = self._bulge_after(peak)
                if bulge is not None:
                    states.append(peak)
                    unbulged = self._unbulged(walker, states, solutions, bulge.plateau_kpa)
                    return ClampedBranch(tuple(states), peak, bulge, unbulged)
                states.append(peak)  # no bulge: on to the strips
                solutions.append(walker.solution)
                state = walker.at(below + HOOP_STEP)
            states.append(state)
            solutions.append(walker.solution)
        raise ValueError(f"{self.label}: the clamped tube meets neither its peak nor the strips")

    @staticmethod
    def _peak(walker: _Walker, low: float, high: float) -> ClampedState:
        found = minimize_scalar(
            lambda h: -walker.at(h).p_kpa,
            bounds=(low, high),
            method="bounded",
            options={"xatol": _PEAK_XTOL},
        )
        return walker.at(float(found.x))

    @staticmethod
    def _unbulged(walker: _Walker, states, solutions, plateau_kpa: float) -> ClampedState:
        """The clamped tube at the plateau's pressure on its rising branch: the unbulged
        phase with its boundary layers (record 0014, item 5)."""
        above = next(k for k, s in enumerate(states) if s.p_kpa >= plateau_kpa)
        walker.solution = solutions[above - 1]
        low, high = states[above - 1].mid_hoop, states[above].mid_hoop
        return walker.root(lambda s: s.p_kpa - plateau_kpa, low, high)

    @property
    def label(self) -> str:
        return f"B{self.l_braid_mm:g}-T{self.l_tube_mm:g}"

    @property
    def rest_ml(self) -> float:
        """The clamped tube's enclosed volume at rest: its V0."""
        return self.branch.states[0].volume_mm3 / MM3_PER_ML

    @property
    def shift_ml(self) -> float:
        """What turns a supplied volume counted from the uniform tube's V0 (record
        0008's fill and lobes) into one counted from the clamped rest volume."""
        return self.V0_ml - self.rest_ml

    def _bulge_after(self, peak: ClampedState) -> Bulge | None:
        return self.bulge_at(
            peak.l_mm,
            peak.mid_outer_mm,
            peak.volume_mm3 / MM3_PER_ML - self.V0_ml,
            self.free_peak_stretch,
        )

    @property
    def bulge(self) -> Bulge | None:
        return self.branch.bulge

    @cached_property
    def lobes(self) -> LobeBranch:
        """Past the fill (record 0008's lobes from the plateau's end) or past contact."""
        branch = self.branch
        if branch.bulge is not None:
            return self.lobes_past_fill(branch.bulge, branch.peak.p_kpa)
        return LobeBranch(self, branch.contact_angle, branch.states[-1].p_kpa)

    def _supplied_ml(self, state: ClampedState) -> float:
        return state.volume_mm3 / MM3_PER_ML - self.rest_ml

    def describe(self) -> str:
        return "clamped at the couplings (record 0014): " + super().describe()

    def curve(self, name: str | None = None) -> SegmentCurve:
        """The segment's p(v), l(v) from the unpressurised state to P_END_KPA."""
        states = self.branch.states
        rising = (
            np.array([self._supplied_ml(s) for s in states]),
            np.array([s.p_kpa for s in states]),
            np.array([s.l_mm for s in states]),
        )
        bulge, unbulged = self.bulge, self.branch.unbulged
        if bulge is not None:
            v_a, l_a = self._supplied_ml(unbulged), unbulged.l_mm
            v, p, length = self.bulge_tables(bulge, rising, v_a, l_a, self.shift_ml)
        else:
            # The clamped tube meets the strips 1.6-2.4 kPa above the pressure of 0008's
            # lobes at its volume (their cylinder has no clamped ends), so the lobes
            # start opening the strips below it. The curve rises straight from contact
            # to the lobes' first state above it (the ends filling out to the cylinder)
            # rather than dropping back: a maximum made by switching forms is no peak.
            v_c, p_c, l_c = self.lobes.table
            after = p_c > rising[1][-1]
            v = np.concatenate([rising[0], v_c[after] + self.shift_ml])
            p = np.concatenate([rising[1], p_c[after]])
            length = np.concatenate([rising[2], l_c[after]])
        v[0], p[0] = 0.0, 0.0  # the unpressurised state, exactly
        return SegmentCurve(
            name or self.label, v, p, length, V0_ml=self.rest_ml, source=self.describe()
        )
