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

It answers every command of ``sim.pump_commands.COMMANDS`` (the run, rate, volume,
time, ramp and syringe commands here; the system, method and I/O settings in
``sim.pump_panel``; the syringe table in ``sim.pump_syringes``), by its full name or
its first four letters, with an optional ``@`` before it (chembot) and an address
before that. Numbers and units are read and printed as the firmware does
(``sim.pump_units``), refusals in the firmware's error texts (``sim.pump_refusals``).

Models of the real pumps the driver must meet are options: the poll mode
it was left in (``poll on``: XON after each prompt; ``poll remote``: no prompts),
strict addressing (one address form is answered, any other ignored, as by a pump that
reads it as meant for another: the manual's form is none at address 0 and ``N:cmd``
elsewhere, ``manual_address_form``; ``"real"``: the forms real pumps are seen to take),
an infuse-only model (every withdraw command refused as unknown, and ``metrics`` says
so), and the memory command the firmware knows (``nvram``, ``rsave`` or neither).
"""

from __future__ import annotations

import collections
import logging
import math
import re
import threading
from collections.abc import Callable
from dataclasses import dataclass

from labrig.drivers.phd_ultra_protocol import ADDRESS_FORMS, rate_limits_ml_min
from labrig.rig.devices import PumpState
from labrig.time.clock import Clock

from .pump_commands import WITHDRAW_COMMANDS
from .pump_methods import METHODS
from .pump_panel import PanelSettings
from .pump_quantity_commands import DIAMETER_RANGE_MM, QuantityCommands, Ramp
from .pump_refusals import (
    Refused,
    argument_error,
    command_error,
    range_error,
    unknown_command,
    word_setting,
)
from .pump_syringes import SyringeChoice, manufacturer_lines
from .pump_units import (
    clock_text,
    number_text,
    volume_text,
)
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
_COMMAND = re.compile(
    r"^(?:(?P<address>\d{1,2})(?P<colon>:)?)?@?(?P<word>[A-Za-z]*)\s*(?P<arg>.*)$"
)
POLL_MODES = ("off", "on", "remote")
MEMORY_COMMANDS = ("nvram", "rsave", None)
# The address forms real pumps are seen to answer: at address 0 none (the manual, chembot)
# or the digits `0`/`00` (flowchem, BioCAT); elsewhere the manual's `N:`.
REAL_ADDRESSING = "real"


def manual_address_form(address: int) -> str:
    """The form the PHD ULTRA manual uses: an address only when it is not 0, as ``N:``."""
    return "none" if address == 0 else "colon"


@dataclass(frozen=True)
class Answer:
    """The answer to one command line: the full command name it was read as (after
    abbreviation), the payload lines, and the pump's state once it was executed."""

    command: str
    lines: list[str]
    state: PumpState


class PumpFirmware(QuantityCommands):
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
        serial_number: str = SERIAL_NUMBER,
        metrics_direction: bool = True,
        quick_start: str = "iw",
        method: str | None = None,
        locked: bool = False,
    ) -> None:
        """``stall_pressure_kpa`` fixes the stall limit; by default it follows from the
        force setting and the plunger area (``max_force_n`` at 100 %).
        ``serial_number``: what ``version`` says (another pump: another number);
        ``metrics_direction``: False for firmware whose ``metrics`` has no Direction
        line; ``quick_start``, ``method``, ``locked``: the mode it was left in (a Quick
        Start variant, a user method of ``sim.pump_methods``, the method lock).
        ``on_target_reached`` is called (under the lock) when a run reaches its target.
        ``poll_mode`` is the mode the pump was left in; ``strict_address_form`` (one of
        ``ADDRESS_FORMS``, or ``REAL_ADDRESSING``) is the only address form answered,
        None answers any; ``infuse_only`` refuses withdraw commands;
        ``memory_command`` is the command that switches memory writes (or None);
        ``echo_settings``: the memory and force settings are answered with a line of
        text saying what was set (firmware seen to confirm them so), not a bare prompt."""
        if not 0 <= address <= 99:
            raise ValueError(f"address must be 0-99, got {address}")
        if poll_mode not in POLL_MODES:
            raise ValueError(f"poll_mode must be one of {POLL_MODES}, got {poll_mode!r}")
        if memory_command not in MEMORY_COMMANDS:
            raise ValueError(f"memory_command must be one of {MEMORY_COMMANDS}")
        if strict_address_form not in (*ADDRESS_FORMS, REAL_ADDRESSING, None):
            raise ValueError(
                f"strict_address_form must be one of {ADDRESS_FORMS}, {REAL_ADDRESSING!r} or None"
            )
        self.poll_mode = poll_mode
        self.serial_number = serial_number
        self.metrics_direction = metrics_direction
        # every command line addressed to this pump, as read (what tests look for)
        self.executed: collections.deque[str] = collections.deque(maxlen=10_000)
        self.strict_address_form = strict_address_form
        self.infuse_only = infuse_only
        self.echo_settings = echo_settings
        self.clock = clock
        self.max_force_n = max_force_n
        self._load = load_pressure_kpa
        self._fixed_stall_kpa = stall_pressure_kpa
        self._on_target_reached = on_target_reached
        self._lock = threading.RLock()
        self._drive = SyringeDrive(clock.now())
        self._generation = 0  # bumped by every change of motion, for the load check
        self._panel = PanelSettings(address, quick_start=quick_start, method=method, locked=locked)
        # the running method's step (None: no method running) and its pause's end
        self._method_step: int | None = None
        self._pause_end_s: float | None = None
        self._diameter_mm = diameter_mm
        self._syringe_ml = syringe_ml
        self._syringe_choice: SyringeChoice | None = None
        self._gang = 1
        # Set rate per direction in mL/min, with the time base it was set in (the pump
        # shows a rate per minute, hour or second as it was given).
        self._rates = {INFUSE: (1.0, "min"), WITHDRAW: (1.0, "min")}
        self._ramps: dict[str, Ramp | None] = {INFUSE: None, WITHDRAW: None}
        self._ramp_start_s = 0.0
        self._force_pct = 100
        self._nvram = "on"
        self._stall_armed = False
        handlers = {
            "ver": lambda arg, now: [FIRMWARE],
            "version": self._version,
            "metrics": self._metrics,
            "poll": lambda arg, now: word_setting(self, "poll_mode", arg, POLL_MODES),
            "force": self._force,
            "diameter": self._diameter,
            "svolume": self._svolume,
            "syrm": self._syrm,
            "syrmanu": lambda arg, now: manufacturer_lines(arg),
            "gang": self._gang_command,
            "irate": lambda arg, now: self._rate(INFUSE, arg, now),
            "wrate": lambda arg, now: self._rate(WITHDRAW, arg, now),
            "crate": self._crate,
            "iramp": lambda arg, now: self._ramp(INFUSE, arg),
            "wramp": lambda arg, now: self._ramp(WITHDRAW, arg),
            "tvolume": self._tvolume,
            "ivolume": lambda arg, now: [volume_text(self._drive.counted_ml(INFUSE, now))],
            "wvolume": lambda arg, now: [volume_text(self._drive.counted_ml(WITHDRAW, now))],
            "civolume": lambda arg, now: self._clear(self._drive.clear, (INFUSE,), now),
            "cwvolume": lambda arg, now: self._clear(self._drive.clear, (WITHDRAW,), now),
            "cvolume": lambda arg, now: self._clear(self._drive.clear, (INFUSE, WITHDRAW), now),
            "ctvolume": lambda arg, now: self._drive.set_target(None, now) or [],
            "itime": lambda arg, now: [clock_text(self._drive.run_time_s(INFUSE, now))],
            "wtime": lambda arg, now: [clock_text(self._drive.run_time_s(WITHDRAW, now))],
            "ttime": self._ttime,
            "citime": lambda arg, now: self._clear(self._drive.clear_time, (INFUSE,), now),
            "cwtime": lambda arg, now: self._clear(self._drive.clear_time, (WITHDRAW,), now),
            "ctime": lambda arg, now: self._clear(self._drive.clear_time, (INFUSE, WITHDRAW), now),
            "cttime": lambda arg, now: self._drive.set_target_time(None, now) or [],
            "irun": lambda arg, now: self._run(INFUSE, now),
            "wrun": lambda arg, now: self._run(WITHDRAW, now),
            "run": self._run_command,
            "rrun": lambda arg, now: self._run(
                WITHDRAW if self._drive.direction == INFUSE else INFUSE, now
            ),
            "stop": self._stop,
            "stp": self._stop,
            "status": self._status,
        }
        for name, handler in self._panel.handlers.items():
            handlers[name] = lambda arg, now, handler=handler: handler(arg)
        handlers["load"] = self._load_command
        if memory_command is not None:
            words = ("on", "off", "none") if memory_command == "nvram" else ("on", "off")
            handlers[memory_command] = lambda arg, now: self._echoed(
                word_setting(self, "_nvram", arg, words), f"{memory_command.upper()} {arg}"
            )
        self._commands = handlers
        # The manual: any command can be shortened to its first 4 letters (where that
        # is not itself a command: `syrm` is not `syrmanu`).
        self._aliases = {
            name[:4]: name for name in handlers if len(name) > 4 and name[:4] not in handlers
        }

    # ---- what the plant, the server and tests read ---------------------------------

    @property
    def address(self) -> int:
        """The pump's address (the ``address`` command changes it)."""
        return self._panel.address

    @property
    def commands(self) -> frozenset[str]:
        """Every command this firmware answers, by its full name."""
        return frozenset(self._commands)

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
    def next_event_s(self) -> float:
        """When the plunger's next event of its own is due: the current motion reaching
        its target volume or time, or a method's pause ending (inf: none)."""
        with self._lock:
            pause_end_s = math.inf if self._pause_end_s is None else self._pause_end_s
            return min(self._drive.end_s(), pause_end_s)

    @property
    def method_running(self) -> bool:
        """A user method is running (moving, or standing in one of its pauses)."""
        with self._lock:
            return self._method_step is not None

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
        """Let time pass to ``now``: the target stop, a ramp's next step, then the load
        check."""
        with self._lock:
            self._advance(now)
            self._step_ramp(now)
        self._check_load(now)

    def execute(self, line: str) -> Answer | None:
        """Run one command line; None when it is addressed to another pump."""
        now = self.clock.now()
        self.tick(now)
        with self._lock:
            match = _COMMAND.match(line.strip())
            if not self._addressed_to_me(match):
                return None
            self.executed.append(line)
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
        if self.strict_address_form == REAL_ADDRESSING:
            return form in (("none", "digits") if self.address == 0 else ("colon",))
        return self.strict_address_form in (None, form)

    def _dispatch(self, name: str, arg: str, now: float) -> list[str]:
        handler = self._commands.get(name)
        if self.infuse_only and name in WITHDRAW_COMMANDS:
            handler = None
        try:
            if handler is None:
                if name or arg:
                    raise unknown_command(name or arg)
                return []  # an empty line: the prompt alone (flowchem's status check)
            return handler(arg, now)
        except Refused as refusal:
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
        """Apply what happened by ``now``: a target stop, and in a method each step
        that ended since (the next one starts when the last ended, not when noticed)."""
        while True:
            end_s = self._drive.end_s()
            if self._drive.settle(now):
                self._generation += 1
                if self._method_step is None:
                    self._on_target_reached()
                    return
                self._method_next(end_s)
            elif self._pause_end_s is not None and self._pause_end_s <= now:
                end_s, self._pause_end_s = self._pause_end_s, None
                self._method_next(end_s)
            else:
                return

    def _method_next(self, t_s: float) -> None:
        """Start the running method's next step at ``t_s``, or end the method."""
        steps = METHODS[self._panel.method]
        index = self._method_step + 1
        if index >= len(steps):
            self._method_step = None
            if self._drive.target_reached:
                self._on_target_reached()
            return
        self._start_step(index, t_s)

    def _start_step(self, index: int, t_s: float) -> None:
        step = METHODS[self._panel.method][index]
        self._method_step = index
        self._generation += 1
        if step.direction is None:
            self._drive.target_reached = False  # standing, the idle prompt
            self._pause_end_s = t_s + step.pause_s
            return
        counted_ml = self._drive.counted_ml(step.direction, t_s)
        self._drive.set_target(counted_ml + step.volume_ml, t_s)
        self._drive.start(step.direction, step.rate_ml_min, t_s)

    def _halt(self, t_s: float, *, stalled: bool = False) -> None:
        """Stop the plunger (a stop, a stall): a running method ends with it."""
        self._drive.halt(max(t_s, self._drive.t0_s), stalled=stalled)
        self._method_step = self._pause_end_s = None
        self._generation += 1

    def _step_ramp(self, now: float) -> None:
        drive = self._drive
        ramp = self._ramps[drive.direction]
        if drive.running and ramp is not None:
            rate = ramp.rate_ml_min(now - self._ramp_start_s)
            if rate != drive.rate_ml_min:
                drive.change_rate(rate, now)

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

    # ---- system commands ---------------------------------------------------------

    def _version(self, arg: str, now: float) -> list[str]:
        return [
            f"Firmware:      v{FIRMWARE.rsplit(' ', 1)[-1]}",
            f"Pump address:  {self.address}",
            f"Serial number: {self.serial_number}",
        ]

    def _metrics(self, arg: str, now: float) -> list[str]:
        """The layout flowchem quotes from a Pump 11 Elite, with the PHD ULTRA's figures;
        the Direction line is what tells a client whether the pump withdraws."""
        direction = "Infuse only" if self.infuse_only else "Infuse/withdraw"
        model = f"{FIRMWARE.rsplit(' ', 1)[0]} {'I' if self.infuse_only else 'I/W'}"
        rows = (
            ("Pump type", FIRMWARE.rsplit(" ", 1)[0]),
            ("Pump type string", model),
            ("Min syringe size", f"{number_text(DIAMETER_RANGE_MM[0])} mm"),
            ("Max syringe size", f"{number_text(DIAMETER_RANGE_MM[1])} mm"),
            ("Direction", direction),
            ("Programmable", "Yes"),
            ("Limit switches", "No"),
        )
        shown = [row for row in rows if self.metrics_direction or row[0] != "Direction"]
        return [f"{name:<19}{value}" for name, value in shown]

    def _force(self, arg: str, now: float) -> list[str]:
        if not arg:
            return [f"{self._force_pct}%"]
        if not arg.isdigit():
            raise argument_error(arg)
        if not 1 <= int(arg) <= 100:
            raise range_error(arg, "Force", "1%", "100%")
        self._force_pct = int(arg)
        return self._echoed([], f"Force = {self._force_pct}%")

    def _echoed(self, lines: list[str], text: str) -> list[str]:
        """A setting's answer: ``lines`` (empty when it was set), or the confirming
        ``text`` with ``echo_settings``."""
        return [text] if self.echo_settings and not lines else lines

    # ---- running -------------------------------------------------------------------

    def _run_command(self, arg: str, now: float) -> list[str]:
        """``run``, the panel's Run key: the loaded method from its first step, or
        Quick Start in the last direction."""
        if self._panel.method is None:
            return self._run(self._drive.direction, now)
        if self._method_step is None:
            self._start_step(0, now)
        return []

    def _load_command(self, arg: str, now: float) -> list[str]:
        if self._drive.running or self._method_step is not None:
            raise command_error("load", "Not allowed while running")
        return self._panel.load_command(arg)

    def _run(self, direction: str, now: float) -> list[str]:
        if refusal := self._panel.refusal(direction):
            raise command_error(f"{direction}run", refusal)
        ramp = self._ramps[direction]
        self._ramp_start_s = now
        rate = ramp.start_ml_min if ramp else self._rates[direction][0]
        self._drive.start(direction, rate, now)
        return []

    def _stop(self, arg: str, now: float) -> list[str]:
        self._halt(now)
        return []

    def _status(self, arg: str, now: float) -> list[str]:
        """Rate (fL/s), time (whole seconds, as the manual gives it), volume (fL) for
        the current direction, and six flags (five in the manual; a real PHD ULTRA 3.0.5
        is quoted with a sixth, target reached)."""
        drive = self._drive
        direction = drive.direction
        # The rate field is the motor's rate: 0 when it stands (the real '0 0 0 w..TI.').
        rate_fl_s = round(drive.rate_ml_min * 1e12 / 60) if drive.running else 0
        time_s = math.floor(drive.run_time_s(direction, now) + 1e-9)
        volume_fl = round(drive.counted_ml(direction, now) * 1e12)
        flags = (
            (direction.upper() if drive.running else direction)
            + "."  # limit switch: always '.' on a PHD ULTRA
            + ("S" if drive.stalled else ".")
            + "T"  # trigger input, idle high as in the real example
            + "I"  # direction port
            + ("T" if drive.target_reached else ".")
        )
        return [f"{rate_fl_s} {time_s} {volume_fl} {flags}"]
