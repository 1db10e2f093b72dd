"""The live view's state: fed by a run (or a file being recorded), read by the server.

The run must never wait for the page. So the run's side of this module is two calls
that cannot block: ``tap`` (the run file's writer calls it with every append; it puts a
reference to the arrays on a ``queue.SimpleQueue``) and ``progress`` (the runner's
progress callback; it replaces one reference). Everything else happens in the live
view's own digest thread: binning the samples and giving them volumes
(``labrig.live.series``), detecting transitions with the analysis' detector, and
publishing the result as append-only lists and immutable snapshots, which the server's
threads read without a lock. A browser that disconnects, or one that polls slowly,
touches only the server's threads.
"""

from __future__ import annotations

import math
import queue
import threading
import time
from dataclasses import dataclass

import numpy as np

from labrig.live.series import RepetitionSeries

# the fields of GET /api/state, in this order: a contract scripts rely on
STATE_FIELDS = (
    "t_s",
    "volume_ml",
    "pressure_kpa",
    "length_mm",
    "step",
    "repetition",
    "repetitions",
    "status",
)
FINAL_STATUSES = ("complete", "aborted", "faulted")
DETECT_EVERY_S = 1.0  # host seconds between transition detections on the newest data


@dataclass(frozen=True)
class RunInfo:
    """What the page shows that does not change during a run."""

    title: str
    repetitions: int
    duration_s: float
    max_volume_ml: float
    max_pressure_kpa: float
    segments: tuple[str, ...]


@dataclass(frozen=True)
class Step:
    """The step the run is in and its clock times (from the runner's progress)."""

    step: str
    repetition: int
    elapsed_s: float
    remaining_s: float


def _finite(x: float) -> float | None:
    return float(x) if x is not None and math.isfinite(x) else None


class LiveState:
    """The run as the live page sees it (see the module docstring)."""

    def __init__(self, info: RunInfo) -> None:
        self.info = info
        # published by the digest thread, read by any thread
        self.pressure_points: list[list] = []  # [repetition, t_s, v_ml, p_kpa], append-only
        self.length_points: list[list] = []  # [repetition, t_s, v_ml, l_mm], append-only
        self.transitions: tuple[dict, ...] = ()
        self.status = "starting"
        self.reason = ""
        self.detection_error = ""  # why the last transition detection failed, if it did
        self._latest = {"volume_ml": None, "pressure_kpa": None, "length_mm": None}
        self._step = Step("starting", 0, 0.0, info.duration_s)
        # the digest's own
        self._inbox: queue.SimpleQueue = queue.SimpleQueue()
        self._series: dict[int, RepetitionSeries] = {}
        self._found: dict[int, list[dict]] = {}
        self._dirty: set[int] = set()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._digest, name="live-digest", daemon=True)

    # --- the run's side: never blocks ----------------------------------------------------
    def tap(self, repetition: int, log: str, columns: dict) -> None:
        """Called by the run file's writer with every append (the arrays are not copied:
        the writer's callers never change an array once appended)."""
        self._inbox.put((repetition, log, columns))

    def progress(self, snapshot) -> None:
        """The runner's progress callback (``labrig.run.runner.Progress``)."""
        self._step = Step(
            snapshot.step, snapshot.repetition, snapshot.elapsed_s, snapshot.remaining_s
        )
        if self.status == "starting":
            self.status = "running"

    def set_step(self, step: Step) -> None:
        """The step, for a run followed from its file (``labrig.live.follow``)."""
        self._step = step

    def finish(self, status: str, reason: str = "") -> None:
        """The run has ended: its final status (complete, aborted, faulted)."""
        self.reason = reason
        self.status = status
        self._step = Step(
            "finished" if status == "complete" else "stopped",
            self._step.repetition,
            self._step.elapsed_s,
            0.0,
        )

    # --- the digest thread ---------------------------------------------------------------
    def start(self) -> LiveState:
        self._thread.start()
        return self

    def close(self) -> None:
        """Digest what was appended so far, then stop."""
        self._stop.set()
        self._thread.join(timeout=10)

    def _digest(self) -> None:
        next_detection = time.monotonic() + DETECT_EVERY_S
        while True:
            try:
                self._take(*self._inbox.get(timeout=0.1))
                while True:  # everything already queued, before detecting
                    self._take(*self._inbox.get_nowait())
            except queue.Empty:
                if self._stop.is_set():
                    break
            now = time.monotonic()
            if now >= next_detection:
                self._detect()
                next_detection = now + DETECT_EVERY_S
        self._detect()

    def _take(self, repetition: int, log: str, columns: dict) -> None:
        series = self._series.get(repetition)
        if series is None:
            series = self._series[repetition] = RepetitionSeries(repetition)
        n_p, n_l = len(series.pressure_points), len(series.length_points)
        # the writer takes scalars (one pump reading, one frame) as well as blocks
        c = {name: np.atleast_1d(values) for name, values in columns.items()}
        t, value = c["time"].astype(float), c["value"].astype(float)
        if log == "pressure":
            series.add_pressure(t, value, c["out_of_range"])
            self._latest["pressure_kpa"] = _finite(value[-1])
        elif log == "pump":
            series.add_pump(t, value)
            self._latest["volume_ml"] = _finite(value[-1])
        elif log == "length":
            ok = c["ok"].astype(bool)
            series.add_length(t, value, ok)
            if ok.any():
                self._latest["length_mm"] = _finite(value[ok][-1])
        self.pressure_points += [[repetition, *p] for p in series.pressure_points[n_p:]]
        self.length_points += [[repetition, *p] for p in series.length_points[n_l:]]
        self._dirty.add(repetition)

    def _detect(self) -> None:
        """Transitions of each repetition with new data, by the analysis' detector."""
        from labrig.analysis.transitions import detect_transitions

        for repetition in sorted(self._dirty):
            a = self._series[repetition].arrays()
            if len(a["pressure_t_s"]) < 2 or len(a["pump_t_s"]) < 2:
                continue
            with_length = len(a["length_t_s"]) >= 3
            try:
                found = detect_transitions(
                    repetition,
                    a["pressure_t_s"],
                    a["pressure_kpa"],
                    a["pump_t_s"],
                    a["pump_v_ml"],
                    a["length_t_s"] if with_length else None,
                    a["length_mm"] if with_length else None,
                )
            except Exception as exc:
                # the detector was made for whole repetitions: on a partial one it may
                # fail, and must not stop the live view; the page shows why, and the
                # next detection, on more data, tries again
                self.detection_error = f"repetition {repetition}: {exc!r}"
                continue
            self._found[repetition] = [self._marker(t, a) for t in found]
        self._dirty.clear()
        self.transitions = tuple(m for rep in sorted(self._found) for m in self._found[rep])

    @staticmethod
    def _marker(t, a: dict[str, np.ndarray]) -> dict:
        """A detected transition where the page marks it: its volume, and the pressure
        and length measured at its time."""

        def at(times: np.ndarray, values: np.ndarray) -> float | None:
            return _finite(np.interp(t.t_s, times, values)) if len(times) else None

        return {
            "repetition": t.repetition,
            "direction": "inflate" if t.direction > 0 else "deflate",
            "t_s": t.t_s,
            "v_ml": t.v_ml,
            "p_kpa": at(a["pressure_t_s"], a["pressure_kpa"]),
            "l_mm": at(a["length_t_s"], a["length_mm"]),
            "dp_kpa": _finite(t.dp_kpa),
            "dl_mm": _finite(t.dl_mm),
        }

    # --- the server's side: reads only -------------------------------------------------
    def state(self) -> dict:
        """GET /api/state: exactly ``STATE_FIELDS``."""
        step, latest = self._step, dict(self._latest)
        return {
            "t_s": step.elapsed_s,
            "volume_ml": latest["volume_ml"],
            "pressure_kpa": latest["pressure_kpa"],
            "length_mm": latest["length_mm"],
            "step": step.step,
            "repetition": step.repetition,
            "repetitions": self.info.repetitions,
            "status": self.status,
        }

    def series_since(self, pressure_from: int, length_from: int) -> dict:
        """The points appended since the given indices, with what the page shows beside
        the plot (transitions, time left, the reason a run stopped)."""
        n_p, n_l = len(self.pressure_points), len(self.length_points)
        step = self._step
        return {
            "pressure": self.pressure_points[max(0, pressure_from) : n_p],
            "length": self.length_points[max(0, length_from) : n_l],
            "next_pressure": n_p,
            "next_length": n_l,
            "transitions": list(self.transitions),
            "remaining_s": step.remaining_s,
            "reason": self.reason,
            "detection_error": self.detection_error,
        }
