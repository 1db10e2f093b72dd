"""The PHD ULTRA's commands on quantities: the syringe (diameter, syringe volume, the
built-in table, gang), the rates and ramps, the target volume and time, and the volume
and time counters. A mixin of ``PumpFirmware``, which owns the state it works on (the
plunger ``_drive``, the syringe, the set rates and ramps) and calls these under its lock.
"""

from __future__ import annotations

from dataclasses import dataclass

from .pump_refusals import argument_error, command_error, range_error
from .pump_syringes import choose, manufacturer_lines
from .pump_units import (
    UnitError,
    clock_text,
    diameter_text,
    number_text,
    rate_text,
    read_duration_s,
    read_number,
    read_rate_ml_min,
    read_volume_ml,
    read_volume_unit,
    volume_text,
)

DIAMETER_RANGE_MM = (0.1, 50.0)
GANG_RANGE = (1, 2)  # the standard rack holds two syringes


@dataclass(frozen=True)
class Ramp:
    """A rate ramp (``iramp``/``wramp``), run as a staircase at every load check."""

    start_ml_min: float
    end_ml_min: float
    seconds: float
    time_base: str

    def rate_ml_min(self, elapsed_s: float) -> float:
        share = min(max(elapsed_s / self.seconds, 0.0), 1.0) if self.seconds > 0 else 1.0
        return self.start_ml_min + (self.end_ml_min - self.start_ml_min) * share

    @property
    def text(self) -> str:
        start = rate_text(self.start_ml_min, self.time_base)
        end = rate_text(self.end_ml_min, self.time_base)
        return f"{start} to {end} in {number_text(self.seconds)} seconds"


class QuantityCommands:
    """Handlers ``(arg, now) -> payload lines``; refusals raise ``Refused``."""

    # ---- syringe -------------------------------------------------------------------

    def _diameter(self, arg: str, now: float) -> list[str]:
        """``diameter 14.567`` or ``diameter 14.567 mm`` (flowchem sends the unit)."""
        if not arg:
            return [diameter_text(self._diameter_mm)]
        words = arg.split()
        if len(words) > 2 or (len(words) == 2 and words[1].lower() != "mm"):
            raise argument_error(arg)
        value = self._number(words[0])
        if not DIAMETER_RANGE_MM[0] <= value <= DIAMETER_RANGE_MM[1]:
            low, high = (f"{number_text(x)} mm" for x in DIAMETER_RANGE_MM)
            raise range_error(words[0], "Diameter", low, high)
        self._refuse_while_running("diameter")
        self._set_syringe(value, self._syringe_ml, None)
        return []

    def _set_syringe(self, diameter_mm: float, volume_ml: float, choice) -> None:
        self._diameter_mm = diameter_mm
        self._syringe_ml = volume_ml
        self._syringe_choice = choice
        # The new syringe's limits apply to the rates already set.
        low, high = self.rate_limits_ml_min
        for direction, (rate, base) in self._rates.items():
            self._rates[direction] = (min(max(rate, low), high), base)

    def _svolume(self, arg: str, now: float) -> list[str]:
        if not arg:
            return [volume_text(self._syringe_ml)]
        words = arg.split()
        if len(words) != 2 or read_volume_unit_or_none(words[1]) not in ("ml", "ul"):
            raise argument_error(arg)
        volume_ml = self._volume_ml(words[0], words[1])
        self._refuse_while_running("svolume")
        self._set_syringe(self._diameter_mm, volume_ml, None)
        return []

    def _syrm(self, arg: str, now: float) -> list[str]:
        """``syrm``: the syringe from the table (or ``Custom``); ``syrm ?``: the
        manufacturers; ``syrm bdp 60 ml``: set diameter and volume from the table."""
        if not arg:
            choice = self._syringe_choice
            return [choice.text if choice else f"Custom {volume_text(self._syringe_ml)}"]
        if arg.strip() == "?":
            return manufacturer_lines("?")
        choice = choose(arg)
        self._refuse_while_running("syrm")
        self._set_syringe(choice.diameter_mm, choice.volume_ml, choice)
        return []

    def _gang_command(self, arg: str, now: float) -> list[str]:
        if not arg:
            return [f"{self._gang} syringes"]
        if not arg.isdigit():
            raise argument_error(arg)
        if not GANG_RANGE[0] <= int(arg) <= GANG_RANGE[1]:
            raise range_error(arg, "Syringe count", *map(str, GANG_RANGE))
        self._gang = int(arg)
        return []

    def _refuse_while_running(self, word: str) -> None:
        if self._drive.running:
            raise command_error(word, "Not allowed while running")

    @staticmethod
    def _number(text: str) -> float:
        try:
            return read_number(text)
        except UnitError as exc:
            raise argument_error(exc.text) from None

    @staticmethod
    def _volume_ml(value: str, unit: str) -> float:
        """A positive volume in any volume spelling."""
        try:
            volume_ml, _ = read_volume_ml(value, unit)
        except UnitError as exc:
            raise argument_error(exc.text) from None
        if volume_ml <= 0:
            raise argument_error(value, "Out of range")
        return volume_ml

    # ---- rates and ramps -----------------------------------------------------------

    def _read_rate(self, value: str, unit: str) -> tuple[float, str]:
        """A rate within the syringe's limits: (mL/min, time base)."""
        try:
            rate, base = read_rate_ml_min(value, unit)
        except UnitError as exc:
            raise argument_error(exc.text) from None
        low, high = self.rate_limits_ml_min
        if not low * (1 - 1e-9) <= rate <= high * (1 + 1e-9):
            raise range_error(value, "Rate", rate_text(low), rate_text(high))
        return rate, base

    def _rate(self, direction: str, arg: str, now: float) -> list[str]:
        rate, base = self._rates[direction]
        low, high = self.rate_limits_ml_min
        if not arg:
            return [rate_text(rate, base)]
        if arg.lower() == "lim":
            return [f"{rate_text(low)} to {rate_text(high)}"]
        if arg.lower() in ("max", "min"):
            new_rate = high if arg.lower() == "max" else low
        else:
            words = arg.split()
            if len(words) != 2:
                raise argument_error(arg)
            new_rate, base = self._read_rate(*words)
        self._rates[direction] = (new_rate, base)
        self._ramps[direction] = None  # a plain rate replaces the ramp
        if self._drive.running and self._drive.direction == direction:
            self._drive.change_rate(new_rate, now)
        return []

    def _crate(self, arg: str, now: float) -> list[str]:
        """The motor's rate now (0 while it stands), in the set rate's time base."""
        drive = self._drive
        base = self._rates[drive.direction][1]
        return [rate_text(drive.rate_ml_min if drive.running else 0.0, base)]

    def _ramp(self, direction: str, arg: str) -> list[str]:
        if not arg:
            ramp = self._ramps[direction]
            return [ramp.text if ramp else "Ramp not set up"]
        words = arg.split()
        if len(words) != 5:
            raise argument_error(arg)
        start, base = self._read_rate(words[0], words[1])
        end, _ = self._read_rate(words[2], words[3])
        seconds = self._number(words[4])
        if seconds <= 0:
            raise argument_error(words[4], "Out of range")
        self._ramps[direction] = Ramp(start, end, seconds, base)
        return []

    # ---- volumes and times ---------------------------------------------------------

    def _tvolume(self, arg: str, now: float) -> list[str]:
        target = self._drive.target_ml
        if not arg:
            return ["Target volume not set" if target is None else volume_text(target)]
        words = arg.split()
        if len(words) != 2:
            raise argument_error(arg)
        self._drive.set_target(self._volume_ml(*words), now)
        return []

    def _ttime(self, arg: str, now: float) -> list[str]:
        target = self._drive.target_s
        if not arg:
            return ["Target time not set" if target is None else clock_text(target)]
        try:
            seconds = read_duration_s(arg)
        except UnitError as exc:
            raise argument_error(exc.text) from None
        if seconds <= 0:
            raise argument_error(arg, "Out of range")
        self._drive.set_target_time(seconds, now)
        return []

    def _clear(self, clear, directions: tuple[str, ...], now: float) -> list[str]:
        for direction in directions:
            clear(direction, now)
        return []


def read_volume_unit_or_none(text: str) -> str | None:
    """The canonical volume unit, or None for a spelling that is not one."""
    try:
        return read_volume_unit(text)
    except UnitError:
        return None
