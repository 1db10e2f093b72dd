"""The paper's state transitions along a path, with (alpha, beta) and the normalised
changes dE, dv, dl, dp (main text, "Numerical Results" and Fig. 4).

A transition is every snap at constant volume (``stable`` False) and every stable change
of branch that changes the number of segments right of their peak (a peak crossing, the
paper's stable (0, 1)). A segment crossing its valley smoothly is not a transition
(nothing jumps and alpha is unchanged), while a snap that moves no peak flag (a segment
jumping from its softening onto its stiffening branch) is one.
Stability comes from the equilibrium structure (a fold or a lost coincident state),
never from the sign of dE: a stable crossing's dE is positive and grows with the volume
it is measured over.

Measured curves resolve pressure to their table's step or noise and volume to its row
spacing (``SegmentCurve.measured``). A snap that lands on the branches it left, with a
pressure jump within that resolution (twice it: each side's pressure is known to it)
and a flow between segments within a row spacing (a fold pair of
0.007 kPa and 0.007 mL where a segment leaves its valley, from a table rounded to 0.01
kPa every 0.05 mL), is not a prediction those tables can make: it is not reported, as
a crossing of a valley is not. Nor is such a fold pair whose slope deficit does not
stand out of the slope the rows resolve over its flow (``fold_slope_deficit``: where
the path is marginally stable, a rising segment's lowest slope within the tables' error
of a falling one's), nor one whose landing state the next snap leaves within a sample
gap of the curves used (a fitted curve's bin: one snap in two steps, the second
reported).
Analytical curves resolve everything: nothing is left out.

Definitions (pre/post: immediately before/after):
- dE = (E_post - E_pre) / E_pre, E the total stored energy from the unpressurised state.
- dv = max_i (v_i,post - v_i,pre) / V_pre, V_pre the total volume supplied before the
  transition. The paper writes V_pre without defining it; labrig's volumes are supplied
  volumes (zero unpressurised, as on the paper's axes), the unpressurised volumes of
  measured segments are not known to the model, and the paper's own illustration of
  internal flow (Movie S6: ~20 mL moved after inflating to 28 mL) is relative to the
  supplied volume. So dv is the fraction of the supplied fluid that changes segment.
- dl = (l_post - l_pre) / l_pre with l the sum of the segment lengths.
- dp = (p_post - p_pre) / p_pre.
For a snap, pre and post are the states on both sides of the jump at the same volume. A
stable transition has no jump, and the paper notes its dE is set by the increment of
its algorithm; here pre and post are the path's states a fixed ``window_ml`` apart,
centred on the crossing (default 1e-4 mL: dE = p window / E, 3e-6 to 1e-5 for the
library, the order of the paper's stable values, up to 4e-5), so the numbers are
deterministic and comparable between actuators.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from labrig.model.actuator.path import INFLATE, Event, Path, State, state_on_piece
from labrig.model.segments.resolution import NOISE_PROMINENCE


@dataclass(frozen=True)
class TransitionNumbers:
    """What the paper reports of a transition (module docstring)."""

    v_ml: float  # supplied volume just before the transition
    alpha: int
    beta: int
    stable: bool
    dE: float
    dv: float
    dl: float
    dp: float
    direction: int  # INFLATE (+1) or DEFLATE (-1)

    @property
    def direction_name(self) -> str:
        return "inflate" if self.direction == INFLATE else "deflate"


@dataclass(frozen=True)
class Transition(TransitionNumbers):
    """An event of the path, with its states on either side."""

    pre: State
    post: State


# the default distance between pre and post of a stable transition (module docstring)
WINDOW_ML = 1e-4


# a fold pair's slope must stand out of the slope the rows resolve by this many standard
# deviations, as a dip must stand out of their noise (``resolution.NOISE_PROMINENCE``)
FOLD_SLOPE_SIGMAS = NOISE_PROMINENCE


@dataclass(frozen=True)
class TablesResolution:
    """What the segments' tables resolve together (module docstring): ``p_kpa`` the
    largest step or noise, ``v_ml`` the largest gap between rows, ``curve_gap_ml`` the
    largest gap between the samples of the curves made of them (a fitted curve's bins),
    and per table (error of a row in kPa, median row spacing in mL) for slopes."""

    p_kpa: float = 0.0
    v_ml: float = 0.0
    curve_gap_ml: float = 0.0
    rows: tuple[tuple[float, float], ...] = ()

    def slope_error_kpa_per_ml(self, window_ml: float) -> float:
        """The standard error of the slope of a least-squares line through a table's
        rows over ``window_ml`` (N = window / spacing rows, each off by e: e sqrt(12 /
        (N window^2))), the largest of the tables'; 0 for curves that are not tables."""
        if not self.rows or window_ml <= 0:
            return 0.0
        return max(e * (12.0 * dv / window_ml**3) ** 0.5 for e, dv in self.rows)

    def resolves_fold_pair(self, deficit_kpa_per_ml: float, flow_ml: float) -> bool:
        """Whether a snap that lands on the branches it left, with a slope deficit
        ``deficit_kpa_per_ml`` (``fold_slope_deficit``) over an internal flow
        ``flow_ml``, is resolved: the deficit stands out of the slope the tables
        resolve over that flow."""
        error = self.slope_error_kpa_per_ml(flow_ml)
        return flow_ml > 0 and deficit_kpa_per_ml > FOLD_SLOPE_SIGMAS * error


def table_resolution(actuator) -> TablesResolution:
    """The resolution of the segments' tables together; all 0 for curves that are not
    tables."""
    measured = [s for s in actuator.segments if s.measured is not None]
    if not measured:
        return TablesResolution()
    found = [s.measured.resolution for s in measured]
    return TablesResolution(
        p_kpa=max(max(r.step_kpa, r.noise_kpa) for r in found),
        v_ml=max(r.spacing_max_ml for r in found),
        curve_gap_ml=max(float(np.max(np.diff(s.v_ml))) for s in measured),
        rows=tuple((max(r.noise_kpa, r.step_kpa / 12**0.5), r.spacing_ml) for r in found),
    )


def _flow_ml(pre: State, post: State) -> float:
    return max(b - a for a, b in zip(pre.v_i_ml, post.v_i_ml, strict=True))


DEFICIT_SAMPLES = 41  # states between a fold pair's ends at which the slopes are taken


def fold_slope_deficit(segments, pre: State, post: State) -> float:
    """How far a fold pair's path is from stable, in kPa/mL: the largest, between the
    snap's two states (each segment's volume taken from pre to post in
    ``DEFICIT_SAMPLES`` steps), of |k_falling| - k_series, k_series the stiffness of the
    rising segments in series (1 / sum of 1 / k). Under volume control the states with
    one falling segment are stable while k_series > |k_falling| (the energy's second
    derivative along the volume shared out, k_series + k_falling, is positive); a fold
    pair is a stretch where it is not, and what a table must resolve to show it is the
    deficit, not the snap's jump over its flow (that is about |k_falling| however
    marginal the stretch: 1.86 kPa/mL for a deficit of 0.2 kPa/mL where a staircase's
    plateau centres put a rising slope 10 % low). 0 where not exactly one segment falls
    (with two falling nothing is marginal: resolved as any snap)."""
    a, b = np.array(pre.v_i_ml), np.array(post.v_i_ml)
    t = np.linspace(0.0, 1.0, DEFICIT_SAMPLES)
    # each segment's slope at every sample, one call a segment: (samples, segments)
    k = np.column_stack(
        [s.slope_kpa_per_ml(a[i] + t * (b[i] - a[i])) for i, s in enumerate(segments)]
    )
    falling = k < 0
    one_falls = (np.count_nonzero(falling, axis=1) == 1) & np.all(k != 0, axis=1)
    if not one_falls.any():
        return 0.0
    k, falling = k[one_falls], falling[one_falls]
    k_series = 1.0 / np.sum(np.where(falling, 0.0, 1.0 / k), axis=1)
    deficit = -np.sum(np.where(falling, k, 0.0), axis=1) - k_series
    return max(0.0, float(np.max(deficit)))


def _fold_pair_unresolved(item, resolution: TablesResolution, segments) -> bool:
    """A snap that lands on the branches it left with a jump and flow within the rows'
    pressure and volume, or with a slope deficit they do not resolve (module
    docstring). Where not exactly one segment falls nothing is marginal, and the
    snap's whole slope, its jump over its flow, is what must be resolved."""
    if item.pre.branches != item.post.branches:
        return False
    flow = _flow_ml(item.pre, item.post)
    dp = item.post.p_kpa - item.pre.p_kpa
    if abs(dp) <= 2 * resolution.p_kpa and flow <= resolution.v_ml:
        return True
    if flow <= 0:
        return True  # no flow: no slope either table could show
    if resolution.rows and np.count_nonzero(np.array(item.pre.k_i) < 0) == 1:
        slope = fold_slope_deficit(segments, item.pre, item.post)
    else:
        slope = abs(dp) / flow
    return not resolution.resolves_fold_pair(slope, flow)


def below_resolution(timeline, t: int, resolution: TablesResolution, segments) -> bool:
    """Whether the snap ``timeline[t]`` is below the tables' resolution (module
    docstring): it lands on the branches it left and its jump is within the pressure
    and volume the rows resolve, or its slope is not resolved, or the state it lands on
    is left by the next snap within the curves' sample gap (one snap in two steps). That
    next snap is the next one the tables resolve: a real snap followed by a train of
    unresolved fold pairs of 0.001 kPa (a falling branch tabulated from rows rounded to
    0.001 kPa every 0.001 mL, whose slope flickers from row to row) is one snap, kept."""
    item = timeline[t]
    if item.pre.branches != item.post.branches:
        return False
    if _fold_pair_unresolved(item, resolution, segments):
        return True
    following = next(
        (
            x
            for x in timeline[t + 1 :]
            if isinstance(x, Event)
            and not (x.kind == "snap" and _fold_pair_unresolved(x, resolution, segments))
        ),
        None,
    )
    return bool(
        following is not None
        and following.kind == "snap"
        and abs(following.pre.v_ml - item.post.v_ml) <= resolution.curve_gap_ml
    )


def transitions(path: Path, window_ml: float = WINDOW_ML) -> list[Transition]:
    """Every transition along ``path``, in order (see the module docstring)."""
    actuator = path.actuator
    resolution = table_resolution(actuator)
    out = []
    timeline = path.timeline
    for t, item in enumerate(timeline):
        if not isinstance(item, Event):
            continue
        alpha, beta = actuator.alpha(item.pre.branches), actuator.alpha(item.post.branches)
        if item.kind == "snap":
            pre, post, stable = item.pre, item.post, False
        elif alpha != beta:
            before, after = timeline[t - 1], timeline[t + 1]
            v = item.pre.v_ml
            half = 0.5 * window_ml * item.direction
            pre = state_on_piece(actuator, before, v - half)
            post = state_on_piece(actuator, after, v + half)
            stable = True
        else:
            continue
        if not stable and below_resolution(timeline, t, resolution, actuator.segments):
            continue  # below the tables' resolution (module docstring)
        flow = _flow_ml(pre, post)
        e_pre, e_post = actuator.energy_mj(pre.v_i_ml), actuator.energy_mj(post.v_i_ml)
        l_pre, l_post = actuator.length_mm(pre.v_i_ml), actuator.length_mm(post.v_i_ml)
        out.append(
            Transition(
                v_ml=item.pre.v_ml,
                alpha=alpha,
                beta=beta,
                stable=stable,
                dE=(e_post - e_pre) / e_pre,
                dv=flow / pre.v_ml,
                dl=(l_post - l_pre) / l_pre,
                dp=(post.p_kpa - pre.p_kpa) / pre.p_kpa,
                direction=item.direction,
                pre=pre,
                post=post,
            )
        )
    return out
