"""Run files written for real, from a simulated specimen whose truth is known.

A ``Plant`` (segments exchanging fluid through a flow resistance) is driven by a known
pump history: per repetition rest, infuse at a rate to V, hold, withdraw to 0, rest.
``RunWriter`` stores what a rig would record: the pump's net volume polled at 10 Hz
(jittered, 4 significant digits as the PHD Ultra prints it), the pressure at 1 kHz with
MPX5100-like errors (a residual offset after zeroing, white noise, 14-bit quantisation
of about 0.03 kPa) and the length at a few frames per second with tracking noise.

The truth comes from the plant itself, independently of anything the analysis does:
the plant's segment volumes are sampled every 50 ms, and a snap-through is a peak of the
internal flow (fluid moving between the segments rather than in from the pump).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.signal import find_peaks

from labrig.model.segments.catalog import load_segment
from labrig.recording.run_writer import RunWriter
from labrig.sim.plant import Plant

PUMP_PERIOD_S = 0.1
TRUTH_STEP_S = 0.05
REST_S = 1.0
QUANTUM_KPA = 100.0 / 2**14 / 0.2  # ~0.03 kPa: 14 bits over +-10 V at 45 mV/kPa
SNAP_FLOW_ML_S = 0.8  # internal flow above this (mL/s) is a snap, not a redistribution


@dataclass(frozen=True)
class TrueSnap:
    """A snap of the plant: its time and supplied volume at the internal flow's peak,
    and ``dl_mm``, the quasi-static jump of the noise-free length (``_true_jump``)."""

    repetition: int
    direction: int
    t_s: float
    v_ml: float
    flow_ml_s: float
    dl_mm: float = float("nan")


@dataclass(frozen=True)
class SimulatedRun:
    path: Path
    segments: tuple[str, ...]
    volume_ml: float
    rate_ml_min: float
    repetitions: int
    fittings_length_mm: float
    snaps: tuple[TrueSnap, ...]


def protocol_yaml(segments, volume_ml, rate_ml_min, hold_s, repetitions, fps, average_last):
    names = ", ".join(segments)
    return textwrap.dedent(
        f"""\
        name: simulated {"+".join(segments)}
        specimen: {{segments: [{names}], fittings_length_mm: 10}}
        rig: sim
        limits: {{max_pressure_kpa: 95, max_volume_ml: {volume_ml + 5:g}}}
        acquisition: {{pressure_rate_hz: 1000, camera_fps: {fps:g}}}
        steps:
          - zero_pressure: {{duration_s: 2}}
          - repeat:
              times: {repetitions}
              steps:
                - infuse: {{rate_ml_min: {rate_ml_min:g}, volume_ml: {volume_ml:g}}}
                - hold: {{seconds: {hold_s:g}}}
                - withdraw: {{rate_ml_min: {rate_ml_min:g}, volume_ml: {volume_ml:g}}}
        analysis: {{average_last: {average_last}, compare_model: true}}
        """
    )


class PumpHistory:
    """Net volume in the specimen against time for the repeated protocol."""

    def __init__(self, volume_ml, rate_ml_min, hold_s, t0_s=0.0):
        self.volume_ml = volume_ml
        self.rate_ml_s = rate_ml_min / 60.0
        self.ramp_s = volume_ml / self.rate_ml_s
        self.hold_s = hold_s
        self.t0_s = t0_s
        self.period_s = 2 * REST_S + 2 * self.ramp_s + hold_s

    def start_s(self, repetition: int) -> float:
        return self.t0_s + (repetition - 1) * self.period_s

    def __call__(self, t_s: float) -> float:
        local = (t_s - self.t0_s) % self.period_s if t_s >= self.t0_s else 0.0
        local -= REST_S
        if local <= 0:
            return 0.0
        if local < self.ramp_s:
            return self.rate_ml_s * local
        local -= self.ramp_s
        if local < self.hold_s:
            return self.volume_ml
        local -= self.hold_s
        return max(0.0, self.volume_ml - self.rate_ml_s * local)

    def direction(self, t_s: float) -> int:
        local = (t_s - self.t0_s) % self.period_s - REST_S
        if 0 < local < self.ramp_s:
            return 1
        if self.ramp_s + self.hold_s < local < 2 * self.ramp_s + self.hold_s:
            return -1
        return 0


def _pump_state(direction: int, volume_ml: float) -> str:
    if direction > 0:
        return "infusing"
    if direction < 0:
        return "withdrawing"
    return "target reached" if volume_ml > 0 else "idle"


def _four_digits(values: np.ndarray) -> np.ndarray:
    """The pump prints volumes with 4 significant digits (e.g. 12.34 ml)."""
    out = np.zeros_like(values)
    nonzero = values > 0
    exponent = np.floor(np.log10(values[nonzero]))
    scale = 10.0 ** (3 - exponent)
    out[nonzero] = np.round(values[nonzero] * scale) / scale
    return out


def simulate_run(
    path: Path,
    segments: tuple[str, ...],
    *,
    volume_ml: float,
    rate_ml_min: float = 20.0,
    hold_s: float = 2.0,
    repetitions: int = 5,
    resistance_kpa_s_per_ml: float = 1.0,
    noise_kpa: float = 0.15,
    offset_kpa: float = 0.1,
    fps: float = 2.0,
    length_noise_mm: float = 0.01,
    average_last: int = 4,
    statuses: tuple[str, ...] | None = None,
    seed: int = 0,
) -> SimulatedRun:
    """Simulate the protocol on the plant and write the run file (see module docstring)."""
    rng = np.random.default_rng(seed)
    curves = [load_segment(name) for name in segments]
    pump = PumpHistory(volume_ml, rate_ml_min, hold_s)
    fittings_mm = 10.0
    plant = Plant(
        curves,
        pump,
        resistance_kpa_s_per_ml=resistance_kpa_s_per_ml,
        fittings_length_mm=fittings_mm,
        seed=seed,
    )
    with_length = fps > 0
    writer = RunWriter(
        path,
        title=f"simulated {'+'.join(segments)}",
        protocol_text=protocol_yaml(
            segments, volume_ml, rate_ml_min, hold_s, repetitions, fps, average_last
        ),
        protocol_path="protocols/simulated.yaml",
        rig_config_text="rig: sim\n",
        repetitions=repetitions,
        with_length=with_length,
    )
    writer.set_zero_offset(0.42)
    snaps: list[TrueSnap] = []
    statuses = statuses or ("complete",) * repetitions
    for rep in range(1, repetitions + 1):
        t_start = pump.start_s(rep)
        t_end = t_start + pump.period_s
        writer.set_repetition_status(rep, "running", t_start_s=t_start)

        # truth: the plant's segment volumes every 50 ms
        t_truth = np.arange(t_start, t_end, TRUTH_STEP_S)
        w = np.empty((len(t_truth), plant.n))
        for k, t in enumerate(t_truth):
            plant.advance_to(t)
            w[k] = plant.volumes_ml
        l_truth = plant.length_mm_at(t_truth)
        snaps += _true_snaps(rep, t_truth, w, pump, l_truth)

        t_p = np.arange(t_start, t_end, 1e-3)
        p = plant.pressure_kpa_at(t_p) + offset_kpa + rng.normal(0, noise_kpa, len(t_p))
        p = np.round(p / QUANTUM_KPA) * QUANTUM_KPA
        for chunk in np.array_split(np.arange(len(t_p)), max(1, len(t_p) // 5000)):
            writer.append_pressure(rep, t_p[chunk], p[chunk], p[chunk] > 102.5)

        t_v = np.arange(t_start, t_end, PUMP_PERIOD_S) + rng.uniform(0, 2e-3, 1)
        v = np.array([pump(t) for t in t_v])
        infused = np.where([pump.direction(t) >= 0 for t in t_v], v, 0.0)
        withdrawn = np.where([pump.direction(t) < 0 for t in t_v], volume_ml - v, 0.0)
        states = [_pump_state(pump.direction(t), x) for t, x in zip(t_v, v, strict=True)]
        writer.append_pump(rep, t_v, _four_digits(v), infused, withdrawn, states)

        if with_length:
            t_l = np.arange(t_start + 0.1, t_end, 1.0 / fps)
            length = plant.length_mm_at(t_l) + rng.normal(0, length_noise_mm, len(t_l))
            x1 = np.full(len(t_l), 120.0)
            x2 = x1 + length / 0.1  # 0.1 mm per pixel
            y = np.full(len(t_l), 240.0)
            writer.append_length(rep, t_l, length, x1, y, x2, y, np.ones(len(t_l), bool))
        status = statuses[rep - 1]
        reason = "" if status == "complete" else "simulated fault"
        writer.set_repetition_status(rep, status, reason, t_end_s=t_end)
    writer.finalise("complete")
    return SimulatedRun(
        path, tuple(segments), volume_ml, rate_ml_min, repetitions, fittings_mm, tuple(snaps)
    )


def _true_snaps(rep, t, w, pump, length_mm) -> list[TrueSnap]:
    """Peaks of the internal flow: half the sum over segments of |inflow - pump share|."""
    if w.shape[1] < 2:
        return []
    supplied = np.array([pump(x) for x in t])
    inflow = np.diff(w, axis=0) / TRUTH_STEP_S
    share = (np.diff(supplied) / TRUTH_STEP_S)[:, None] / w.shape[1]
    internal = 0.5 * np.abs(inflow - share).sum(axis=1)
    t_mid = 0.5 * (t[1:] + t[:-1])
    peaks, _ = find_peaks(internal, height=SNAP_FLOW_ML_S, distance=int(2.0 / TRUTH_STEP_S))
    out = []
    for k in peaks:
        t_peak = t_mid[k]
        if 0 < k < len(internal) - 1:  # parabola through the peak and its neighbours
            y0, y1, y2 = internal[k - 1 : k + 2]
            t_peak += 0.5 * (y0 - y2) / (y0 - 2 * y1 + y2) * TRUTH_STEP_S
        dl = _true_jump(t_mid, internal, t, length_mm, k, t_peak)
        direction = pump.direction(t_peak)
        out.append(TrueSnap(rep, direction, t_peak, pump(t_peak), float(internal[k]), dl))
    return out


def _true_jump(t_mid, internal, t, length_mm, k, t_peak, fit_s=1.0) -> float:
    """The quasi-static jump of the plant's noise-free length at a snap, as the model
    defines it (post minus pre at one supplied volume): the snap spans the internal
    flow above a quarter of its peak; lines through the length over ``fit_s`` before and
    after that span, each on its own branch, are extrapolated to the peak and differenced.
    Uses the plant's own flow and noise-free length, nothing the analysis computes."""
    above = internal > 0.25 * internal[k]
    first = last = k
    while first > 0 and above[first - 1]:
        first -= 1
    while last < len(above) - 1 and above[last + 1]:
        last += 1
    t_a, t_b = t_mid[first], t_mid[last]
    before = (t >= t_a - fit_s) & (t <= t_a)
    after = (t >= t_b) & (t <= t_b + fit_s)
    if np.count_nonzero(before) < 3 or np.count_nonzero(after) < 3:
        return float("nan")
    pre = np.polyval(np.polyfit(t[before] - t_peak, length_mm[before], 1), 0.0)
    post = np.polyval(np.polyfit(t[after] - t_peak, length_mm[after], 1), 0.0)
    return float(post - pre)


# --- small files for damage and recovery tests ---------------------------------------
PROTOCOL = textwrap.dedent(
    """\
    name: tiny
    specimen: {segments: [SI-B46-T20]}
    limits: {max_pressure_kpa: 90, max_volume_ml: 5}
    steps:
      - repeat: {times: 2, steps: [{infuse: {rate_ml_min: 60, volume_ml: 2}},
                                   {withdraw: {rate_ml_min: 60, volume_ml: 2}}]}
    analysis: {average_last: 2, compare_model: false}
    """
)


def tiny_run(path, repetitions=2):
    """A small, complete run: p = 5 v, l = 30 + v, infusing then withdrawing 2 mL."""
    writer = RunWriter(
        path,
        title="tiny",
        protocol_text=PROTOCOL,
        protocol_path="tiny.yaml",
        rig_config_text="",
        repetitions=repetitions,
        with_length=True,
    )
    for rep in range(1, repetitions + 1):
        t0 = (rep - 1) * 4.0
        t = t0 + np.arange(0, 4.0, 0.001)
        v = np.where(t - t0 < 2.0, t - t0, 4.0 - (t - t0))
        writer.append_pressure(rep, t, 5.0 * v, np.zeros(len(t), bool))
        tp = t0 + np.arange(0, 4.0, 0.1)
        vp = np.where(tp - t0 < 2.0, tp - t0, 4.0 - (tp - t0))
        writer.append_pump(rep, tp, vp, vp, 0 * vp, ["infusing"] * len(tp))
        tl = t0 + np.arange(0, 4.0, 0.5)
        vl = np.where(tl - t0 < 2.0, tl - t0, 4.0 - (tl - t0))
        ones = np.ones(len(tl))
        writer.append_length(rep, tl, 30.0 + vl, ones, ones, ones, ones, ones.astype(bool))
        writer.set_repetition_status(rep, "complete", t_start_s=t0, t_end_s=t0 + 4.0)
    writer.finalise("complete")
    return path


KILLED_WRITER = textwrap.dedent(
    """
    import sys, time
    import numpy as np
    from labrig.recording.run_writer import RunWriter
    protocol = open(sys.argv[2]).read()
    writer = RunWriter(sys.argv[1], title="killed", protocol_text=protocol,
                       protocol_path="tiny.yaml", rig_config_text="", repetitions=2,
                       with_length=False, flush_interval_s=0.2)
    writer.set_repetition_status(1, "running", t_start_s=0.0)
    print("ready", flush=True)
    k = 0
    while True:
        t = k * 0.1 + np.arange(100) * 1e-3
        writer.append_pressure(1, t, 50.0 * t, np.zeros(100, bool))
        writer.append_pump(1, k * 0.1, 10.0 * k * 0.1, 10.0 * k * 0.1, 0.0, "infusing")
        k += 1
        time.sleep(0.01)
    """
)


def killed_run(directory: Path) -> Path:
    """A run file whose writing process was SIGKILLed mid-repetition (for real)."""
    path = directory / "killed.h5"
    protocol = directory / "tiny.yaml"
    protocol.write_text(PROTOCOL)
    process = subprocess.Popen(
        [sys.executable, "-c", KILLED_WRITER, str(path), str(protocol)],
        stdout=subprocess.PIPE,
        text=True,
    )
    assert process.stdout.readline().strip() == "ready"
    time.sleep(1.0)
    os.kill(process.pid, signal.SIGKILL)
    process.wait()
    return path
