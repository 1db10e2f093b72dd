"""What an emulated PHD ULTRA says and does: its command set, its settings and its
plunger, with no I/O.

``PumpFirmware`` takes one command line and returns the payload lines of its answer
and the state after it; ``sim.pump`` frames that for the serial line and injects the
faults. The plunger moves on the shared clock (``sim.syringe_drive``): volumes follow
the set rate, the run stops exactly at the target volume, and it stalls (silently, as
the real pump does) when the load pressure pushes back harder than its force limit.
The load is whatever is attached: ``load_pressure_kpa(t)`` is called with
non-decreasing clock times, never under this object's lock, so a plant may call
``net_volume_ml`` from it.

Models of the real pumps the driver must meet are options: the poll mode
it was left in (``poll on``: XON after each prompt; ``poll remote``: no prompts),
strict addressing (one address form is answered, any other ignored, as by a pump that
reads it as meant for another: the manual's form is none at address 0 and ``N:cmd``
elsewhere, ``manual_address_form``),
an infuse-only model (every withdraw command refused as unknown), and the memory
command the firmware knows (``nvram``, ``rsave`` or neither).

Units, parsing and formatting are written here independently of the driver's protocol
module on purpose: a shared unit table would hide a unit error from every test.
"""

from __future__ import annotations

import logging
import math
import re
import threading
from collections.abc import Callable
from dataclasses import dataclass

from labrig.drivers.phd_ultra_protocol import ADDRESS_FORMS, rate_limits_ml_min
from labrig.rig.devices import PumpState
from labrig.time.clock import Clock

from .syringe_drive import INFUSE, WITHDRAW, SyringeDrive

log = logging.getLogger(__name__)

FIRMWARE = "PHD ULTRA 3.0.5"
SERIAL_NUMBER = "EMU00001"
# The default syringe: the manual's example (`diameter 26.7`, `svolume 60 ml`), a 60 mL
# plastic syringe.
DEFAULT_DIAMETER_MM = 26.7
DEFAULT_SYRINGE_ML = 60.0
# PHD ULTRA catalogue: 75 lbf linear force at 100 % force (unverified).
MAX_FORCE_N = 75 * 4.4482216
DIAMETER_RANGE_MM = (0.1, 50.0)

_VOLUME_ML = {"ml": 1.0, "ul": 1e-3, "nl": 1e-6, "pl": 1e-9}
_TIME_MIN = {"min": 1.0, "hr": 60.0}
_RATE_SCALE = (("ml/min", 1.0), ("ul/min", 1e-3), ("nl/min", 1e-6), ("pl/min", 1e-9))
_VOLUME_SCALE = (("ml", 1.0), ("ul", 1e-3), ("nl", 1e-6), ("pl", 1e-9))
_COMMAND = re.compile(
    r"^(?:(?P<address>\d{1,2})(?P<colon>:)?)?@?(?P<word>[A-Za-z]*)\s*(?P<arg>.*)$"
)
POLL_MODES = ("off", "on", "remote")
MEMORY_COMMANDS = ("nvram", "rsave", None)
# What an infuse-only PHD ULTRA does not know (flowchem: "Unknown command" for a
# withdraw command sent to an infuse-only pump).
WITHDRAW_COMMANDS = frozenset(
    {"wrate", "wrun", "rrun", "wvolume", "cwvolume", "wtime", "cwtime", "wramp"}
)


class _Refused(Exception):
    """A command the pump answers with an error text (``lines``)."""

    def __init__(self, *lines: str) -> None:
        super().__init__(lines[0])
        self.lines = list(lines)


def manual_address_form(address: int) -> str:
    """The form the PHD ULTRA manual uses: an address only when it is not 0, as ``N:``."""
    return "none" if address == 0 else "colon"


def _argument_error(arg: str, detail: str = "Unknown argument") -> _Refused:
    # chembot's quote from a real pump: 'Argument error: [on]' then '   Unknown argument'.
    return _Refused(f"Argument error: [{arg}]", f"   {detail}")


def _not_now(word: str, detail: str) -> _Refused:
    return _Refused(f"Command error: [{word}]", f"   {detail}")


def _number(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise _argument_error(text) from None
    if not math.isfinite(value):
        raise _argument_error(text)
    return value


def _scaled(value: float, scale) -> str:
    if value == 0:
        return f"0 {scale[1][0]}"  # the pump shows an empty counter as '0 ul'
    for unit, factor in scale:
        if abs(value) >= factor:
            return f"{value / factor:.4f} {unit}"
    unit, factor = scale[-1]
    return f"{value / factor:.4f} {unit}"


@dataclass(frozen=True)
class Answer:
    """The answer to one command line: the full command name it was read as (after
    abbreviation), the payload lines, and the pump's state once it was executed."""

    command: str
    lines: list[str]
    state: PumpState


class PumpFirmware:
    """A PHD ULTRA's command interpreter and plunger. Thread-safe."""

    def __init__(
        self,
        clock: Clock,
        *,
        address: int = 0,
        diameter_mm: float = DEFAULT_DIAMETER_MM,
        syringe_ml: float = DEFAULT_SYRINGE_ML,
        load_pressure_kpa: Callable[[float], float] | None = None,
        stall_pressure_kpa: float | None = None,
        max_force_n: float = MAX_FORCE_N,
        on_target_reached: Callable[[], None] = lambda: None,
        poll_mode: str = "off",
        strict_address_form: str | None = None,
        infuse_only: bool = False,
        memory_command: str | None = "nvram",
        echo_settings: bool = False,
    ) -> None:
        """``stall_pressure_kpa`` fixes the stall limit; by default it follows from the
        force setting and the plunger area (``max_force_n`` at 100 %).
        ``on_target_reached`` is called (under the lock) when a run reaches its target.
        ``poll_mode`` is the mode the pump was left in; ``strict_address_form`` (one of
        ``ADDRESS_FORMS``) is the only address form answered, None answers any;
        ``infuse_only`` refuses withdraw commands;
        ``memory_command`` is the command that switches memory writes (or None);
        ``echo_settings``: the memory and force settings are answered with a line of
        text saying what was set (firmware seen to confirm them so), not a bare prompt."""
        if not 0 <= address <= 99:
            raise ValueError(f"address must be 0-99, got {address}")
        if poll_mode not in POLL_MODES:
            raise ValueError(f"poll_mode must be one of {POLL_MODES}, got {poll_mode!r}")
        if memory_command not in MEMORY_COMMANDS:
            raise ValueError(f"memory_command must be one of {MEMORY_COMMANDS}")
        if strict_address_form not in (*ADDRESS_FORMS, None):
            raise ValueError(f"strict_address_form must be one of {ADDRESS_FORMS} or None")
        self.poll_mode = poll_mode
        self.strict_address_form = strict_address_form
        self.infuse_only = infuse_only
        self.echo_settings = echo_settings
        self.clock = clock
        self.address = address
        self.max_force_n = max_force_n
        self._load = load_pressure_kpa
        self._fixed_stall_kpa = stall_pressure_kpa
        self._on_target_reached = on_target_reached
        self._lock = threading.RLock()
        self._drive = SyringeDrive(clock.now())
        self._generation = 0  # bumped by every change of motion, for the load check
        self._diameter_mm = diameter_mm
        self._syringe = (syringe_ml, "ml")
        # Set rate per direction in mL/min, with the unit it was set in (the pump shows
        # a rate in the unit it was given).
        self._rates = {INFUSE: (1.0, "ml/min"), WITHDRAW: (1.0, "ml/min")}
        self._target_unit = "ml"
        self._force_pct = 100
        self._nvram = "on"
        self._stall_armed = False
        self._commands = {
            "": lambda arg, now: [],
            "ver": self._ver,
            "version": self._version,
            "poll": lambda arg, now: self._choice(arg, "poll_mode", POLL_MODES),
            "force": self._force,
            "diameter": self._diameter,
            "svolume": self._svolume,
            "irate": lambda arg, now: self._rate(INFUSE, arg, now),
            "wrate": lambda arg, now: self._rate(WITHDRAW, arg, now),
            "tvolume": self._tvolume,
            "ivolume": lambda arg, now: [self._volume_text(INFUSE, now)],
            "wvolume": lambda arg, now: [self._volume_text(WITHDRAW, now)],
            "civolume": lambda arg, now: self._clear((INFUSE,), now),
            "cwvolume": lambda arg, now: self._clear((WITHDRAW,), now),
            "cvolume": lambda arg, now: self._clear((INFUSE, WITHDRAW), now),
            "ctvolume": lambda arg, now: self._set_target(None, now),
            "irun": lambda arg, now: self._run(INFUSE, now),
            "wrun": lambda arg, now: self._run(WITHDRAW, now),
            "run": lambda arg, now: self._run(self._drive.direction, now),
            "rrun": lambda arg, now: self._run(
                WITHDRAW if self._drive.direction == INFUSE else INFUSE, now
            ),
            "stop": self._stop,
            "stp": self._stop,
            "status": self._status,
        }
        if memory_command is not None:
            words = ("on", "off", "none") if memory_command == "nvram" else ("on", "off")
            self._commands[memory_command] = lambda arg, now: self._echoed(
                self._choice(arg, "_nvram", words), f"{memory_command.upper()} {arg}"
            )
        # The manual: any command can be shortened to its first 4 letters.
        self._aliases = {name[:4]: name for name in self._commands if len(name) > 4}

    # ---- what the plant, the server and tests read ---------------------------------

    def net_volume_ml(self, t_s: float) -> float:
        """Infused minus withdrawn at clock time ``t_s`` since the pump was made: the
        physical volume in the specimen, unaffected by clearing the counters."""
        with self._lock:
            return self._drive.net_ml(t_s)

    @property
    def state(self) -> PumpState:
        with self._lock:
            self._advance(self.clock.now())
            return self._state()

    @property
    def running(self) -> bool:
        with self._lock:
            return self._drive.running

    @property
    def target_stop_s(self) -> float:
        """When the current motion reaches its target volume (inf: it does not)."""
        with self._lock:
            return self._drive.end_s()

    @property
    def stall_pressure_kpa(self) -> float:
        """The load pressure above which the plunger stalls: the force limit over the
        plunger area, unless fixed at construction."""
        if self._fixed_stall_kpa is not None:
            return self._fixed_stall_kpa
        area_m2 = math.pi / 4 * (self._diameter_mm * 1e-3) ** 2
        return self.max_force_n * self._force_pct / 100 / area_m2 / 1e3

    @property
    def rate_limits_ml_min(self) -> tuple[float, float]:
        return rate_limits_ml_min(self._diameter_mm)

    # ---- what moves it -------------------------------------------------------------

    def stall(self) -> None:
        """Stall now if the plunger moves, else at the next run."""
        with self._lock:
            now = self.clock.now()
            self._advance(now)
            if self._drive.running:
                self._halt(now, stalled=True)
            else:
                self._stall_armed = True

    def tick(self, now: float) -> None:
        """Let time pass to ``now``: the target stop, then the load check."""
        with self._lock:
            self._advance(now)
        self._check_load(now)

    def execute(self, line: str) -> Answer | None:
        """Run one command line; None when it is addressed to another pump."""
        now = self.clock.now()
        self.tick(now)
        with self._lock:
            match = _COMMAND.match(line.strip())
            if not self._addressed_to_me(match):
                return None
            word = match["word"].lower()
            name = self._aliases.get(word, word)
            lines = self._dispatch(name, match["arg"].strip(), now)
            self._generation += 1
            self._advance(now)
            return Answer(name, lines, self._state())

    def _addressed_to_me(self, match: re.Match[str]) -> bool:
        """Tolerant: any form with this address, or none. Strict: that form only."""
        if match["address"] is None:
            form = "none"
        elif int(match["address"]) != self.address:
            return False
        else:
            form = "colon" if match["colon"] else "digits"
        return self.strict_address_form in (None, form)

    def _dispatch(self, name: str, arg: str, now: float) -> list[str]:
        handler = self._commands.get(name)
        if self.infuse_only and name in WITHDRAW_COMMANDS:
            handler = None
        if handler is None or (not name and arg):
            return [f"Command error: [{name or arg}]", "   Unknown command"]
        try:
            return handler(arg, now)
        except _Refused as refusal:
            return refusal.lines

    def _state(self) -> PumpState:
        drive = self._drive
        if drive.stalled:
            return PumpState.STALLED
        if drive.target_reached:
            return PumpState.TARGET_REACHED
        if drive.running:
            return PumpState.INFUSING if drive.direction == INFUSE else PumpState.WITHDRAWING
        return PumpState.IDLE

    def _advance(self, now: float) -> None:
        if self._drive.settle(now):
            self._generation += 1
            self._on_target_reached()

    def _halt(self, t_s: float, *, stalled: bool = False) -> None:
        self._drive.halt(max(t_s, self._drive.t0_s), stalled=stalled)
        self._generation += 1

    def _check_load(self, now: float) -> None:
        """Stall if the load pushes back harder than the force limit. The load function
        runs outside the lock, and its verdict is dropped if the motion changed meanwhile."""
        with self._lock:
            drive = self._drive
            if not drive.running:
                return
            if self._stall_armed:
                self._stall_armed = False
                self._halt(now, stalled=True)
                return
            if self._load is None:
                return
            generation, direction, limit = (
                self._generation,
                drive.direction,
                self.stall_pressure_kpa,
            )
        load_kpa = self._load(now)
        with self._lock:
            if generation != self._generation:
                return
            if (direction == INFUSE and load_kpa > limit) or (
                direction == WITHDRAW and load_kpa < -limit
            ):
                log.info("stalled at t=%.3f s: load %.1f kPa, limit %.1f kPa", now, load_kpa, limit)
                self._halt(now, stalled=True)

    # ---- commands ----------------------------------------------------------------

    def _ver(self, arg: str, now: float) -> list[str]:
        return [FIRMWARE]

    def _version(self, arg: str, now: float) -> list[str]:
        return [
            f"Firmware:      v{FIRMWARE.rsplit(' ', 1)[-1]}",
            f"Pump address:  {self.address}",
            f"Serial number: {SERIAL_NUMBER}",
        ]

    def _choice(self, arg: str, attribute: str, allowed: tuple[str, ...]) -> list[str]:
        """A command that shows or sets one of a few words (``poll``, ``nvram``, ``rsave``)."""
        if not arg:
            return [getattr(self, attribute)]
        if arg.lower() not in allowed:
            raise _argument_error(arg)
        setattr(self, attribute, arg.lower())
        return []

    def _force(self, arg: str, now: float) -> list[str]:
        if not arg:
            return [f"{self._force_pct}%"]
        if not arg.isdigit():
            raise _argument_error(arg)
        if not 1 <= int(arg) <= 100:
            raise _argument_error(arg, "Out of range")
        self._force_pct = int(arg)
        return self._echoed([], f"Force = {self._force_pct}%")

    def _echoed(self, lines: list[str], text: str) -> list[str]:
        """A setting's answer: ``lines`` (empty when it was set), or the confirming
        ``text`` with ``echo_settings``."""
        return [text] if self.echo_settings and not lines else lines

    def _diameter(self, arg: str, now: float) -> list[str]:
        if not arg:
            return [f"{self._diameter_mm:.4f} mm"]
        self._refuse_while_running("diameter")
        value = _number(arg)
        if not DIAMETER_RANGE_MM[0] <= value <= DIAMETER_RANGE_MM[1]:
            raise _argument_error(arg, "Out of range")
        self._diameter_mm = value
        # The new syringe's limits apply to the rates already set.
        low, high = self.rate_limits_ml_min
        for direction, (rate, unit) in self._rates.items():
            self._rates[direction] = (min(max(rate, low), high), unit)
        return []

    def _svolume(self, arg: str, now: float) -> list[str]:
        if not arg:
            value, unit = self._syringe
            return [f"{value / _VOLUME_ML[unit]:.4f} {unit}"]
        self._refuse_while_running("svolume")
        value_ml, unit = self._quantity(arg, {"ml", "ul"})
        self._syringe = (value_ml, unit)
        return []

    def _refuse_while_running(self, word: str) -> None:
        if self._drive.running:
            raise _not_now(word, "Not allowed while running")

    def _quantity(self, arg: str, units: set[str]) -> tuple[float, str]:
        """'5 ml' -> (5.0 mL, 'ml'); positive values in one of ``units`` only."""
        parts = arg.split()
        if len(parts) != 2 or parts[1].lower() not in units:
            raise _argument_error(arg)
        value = _number(parts[0])
        if value <= 0:
            raise _argument_error(arg, "Out of range")
        unit = parts[1].lower()
        return value * _VOLUME_ML[unit], unit

    def _rate(self, direction: str, arg: str, now: float) -> list[str]:
        rate, unit = self._rates[direction]
        low, high = self.rate_limits_ml_min
        if not arg:
            factor = _VOLUME_ML[unit.split("/")[0]] / _TIME_MIN[unit.split("/")[1]]
            return [f"{rate / factor:.4f} {unit}"]
        if arg.lower() == "lim":
            return [f"{_scaled(low, _RATE_SCALE)} to {_scaled(high, _RATE_SCALE)}"]
        if arg.lower() in ("max", "min"):
            new_rate = high if arg.lower() == "max" else low
        else:
            parts = arg.split()
            if len(parts) != 2:
                raise _argument_error(arg)
            volume_unit, _, time_unit = parts[1].lower().partition("/")
            if volume_unit not in _VOLUME_ML or time_unit not in _TIME_MIN:
                raise _argument_error(parts[1])
            unit = parts[1].lower()
            new_rate = _number(parts[0]) * _VOLUME_ML[volume_unit] / _TIME_MIN[time_unit]
            if not low * (1 - 1e-9) <= new_rate <= high * (1 + 1e-9):
                raise _argument_error(parts[0], "Out of range")
        self._rates[direction] = (new_rate, unit)
        if self._drive.running and self._drive.direction == direction:
            self._drive.change_rate(new_rate, now)
        return []

    def _tvolume(self, arg: str, now: float) -> list[str]:
        target = self._drive.target_ml
        if not arg:
            if target is None:
                return ["Target volume not set"]
            return [f"{target / _VOLUME_ML[self._target_unit]:.4f} {self._target_unit}"]
        target_ml, self._target_unit = self._quantity(arg, set(_VOLUME_ML))
        return self._set_target(target_ml, now)

    def _set_target(self, target_ml: float | None, now: float) -> list[str]:
        self._drive.set_target(target_ml, now)
        return []

    def _volume_text(self, direction: str, now: float) -> str:
        return _scaled(self._drive.counted_ml(direction, now), _VOLUME_SCALE)

    def _clear(self, directions: tuple[str, ...], now: float) -> list[str]:
        for direction in directions:
            self._drive.clear(direction, now)
        return []

    def _run(self, direction: str, now: float) -> list[str]:
        self._drive.start(direction, self._rates[direction][0], now)
        return []

    def _stop(self, arg: str, now: float) -> list[str]:
        self._halt(now)
        return []

    def _status(self, arg: str, now: float) -> list[str]:
        drive = self._drive
        direction = drive.direction
        # The rate field is the motor's rate: 0 when it stands (the real '0 0 0 w..TI.').
        rate_fl_s = round(drive.rate_ml_min * 1e12 / 60) if drive.running else 0
        time_ms = round(drive.run_time_s(direction, now) * 1e3)
        volume_fl = round(drive.counted_ml(direction, now) * 1e12)
        flags = (
            (direction.upper() if drive.running else direction)
            + "."  # limit switch: always '.' on a PHD ULTRA
            + ("S" if drive.stalled else ".")
            + "T"  # trigger input, idle high as in the real example
            + "I"  # direction port
            + ("T" if drive.target_reached else ".")
        )
        return [f"{rate_fl_s} {time_ms} {volume_fl} {flags}"]
