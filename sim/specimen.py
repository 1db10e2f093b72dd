"""The simulated specimen's real-world behaviour: what a real specimen does that its
segments' curves do not say (the rig file's ``sim.specimen``).

The curves give the pressure at a volume on a reversible path; a latex specimen on the
bench is softer on its way down (hysteresis), stiffer on its first inflation than ever
after (the Mullins effect), may weep at a fitting, and may burst. Each is off by default,
so a simulated specimen is exactly its curves unless the rig file says otherwise.

- ``scaled_curve``: the pressure scaled at equal volume (a stiffer or softer specimen).
- ``LeakyVolume``: the volume the specimen holds when a share of the pump's infused flow
  is lost at it; what leaks never comes back.
- ``SpecimenBehaviour``: the sensor pressure changed by hysteresis, the first cycle and
  a burst, applied in time order to the plant's pressure as it is computed.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import replace

from labrig.model.segments.curve import SegmentCurve

# The volume withdrawn over which deflation reaches its full hysteresis (and infused over
# which inflation leaves it): a latex wall turns from loading to unloading over a small
# strain, not at once.
HYSTERESIS_TURN_ML = 0.5
# The shape of the Mullins softening below the largest volume held: the factor is
# 1 + (f - 1) (v / v_max)^4, the virgin stiffness at v_max, nearly none well below it.
MULLINS_EXPONENT = 4


def scaled_curve(curve: SegmentCurve, factor: float) -> SegmentCurve:
    """``curve`` with its pressure multiplied by ``factor`` at every volume."""
    if factor == 1.0:
        return curve
    return replace(curve, p_kpa=curve.p_kpa * factor, measured=None)


class LeakyVolume:
    """The volume in the specimen when ``fraction`` of the pump's infused flow leaks
    away: the pump's net volume minus the leaked share of everything infused so far.

    Times are asked in increasing order by a plant (a solver's step may look slightly
    back: the loss there is taken as it was at the latest time asked). Thread-safe.
    """

    def __init__(self, volume_ml_at: Callable[[float], float], fraction: float) -> None:
        self.volume_ml_at = volume_ml_at
        self.fraction = float(fraction)
        self._lock = threading.Lock()
        self._t_s = float("-inf")
        self._v_ml = 0.0
        self._lost_ml = 0.0

    @property
    def lost_ml(self) -> float:
        with self._lock:
            return self._lost_ml

    def __call__(self, t_s: float) -> float:
        v_ml = float(self.volume_ml_at(t_s))
        with self._lock:
            if self._t_s == float("-inf"):
                self._t_s, self._v_ml = t_s, v_ml
            if t_s >= self._t_s:
                self._lost_ml += self.fraction * max(v_ml - self._v_ml, 0.0)
                self._t_s, self._v_ml = t_s, v_ml
                return v_ml - self._lost_ml
            return v_ml - self._lost_ml + self.fraction * max(self._v_ml - v_ml, 0.0)


class SpecimenBehaviour:
    """The sensor pressure of a specimen with hysteresis, a first cycle and a burst.

    ``pressure_kpa(t_s, volume_ml, p_kpa)`` is called by a plant at each time it records,
    in increasing time: ``volume_ml`` is the volume in the specimen, ``p_kpa`` the
    pressure its curves give there. ``pump_volume_ml_at`` is the volume the pump has
    supplied (a burst opens the specimen at a supplied volume).
    """

    def __init__(
        self,
        pump_volume_ml_at: Callable[[float], float],
        *,
        hysteresis_kpa: float = 0.0,
        first_cycle_factor: float = 1.0,
        burst_at_ml: float | None = None,
    ) -> None:
        self.pump_volume_ml_at = pump_volume_ml_at
        self.hysteresis_kpa = float(hysteresis_kpa)
        self.first_cycle_factor = float(first_cycle_factor)
        self.burst_at_ml = burst_at_ml
        self.burst_s: float | None = None  # when it burst
        self._previous_ml: float | None = None
        self._max_ml = 0.0
        self._unloading = 0.0  # 0 on the loading path, 1 on the unloading one

    def pressure_kpa(self, t_s: float, volume_ml: float, p_kpa: float) -> float:
        if self.burst_s is not None:
            return 0.0
        if self.burst_at_ml is not None and self.pump_volume_ml_at(t_s) >= self.burst_at_ml:
            self.burst_s = t_s  # open to the air from here on
            return 0.0
        previous = volume_ml if self._previous_ml is None else self._previous_ml
        self._previous_ml = volume_ml
        self._unloading = min(
            max(self._unloading + (previous - volume_ml) / HYSTERESIS_TURN_ML, 0.0), 1.0
        )
        if self.first_cycle_factor != 1.0:
            self._max_ml = max(self._max_ml, volume_ml)
            share = (max(volume_ml, 0.0) / self._max_ml) ** MULLINS_EXPONENT if self._max_ml else 1
            p_kpa *= 1.0 + (self.first_cycle_factor - 1.0) * share
        if self.hysteresis_kpa:
            p_kpa -= self._unloading * min(self.hysteresis_kpa, max(p_kpa, 0.0) / 2)
        return p_kpa
