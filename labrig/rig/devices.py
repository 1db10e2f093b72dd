"""The device contracts: what the runner needs from a pump, a pressure source and a
length source, and the ``Rig`` that holds one of each with the clock they share.

Small runtime-checkable protocols in physical units, after bluesky's ``protocols.py``:
a real driver and a simulator are interchangeable because both fit the same contract,
with no base class. Drivers convert at their edges; nothing past this line sees a
device's own units. Every timestamp is on the run's shared clock (``labrig.time.clock``).
"""

from __future__ import annotations

import enum
import functools
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np

from labrig.time.clock import Clock


class PumpState(enum.Enum):
    """What the pump's motor is doing, from its prompt and its status flags."""

    IDLE = "idle"
    INFUSING = "infusing"
    WITHDRAWING = "withdrawing"
    STALLED = "stalled"
    TARGET_REACHED = "target reached"


@dataclass(frozen=True)
class PumpStatus:
    """One reading of the pump.

    ``infused_ml`` and ``withdrawn_ml`` count since the volumes were last cleared; the
    volume the pump has put into the specimen is their difference.
    """

    t_s: float
    state: PumpState
    infused_ml: float
    withdrawn_ml: float

    @property
    def net_volume_ml(self) -> float:
        return self.infused_ml - self.withdrawn_ml


@runtime_checkable
class Pump(Protocol):
    """A syringe pump that infuses into and withdraws from the specimen.

    Volumes in mL, rates in mL/min, diameters in mm. ``stop`` must be safe to call at
    any time and from any thread: interlocks call it first when something goes wrong.
    """

    def configure_syringe(self, diameter_mm: float, volume_ml: float) -> None:
        """Set the syringe's inner diameter and nominal volume."""
        ...

    def set_infuse_rate(self, rate_ml_min: float) -> None: ...

    def set_withdraw_rate(self, rate_ml_min: float) -> None: ...

    def set_target_volume(self, volume_ml: float) -> None:
        """Stop by itself after this volume (counted from the last clear) is moved."""
        ...

    def clear_volumes(self) -> None:
        """Zero the infused and withdrawn volume counters (and the target)."""
        ...

    def infuse(self) -> None:
        """Start infusing at the set infuse rate."""
        ...

    def withdraw(self) -> None:
        """Start withdrawing at the set withdraw rate."""
        ...

    def stop(self) -> None: ...

    def status(self) -> PumpStatus: ...


@dataclass(frozen=True)
class PressureBlock:
    """Consecutive pressure samples: times in s on the shared clock, pressure in kPa
    (gauge, after zeroing). ``out_of_range`` flags samples beyond the sensor's or the
    ADC's range: they are kept as measured, never clipped. ``wire_open`` flags, among
    them, the samples above the sensor's output band before the zero is taken off,
    where the rig's pull-up holds a cut output wire (None: no sample is)."""

    t_s: np.ndarray
    pressure_kpa: np.ndarray
    out_of_range: np.ndarray
    wire_open: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.t_s)

    @functools.cached_property
    def all_good(self) -> bool:
        """Every sample a finite reading within range (nearly every block): what each
        interlock asks first, answered once a block."""
        return bool(np.isfinite(self.pressure_kpa).all() and not self.out_of_range.any())


@runtime_checkable
class PressureSource(Protocol):
    """A pressure sensor read by hardware-timed acquisition."""

    def zero(self, duration_s: float = 1.0) -> float:
        """Take the zero offset at atmospheric pressure; return it in kPa."""
        ...

    def start(self, rate_hz: float) -> None:
        """Start continuous acquisition at ``rate_hz`` samples per second."""
        ...

    def read(self) -> PressureBlock:
        """Every sample acquired since the last read (possibly none)."""
        ...

    def stop(self) -> None: ...


@dataclass(frozen=True)
class LengthSample:
    """The specimen's length from one camera frame.

    Marker positions in px, length in mm; ``ok`` is False when a marker was lost or two
    merged, and then the length is NaN rather than a wrong number. ``image`` is the
    frame it was measured in (an array, or an array-like that renders on access), for
    a video of the run; None when the source keeps no frames.
    """

    t_s: float
    x1_px: float
    y1_px: float
    x2_px: float
    y2_px: float
    length_mm: float
    ok: bool
    image: Any = field(default=None, repr=False, compare=False)


@runtime_checkable
class LengthSource(Protocol):
    """A camera with a marker tracker: frames in, specimen length out."""

    def read(self) -> LengthSample | None:
        """Grab one frame and measure it; None when no frame is available."""
        ...

    @property
    def measured_fps(self) -> float | None:
        """The frame rate the camera really gave so far; None before two frames."""
        ...

    def close(self) -> None: ...


@dataclass
class Rig:
    """The devices of one run and the clock they share."""

    clock: Clock
    pump: Pump
    pressure: PressureSource
    length: LengthSource | None
    config_text: str
    close: Callable[[], None] = lambda: None
    # The simulated specimen and emulators behind the drivers, when simulated: the
    # truth that tests and benchmarks compare the recorded data with.
    simulation: object | None = None
    # who answers the protocol's prompts and pushes the reservoir (labrig.run.technician)
    technician: object | None = None
