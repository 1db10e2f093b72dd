"""The step experiments read back from a run file: actuation times and blocked force.

A run with reservoir steps (``entry/events``) gets, per step, the 10-90 % actuation time
of its pressure (1 kHz) and of its length (the camera), the changes they settled to and,
for a simulated run, the internal flow between the segments (``entry/simulation``). A
run with a load cell (a ``force`` log) gets its force against the supplied volume and the
model's blocked-actuator force (``labrig.model.blocked``): the rms difference and, at
each of the model's snaps, the jump measured against the jump predicted.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from labrig.analysis.actuation import StepResponse, step_response
from labrig.recording.run_layout import repetition_name
from labrig.recording.run_reader import decode, open_run

# The smallest change believed: a few times the noise of a sample.
PRESSURE_NOISE_KPA = 0.2
LENGTH_NOISE_MM = 0.05
# How far (mL of supplied volume) on either side of a snap the force's levels are fitted,
# and how far past the model's volume a measured snap is looked for.
FORCE_WINDOW_ML = 0.5
SNAP_SEARCH_ML = 1.5
# The force is averaged over this long before its rate is taken: a snap through the
# couplings takes about a second, and over a shorter average the rate of the load
# cell's noise and the DAQ's quantisation (a few hundredths of a newton per 1 kHz
# sample) can outrun a small snap's.
FORCE_SMOOTH_S = 0.2


@dataclass(frozen=True)
class StepResult:
    """One reservoir step and what followed it."""

    t_s: float
    volume_ml: float
    pressure: StepResponse
    length: StepResponse | None
    internal_flow_ml: float | None

    @property
    def actuation_time_s(self) -> float:
        """The 10-90 % time of the length's change (the actuator's motion) when a camera
        saw one, else of the pressure's (1 kHz)."""
        if self.length is not None and np.isfinite(self.length.actuation_time_s):
            return self.length.actuation_time_s
        return self.pressure.actuation_time_s


@dataclass(frozen=True)
class ForceTransition:
    """A snap of the blocked actuator: where, and the force jump seen and predicted."""

    v_ml: float
    force_n: float | None
    force_model_n: float


@dataclass(frozen=True)
class ForceResult:
    v_ml: np.ndarray
    force_n: np.ndarray
    model_v_ml: np.ndarray
    model_force_n: np.ndarray
    model_p_kpa: np.ndarray
    rms_n: float
    transitions: tuple[ForceTransition, ...]


def _joined(run: h5py.File, log: str) -> tuple[np.ndarray, np.ndarray] | None:
    """A log's time and value over every repetition, in time order (None if absent)."""
    reps = run["entry/repetitions"]
    times, values = [], []
    for index in range(1, len(reps["status"]) + 1):
        where = f"{repetition_name(index)}/{log}"
        if where in reps:
            times.append(reps[where]["time"][:])
            values.append(reps[where]["value"][:])
    if not times:
        return None
    t, v = np.concatenate(times), np.concatenate(values)
    order = np.argsort(t, kind="stable")
    return t[order], v[order]


def reservoir_steps(path: str | Path) -> list[StepResult]:
    """Every reservoir step of a run, with its responses (empty without events)."""
    with open_run(path) as run:
        if "entry/events" not in run:
            return []
        events = run["entry/events"]
        t_events = events["time"][:]
        kinds = [decode(k) for k in events["kind"][:]]
        volumes = events["volume"][:]
        pressure = _joined(run, "pressure")
        length = _joined(run, "length")
        flows = None
        if "entry/simulation/segment_volumes" in run:
            group = run["entry/simulation/segment_volumes"]
            names = sorted((k for k in group if k != "time"), key=lambda k: int(k[1:]))
            flows = group["time"][:], np.stack([group[k][:] for k in names], axis=1)
    if pressure is None:
        return []
    t_last = float(pressure[0][-1])
    results = []
    for i, (t, kind, volume) in enumerate(zip(t_events, kinds, volumes, strict=True)):
        if kind != "reservoir":
            continue
        t_end = float(t_events[i + 1]) if i + 1 < len(t_events) else t_last
        p = step_response(*pressure, float(t), t_end, noise=PRESSURE_NOISE_KPA)
        l_resp = None
        if length is not None:
            # the camera's last frames may end before the pressure's last samples
            l_end = min(t_end, float(length[0][-1]))
            l_resp = step_response(*length, float(t), l_end, noise=LENGTH_NOISE_MM)
        results.append(
            StepResult(float(t), float(volume), p, l_resp, _internal_flow(flows, t, t_end))
        )
    return results


def _internal_flow(flows, t_start: float, t_end: float) -> float | None:
    """Fluid moved from some segments into others between two times (mL): half the
    summed volume changes beyond the net one that entered."""
    if flows is None:
        return None
    t, volumes = flows
    before = np.array([np.interp(t_start, t, column) for column in volumes.T])
    after = np.array([np.interp(t_end, t, column) for column in volumes.T])
    change = after - before
    return float(0.5 * (np.abs(change).sum() - abs(change.sum())))


def blocked_force(path: str | Path, segments, fittings_length_mm: float) -> ForceResult | None:
    """The run's force against supplied volume and the model's, None without a load cell.

    The force is taken while the pump infuses (the inflation the model describes),
    interpolated onto the pump's volume at each force sample's time.
    """
    from labrig.model.blocked import BlockedActuator

    with open_run(path) as run:
        force = _joined(run, "force")
        pump = _joined(run, "pump")
    if force is None or pump is None:
        return None
    t_pump, v_pump = pump
    rising = np.concatenate(([False], np.diff(v_pump) > 1e-6))
    if not rising.any():
        return None
    t_lo, t_hi = t_pump[np.argmax(rising)] - 0.2, t_pump[len(rising) - np.argmax(rising[::-1]) - 1]
    t_f, f = force
    inside = (t_f >= t_lo) & (t_f <= t_hi)
    v_f, f = np.interp(t_f[inside], t_pump, v_pump), f[inside]
    model = BlockedActuator(segments, fittings_length_mm).path(float(v_f.max()), 0.05)
    # the model's force at each measured volume, on its branch before any snap there
    unique_v, first = np.unique(model.v_ml, return_index=True)
    f_model = np.interp(v_f, unique_v, model.force_n[first])
    rms = float(np.sqrt(np.mean((f - f_model) ** 2)))
    transitions = tuple(
        ForceTransition(
            float(model.v_ml[i]),
            _measured_jump(t_f[inside], v_f, f, model, int(i)),
            float(model.force_n[i + 1] - model.force_n[i]),
        )
        for i in np.flatnonzero(np.diff(model.v_ml) == 0)
    )
    return ForceResult(v_f, f, model.v_ml, model.force_n, model.p_kpa, rms, transitions)


def _measured_jump(t_s, v_ml, f_n, model, i_snap: int) -> float | None:
    """The force jump of the model's snap at row ``i_snap`` of its path, as measured.

    A snap crossed at a finite rate starts late and takes time while the pump goes on,
    so the measured force is not read at the model's volume itself. The measured snap is
    found as the fastest change of the (FORCE_SMOOTH_S averaged) force from a little before
    the model's volume to SNAP_SEARCH_ML after it; its span is where the rate stays above
    a fifth of that peak. Before the span (and before the model's volume) and after it,
    over FORCE_WINDOW_ML, the median offset of the measured force from the model's
    branch there carries each measured branch to the model's volume: the jump measured
    is the model's plus the difference of the two offsets.
    """
    v_snap_ml = float(model.v_ml[i_snap])
    if len(f_n) < 50:
        return None
    width = max(1, round(FORCE_SMOOTH_S / float(np.median(np.diff(t_s)))))
    if len(f_n) < 2 * width + 1:
        return None
    smooth = np.convolve(f_n, np.ones(width) / width, mode="same")
    rate = np.gradient(smooth, t_s)
    search = np.flatnonzero((v_ml > v_snap_ml - 0.2) & (v_ml < v_snap_ml + SNAP_SEARCH_ML))
    search = search[(search > width) & (search < len(f_n) - width)]
    if search.size == 0:
        return None
    peak = int(search[np.argmax(np.abs(rate[search]))])
    threshold = 0.2 * abs(rate[peak])
    start, end = peak, peak
    while start > 0 and abs(rate[start - 1]) > threshold:
        start -= 1
    while end < len(rate) - 1 and abs(rate[end + 1]) > threshold:
        end += 1
    last_before = min(v_ml[start], v_snap_ml)
    before = (v_ml > last_before - FORCE_WINDOW_ML) & (v_ml < last_before)
    after = (v_ml > v_ml[end]) & (v_ml < v_ml[end] + FORCE_WINDOW_ML)
    if before.sum() < 10 or after.sum() < 10:
        return None
    pre_v, pre_f = model.v_ml[: i_snap + 1], model.force_n[: i_snap + 1]
    post_v, post_f = model.v_ml[i_snap + 1 :], model.force_n[i_snap + 1 :]
    offset_before = np.median(f_n[before] - np.interp(v_ml[before], pre_v, pre_f))
    offset_after = np.median(f_n[after] - np.interp(v_ml[after], post_v, post_f))
    return float(model.force_n[i_snap + 1] - model.force_n[i_snap] + offset_after - offset_before)


def force_for_run(path: str | Path) -> ForceResult | None:
    """``blocked_force`` for the specimen the run file's protocol names (None for a run
    without a load cell, or a specimen with no model)."""
    from labrig.config.protocol import parse_protocol
    from labrig.model.segments.catalog import load_segment

    with open_run(path) as run:
        if not any("force" in group for group in run["entry/repetitions"].values()):
            return None
        protocol = parse_protocol(decode(run["entry/protocol"][()]), f"{path}:/entry/protocol")
    specimen = protocol.specimen
    if not specimen.has_model:  # its segments are labels: no blocked actuator to compare
        return None
    segments = [load_segment(name) for name in specimen.segments]
    return blocked_force(path, segments, specimen.fittings_length_mm)


def _number(value: float | None) -> float | None:
    return None if value is None or not np.isfinite(value) else float(value)


def experiment_fields(path: str | Path, comparison: dict, match_ml: float = 2.0) -> dict:
    """``labrig compare --json``'s fields for the step experiments, added to
    ``comparison``: ``steps`` (one per reservoir step, with ``actuation_time_s``), and
    for a run with a load cell ``force`` (rms and the model's snaps) and ``force_n`` /
    ``force_model_n`` on each transition (the force jump at the model's blocked snap
    within ``match_ml`` of it; null where there is none)."""
    steps = reservoir_steps(path)
    if steps:
        comparison["steps"] = [
            {
                "kind": "reservoir",
                "t_s": step.t_s,
                "volume_ml": step.volume_ml,
                "actuation_time_s": _number(step.actuation_time_s),
                "actuation_time_length_s": _number(
                    step.length.actuation_time_s if step.length else None
                ),
                "actuation_time_pressure_s": _number(step.pressure.actuation_time_s),
                "dp_kpa": _number(step.pressure.change),
                "dl_mm": _number(step.length.change if step.length else None),
                "internal_flow_ml": _number(step.internal_flow_ml),
            }
            for step in steps
        ]
    force = force_for_run(path)
    if force is None:
        return comparison
    snaps = [
        {
            "v_ml": t.v_ml,
            "force_n": _number(t.force_n),
            "force_model_n": _number(t.force_model_n),
        }
        for t in force.transitions
    ]
    comparison["force"] = {"rms_n": _number(force.rms_n), "transitions": snaps}
    for transition in comparison.get("transitions", []):
        near = [s for s in snaps if abs(s["v_ml"] - (transition["v_ml"] or np.inf)) <= match_ml]
        nearest = min(near, key=lambda s: abs(s["v_ml"] - transition["v_ml"]), default=None)
        transition["force_n"] = nearest["force_n"] if nearest else None
        transition["force_model_n"] = nearest["force_model_n"] if nearest else None
    return comparison
