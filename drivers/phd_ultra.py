"""Harvard Apparatus PHD ULTRA syringe pump over serial: the rig's only actuator.

The driver implements ``labrig.rig.devices.Pump`` in mL, mL/min and mm. It does exactly
what it is told and checks that it happened: every setting is read back, every run
command must show the matching prompt, every reply is parsed as value + unit and
converted, and the pump's error texts become typed exceptions
(``phd_ultra_errors``). The framing rules themselves are pure functions in
``phd_ultra_protocol``; this module owns the port, the lock and the clocks.

Safety rules, because a pump that does not stop is the rig's worst failure:

- No call hangs: each reply has a deadline (``timeout_s``), the port is read in short
  slices, a lost port raises ``PumpDisconnected`` at once.
- ``stop()`` is safe from any thread at any time and never waits behind another
  exchange: a pending stop goes before any queued command, and when the port is busy
  (a reply in flight, perhaps one that will time out) the stop is written beside it at
  once; the exchange in flight gives up (``PumpInterrupted``) and the stop's reply is
  then read after the late replies are discarded.
- A reply that never came or could not be read leaves the pump's state unknown, so the
  driver sends a stop before raising and says in the message whether it worked.
- Bytes that arrive with no command pending (the unsolicited target-reached prompt,
  line noise, the late reply of a timed-out command) are discarded before each command;
  after a timeout the driver first waits one more deadline for the late reply, except
  before a stop: the stop is written first and the waiting comes after it.
- A stop is confirmed by what the pump reports, not by its prompt (one character, and
  a method waiting in a pause shows the idle one): ``status`` polls until two in a row
  show the motor standing with the same volume counter. Every stop's reply is awaited
  the full reply timeout, a healthy pump can take more than half a second after a
  target alarm; a pump that left a stop unanswered (``_deaf``) is not first waited
  for to send its late replies.
- A lost port is closed, and a stop looks for the pump again: a USB pump that drops
  off the bus (a brown-out, a cable pulled and plugged back) comes back as another
  /dev/ttyACM*, but under the same /dev/serial/by-id/... path, which is what a rig file
  should name. The stop reopens that path for up to ``reconnect_s`` and is sent there
  once what answers proves to be the same pump (``version``, syringe, counters); the
  pump ran its last command meanwhile. Anything else there is not sent ``stop``
  (``PumpNotTheSame``).
- Stalls send nothing by themselves: ``status()`` reports them and
  ``wait_until_stopped()`` polls for them.

What ``connect()`` assumes of a pump left by other software: it may be in
``poll on`` (prompts end with XON) or ``poll remote`` (no prompts), so ``poll off`` goes
first and its reply may never come; the address form the firmware wants is unknown, so
with ``address_form="auto"`` the forms are tried in turn and the answered one is kept;
it may be running, or in a method's pause, or in a Quick Start variant or a method
that refuses a direction, so its state is read (``status``, ``version``, ``mode``)
before anything it could refuse, and a connection that takes control stops it
(confirmed, and said in ``connect_notices``) and loads the Quick Start variant labrig
needs; NVRAM writes are switched off by the first accepted form, and none accepted only
warns (memory wear must not block a run); whether it withdraws is read from the
Direction line of ``metrics`` or, without one, from whether it answers ``wvolume`` (an
infuse-only model refuses withdraw commands), so ``can_withdraw`` says which it is and
nothing withdraw-related is asked of an infuse-only one.
"""

from __future__ import annotations

import contextlib
import logging
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

import serial

from labrig.rig.devices import PumpState, PumpStatus
from labrig.time.clock import Clock, RealClock

from .phd_ultra_errors import (
    PumpCommandError,
    PumpDisconnected,
    PumpError,
    PumpInterrupted,
    PumpLimitError,
    PumpModeError,
    PumpNotTheSame,
    PumpPortError,
    PumpProtocolError,
    PumpStalled,
    PumpTimeout,
    PumpUnknownCommand,
)
from .phd_ultra_protocol import (
    ADDRESS_FORMS,
    AUTO_ADDRESS_FORM,
    QUICK_START_VARIANTS,
    PumpIdentity,
    Reading,
    Reply,
    StatusLine,
    agrees,
    candidate_address_forms,
    check_refusal,
    force_limit_pressure_kpa,
    format_rate,
    format_volume,
    frame_command,
    parse_can_withdraw,
    parse_diameter_mm,
    parse_force_pct,
    parse_identity,
    parse_mode,
    parse_rate_limits,
    parse_rate_ml_min,
    parse_reply,
    parse_status_line,
    parse_target_ml,
    parse_volume_ml,
    prompts_in,
    read_diameter,
    read_rate,
    read_target,
    read_volume,
)

log = logging.getLogger(__name__)

DEFAULT_BAUD = 115200
# How long a reply may take. A PHD ULTRA answers in milliseconds, but one busy redrawing
# its screen (after a run command, a target alarm) has been seen to take longer than the
# 0.5 s once used here; a longer deadline costs nothing while the pump answers.
DEFAULT_TIMEOUT_S = 2.0
# How long one read of the port may block: short, so a reply's deadline is honoured
# within this much and a closing port is noticed quickly.
READ_SLICE_S = 0.02
# NVRAM writes off, in the order of the evidence: chembot on a real PHD ULTRA, then the
# Pico Plus / Legato drivers of the same command family, then the Pump 33 DDS manual's
# `rsave`.
NVRAM_OFF_COMMANDS = ("nvram off", "nvram none", "rsave off")
# How long a stop waits for the port before it writes beside the exchange in flight: an
# answered exchange takes milliseconds, one waiting out its timeout takes seconds; a stop
# must reach the pump within 0.3 s of being asked for.
STOP_WAIT_S = 0.1
# How many ``status`` polls a stop may take to show the motor standing with its volume
# counter unchanged in two polls in a row (a prompt alone is one character, and a
# paused method shows the idle one): two suffice on a pump that stopped.
CONFIRM_POLLS = 4
# How long a stop looks for a pump whose port was lost (host seconds), and how often it
# tries to reopen the port meanwhile: a USB pump re-enumerates within a few seconds.
RECONNECT_S = 10.0
REOPEN_PERIOD_S = 0.1
_RUNNING = (PumpState.INFUSING, PumpState.WITHDRAWING)
# The volume counters, and the one each motion moves.
_COUNTERS = ("ivolume", "wvolume")
_MOVING_COUNTER = {PumpState.INFUSING: "ivolume", PumpState.WITHDRAWING: "wvolume"}
# the counters' last printed digit (`1.2345 ml`): what a reading may be off by
COUNTER_DISPLAY_ML = 1e-4


@dataclass(frozen=True)
class Syringe:
    diameter_mm: float
    volume_ml: float


@dataclass(frozen=True)
class RateLimits:
    """What the pump accepts for the current syringe (``irate lim`` / ``wrate lim``)."""

    infuse_ml_min: tuple[float, float]
    withdraw_ml_min: tuple[float, float] | None  # None on an infuse-only pump


class PhdUltra:
    """A PHD ULTRA on a pyserial port (or any object with pyserial's read/write API).

    Use ``PhdUltra.open(port)`` for a real port or URL; the constructor takes an already
    open transport and sends nothing until ``connect()``.

    After ``connect()``: ``address_form`` is the form the pump answered, ``can_withdraw``
    whether it takes withdraw commands, ``nvram_off_command`` the command that switched
    off its memory writes (None if none was accepted), and ``connect_warnings`` what a
    person should know about the connection (for the rig check).
    """

    def __init__(
        self,
        transport,
        *,
        address: int = 0,
        address_form: str = AUTO_ADDRESS_FORM,
        clock: Clock | None = None,
        timeout_s: float = DEFAULT_TIMEOUT_S,
        port_name: str | None = None,
    ) -> None:
        if not 0 <= address <= 99:
            raise ValueError(f"pump address must be 0-99, got {address}")
        forms = (*ADDRESS_FORMS, AUTO_ADDRESS_FORM)
        if address_form not in forms:
            raise ValueError(f"address_form must be one of {forms}, got {address_form!r}")
        if not timeout_s > 0:
            raise ValueError(f"reply timeout must be > 0 s, got {timeout_s}")
        self.address = address
        self._forms = (
            candidate_address_forms(address)
            if address_form == AUTO_ADDRESS_FORM
            else (address_form,)
        )
        self.address_form = self._forms[0]
        self.clock = clock or RealClock()
        self.timeout_s = timeout_s
        self.port_name = port_name or str(getattr(transport, "port", "the serial port"))
        self.firmware = ""
        self.syringe: Syringe | None = None
        self.can_withdraw = True
        self.nvram_off_command: str | None = None
        self.connect_warnings: list[str] = []
        # what connect found the pump doing and changed (a run it stopped, the Quick
        # Start variant it loaded), one line each, for the operator and the run file
        self.connect_notices: list[str] = []
        self.identity: PumpIdentity | None = None
        self._transport = transport
        # opens the port again after it was lost (None: a transport given, not opened)
        self._reopen = None
        self.reconnect_s = RECONNECT_S
        self._not_found = False  # a lost port did not come back within reconnect_s
        self._limits: dict[str, tuple[float, float]] = {}
        self._lost: Exception | None = None
        self._resync_due = False
        self._io_lock = threading.Lock()
        # every write to the port: a stop written beside an exchange must not split it
        self._write_lock = threading.Lock()
        self._stops_written = 0  # stops written beside an exchange: it abandons its reply
        self._deaf = False  # a stop went unanswered: later stops are written, not awaited
        self.stop_wait_s = STOP_WAIT_S  # how long a stop waits for the port (above)
        # Set while no stop is waiting: ordinary commands wait on it, so a stop never
        # queues behind a stream of status polls.
        self._no_stop_pending = threading.Event()
        self._no_stop_pending.set()
        self._stops_waiting = 0
        self._stops_lock = threading.Lock()
        # what ``status()`` last read of each counter; a counter is stale (read again at
        # the next poll) after any command and while or after it moved
        self._status_lock = threading.Lock()
        self._counters_ml = dict.fromkeys(_COUNTERS, 0.0)
        self._stale_counters = set(_COUNTERS)
        self._last_state: PumpState | None = None
        # whether a counter's prompt shows the motor running (``>``, ``<``): a poll in
        # motion is then that counter alone
        self._prompt_shows_motion = True

    # ---- opening and closing -------------------------------------------------------

    @classmethod
    def open(
        cls,
        port: str,
        *,
        baudrate: int = DEFAULT_BAUD,
        address: int = 0,
        address_form: str = AUTO_ADDRESS_FORM,
        exclusive: bool = True,
        clock: Clock | None = None,
        timeout_s: float = DEFAULT_TIMEOUT_S,
        take_control: bool = True,
    ) -> PhdUltra:
        """Open ``port`` (a device path or a pyserial URL) at 8N1, no flow control, and
        connect (``take_control``: see ``connect``). ``exclusive`` locks the port so a
        second program gets a clear error."""

        def open_port():
            return serial.serial_for_url(
                port,
                baudrate=baudrate,
                bytesize=serial.EIGHTBITS,
                parity=serial.PARITY_NONE,
                stopbits=serial.STOPBITS_ONE,
                timeout=READ_SLICE_S,
                write_timeout=timeout_s,
                exclusive=exclusive,
            )

        try:
            transport = open_port()
        except (serial.SerialException, ValueError, OSError) as exc:
            if "exclusively lock" in str(exc):
                raise PumpPortError(
                    f"cannot open {port}: another program (another labrig?) is using it; "
                    "close that one first"
                ) from exc
            raise PumpPortError(f"cannot open {port}: {exc}") from exc
        pump = cls(
            transport,
            address=address,
            address_form=address_form,
            clock=clock,
            timeout_s=timeout_s,
            port_name=port,
        )
        pump._reopen = open_port
        try:
            pump.connect(take_control=take_control)
        except BaseException:
            transport.close()
            raise
        return pump

    def connect(self, *, take_control: bool = True) -> None:
        """Switch poll mode off and identify the pump (finding the address form), read
        what it is doing before sending anything it could refuse, switch off NVRAM
        writes, learn whether it withdraws, read the syringe settings.

        ``take_control`` (a run, a manual run): whatever the pump was doing is stopped
        and the stop confirmed (a run another program or a killed labrig left going, a
        method waiting in a pause, an alarm), and it is put in the Quick Start variant
        labrig drives (``load qs iw``, ``load qs i`` on an infuse-only pump), or refused
        in one line that says how to change it on the panel. Without it (``pump
        status``, ``version``) the pump is looked at and left as it is."""
        self.connect_warnings = []
        self.connect_notices = []
        self._find_address_form()
        line, prompt_state = self.read_status_line()
        self.identity = parse_identity(self.firmware, self.version_details())
        mode = self._read_mode()
        if take_control:
            self._stop_at_connect(line, _state(line, prompt_state), mode)
        self._switch_off_nvram()
        self.can_withdraw = self._probe_withdraw()
        if take_control:
            self._load_quick_start(mode)
        self.syringe = self.read_syringe()
        for notice in self.connect_notices:
            log.warning("%s", notice)
        log.info(
            "connected to %s at address %d (%s form) on %s%s",
            self.identity.describe(),
            self.address,
            self.address_form,
            self.port_name,
            "" if self.can_withdraw else ", infuse only",
        )

    def _read_mode(self) -> str | None:
        """The ``mode`` reply (``Quick Start Infuse/Withdraw``, or a method's name);
        None from firmware that does not know the command."""
        try:
            return self._query("mode").text
        except PumpCommandError as exc:
            log.info("the pump refused 'mode' (%s): its mode is not known", exc.pump_text)
            return None

    def _stop_at_connect(self, line: StatusLine, state: PumpState, mode: str | None) -> None:
        """A confirmed stop, whatever the state: a pump standing still may be in a
        method's pause, about to move again. What it was doing is told in one line."""
        self.stop()
        method = mode is not None and parse_mode(mode) is None
        if state in _RUNNING:
            direction = "infused" if state is PumpState.INFUSING else "withdrawn"
            doing = (
                f"the pump was {state.value} at {line.rate_ml_min:.4g} mL/min "
                f"({line.volume_ml:.4f} mL {direction} on its counter)"
            )
        elif method:
            doing = f"the pump was in a method ({mode!r}), standing (a pause or a wait)"
        elif state is not PumpState.IDLE:
            doing = f"the pump was {state.value} (its alarm on)"
        else:
            return
        self.connect_notices.append(
            f"{doing} when labrig connected to it on {self.port_name}: labrig stopped it "
            "(stop confirmed by its status)"
        )

    def _load_quick_start(self, mode: str | None) -> None:
        """The Quick Start variant labrig needs: both directions on a pump that
        withdraws, infuse on one that does not. A variant that has them already is
        kept; another variant or a method is replaced with ``load qs ...``, read back."""
        needed = "iw" if self.can_withdraw else "i"
        variant = None if mode is None else parse_mode(mode)
        if variant is not None and set(needed) <= set(variant):
            return
        command = f"load qs {needed}"
        try:
            self._command(command)
        except PumpCommandError as exc:
            if mode is None:  # no 'mode', no 'load qs': firmware without Quick Start commands
                warning = (
                    f"the pump answers neither 'mode' nor {command!r} ({exc.pump_text}): its "
                    "mode is not checked; set Quick Start on its panel if a run is refused"
                )
                log.warning(warning)
                self.connect_warnings.append(warning)
                return
            raise self._mode_error(mode, needed, f"refused {command!r}: {exc.pump_text}") from exc
        now = self._read_mode()
        if now is not None and parse_mode(now) != needed:
            raise self._mode_error(mode, needed, f"reports {now!r} after {command!r}")
        was = "its mode was not known" if mode is None else f"it was in {mode!r}"
        self.connect_notices.append(f"labrig loaded Quick Start on the pump ({command!r}): {was}")

    def _mode_error(self, mode: str | None, needed: str, what: str) -> PumpModeError:
        name = next(k for k, v in QUICK_START_VARIANTS.items() if v == needed).title()
        return PumpModeError(
            f"the pump on {self.port_name} is in {mode!r} and {what}: on its panel, stop "
            f"any method (unlock it if locked) and choose Quick Start, then {name}, and "
            "start again"
        )

    def _find_address_form(self) -> None:
        """For each candidate form: ``poll off`` (its reply may not come), then ``ver``,
        which must be answered. A pump ignores a command in a form it does not take,
        so a wrong form costs two timeouts and the late-reply wait."""
        tried = []
        for form in self._forms:
            self.address_form = form
            self._switch_off_poll()
            try:
                self.firmware = self._probe("ver", expect_payload=True).text
            except PumpTimeout as exc:
                tried.append(f"{frame_command('ver', address=self.address, address_form=form)!r}")
                last = exc
                continue
            if tried:
                log.info("the pump answers the %s address form (no answer to %s)", form, tried)
            return
        raise PumpTimeout(
            f"no answer from a pump at address {self.address} on {self.port_name} to "
            f"{' or '.join(tried)} within {self.timeout_s:g} s each: check the address, "
            "baud rate and cable"
        ) from last

    def _switch_off_poll(self) -> None:
        """``poll off``: prompts without XON, and event prompts. A pump in ``poll remote``
        sends no prompt, so no reply is a normal answer; a firmware that does not know
        the command is one that has no poll mode to leave."""
        try:
            self._probe("poll off", expect_payload=False)
        except PumpTimeout:
            log.info("no reply to 'poll off' (a pump in poll remote sends no prompt)")
        except PumpProtocolError as exc:
            log.info("an unexpected reply to 'poll off' (%s): going on", exc)
        except PumpCommandError as exc:
            log.info("the pump refused 'poll off' (%s): assuming it has no poll mode", exc)

    def _probe(self, command: str, *, expect_payload: bool) -> Reply:
        """One exchange whose failure is an answer, not a fault: no stop is sent."""
        return self._exchange(command, expect_payload=expect_payload, stop_on_fault=False)

    def _probe_withdraw(self) -> bool:
        """The Direction line of ``metrics`` (``Infuse/withdraw`` or ``Infuse only``), as
        flowchem reads it. A pump that does not say is asked for its withdrawn volume,
        the one withdraw command that moves nothing: refused, it cannot withdraw;
        answered, it is taken as withdrawing. Either way with a warning."""
        try:
            can_withdraw = parse_can_withdraw(self._query("metrics").lines)
            said = "no Direction line in its 'metrics'"
        except PumpCommandError as exc:
            can_withdraw, said = None, f"it refused 'metrics' ({exc.pump_text})"
        if can_withdraw is not None:
            return can_withdraw
        try:
            self._query("wvolume")
        except PumpCommandError as exc:
            warning = (
                f"the pump does not say whether it withdraws ({said}) and refused 'wvolume' "
                f"({exc.pump_text}): it cannot withdraw, and no withdraw command is sent to it"
            )
            can_withdraw = False
        else:
            warning = (
                f"the pump does not say whether it withdraws ({said}); it answers 'wvolume', "
                "so it is taken as withdrawing (an infuse-only pump refuses withdraw "
                "commands before anything moves)"
            )
            can_withdraw = True
        log.warning(warning)
        self.connect_warnings.append(warning)
        return can_withdraw

    def close(self) -> None:
        """Release the port. The pump keeps doing what it was doing."""
        with self._io_lock:
            self._transport.close()

    def __enter__(self) -> PhdUltra:
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()

    # ---- identity and syringe ------------------------------------------------------

    def identify(self) -> str:
        """The short firmware string, e.g. ``'PHD ULTRA 3.0.5'``."""
        return self._query("ver").text

    def version_details(self) -> tuple[str, ...]:
        """The long version: firmware, pump address, serial number (one per line)."""
        return self._query("version").lines

    @property
    def run_record(self) -> dict[str, str]:
        """What a run file keeps of the pump: who it is (as connect read it) and what
        connect found it doing, one line each (empty when nothing)."""
        identity = self.identity
        if identity is None:
            return {}
        return {
            "model": identity.model,
            "firmware": identity.firmware,
            "serial_number": identity.serial_number or "",
            "address": str(self.address),
            "version": "\n".join(identity.version_lines),
            "port": self.port_name,
            "at_connect": "\n".join(self.connect_notices + self.connect_warnings),
        }

    def _switch_off_nvram(self) -> None:
        """The first of ``NVRAM_OFF_COMMANDS`` the pump accepts. None accepted is a
        warning: every setting is then written to the pump's memory, which wears it,
        but a run must not be refused for it."""
        refusals = []
        for command in NVRAM_OFF_COMMANDS:
            try:
                self._setting(command)
                self.nvram_off_command = command
                return
            except PumpCommandError as exc:
                refusals.append(f"{command!r}: {exc.pump_text}")
        self.nvram_off_command = None
        warning = (
            "the pump accepted none of "
            + ", ".join(map(repr, NVRAM_OFF_COMMANDS))
            + " ("
            + "; ".join(refusals)
            + "): its memory is written at every setting change"
        )
        log.warning(warning)
        self.connect_warnings.append(warning)

    def read_syringe(self) -> Syringe:
        return self._syringe_from(*self._syringe_replies())

    def _syringe_replies(self) -> tuple[str, str]:
        return self._query("diameter").text, self._query("svolume").text

    @staticmethod
    def _syringe_from(diameter: str, volume: str) -> Syringe:
        return Syringe(diameter_mm=parse_diameter_mm(diameter), volume_ml=parse_volume_ml(volume))

    def configure_syringe(self, diameter_mm: float, volume_ml: float) -> None:
        """Set the syringe's inner diameter and nominal volume; the rate limits follow."""
        self._limits = {}
        diameter = f"{diameter_mm:.4f} mm"
        volume = format_volume(volume_ml, smallest="ul")
        self._command(f"diameter {diameter.removesuffix(' mm')}")
        self._command(f"svolume {volume}")
        diameter_reply, volume_reply = self._syringe_replies()
        self.syringe = self._syringe_from(diameter_reply, volume_reply)
        self._verify("diameter", read_diameter, diameter_reply, diameter)
        self._verify("syringe volume", read_volume, volume_reply, volume)

    def rate_limits(self) -> RateLimits:
        """The rate range the pump accepts for the current syringe (each direction asked
        once per syringe; the withdraw range is None on an infuse-only pump)."""
        return RateLimits(
            infuse_ml_min=self._rate_limits("irate"),
            withdraw_ml_min=self._rate_limits("wrate") if self.can_withdraw else None,
        )

    def _rate_limits(self, command: str) -> tuple[float, float]:
        if command not in self._limits:
            self._limits[command] = parse_rate_limits(self._query(f"{command} lim").text)
        return self._limits[command]

    # ---- force limit ---------------------------------------------------------------

    def set_force_limit(self, percent: int) -> None:
        """Set the force at which the pump stalls, in percent of its rated force, and
        read it back: the hardware backstop when software limits are not running."""
        if isinstance(percent, bool) or not isinstance(percent, int) or not 1 <= percent <= 100:
            raise PumpLimitError(f"force limit must be a whole 1-100 %, got {percent!r}")
        self._setting(f"force {percent}")
        got = self.force_limit_pct()
        if got != percent:
            raise PumpError(
                f"the pump reports a force limit of {got} % after being set to {percent} %"
            )

    def force_limit_pct(self) -> int:
        """The pump's force limit in percent of its rated force (``force``)."""
        return parse_force_pct(self._query("force").text)

    def force_limit_kpa(self, rated_force_n: float) -> float:
        """The force limit read from the pump as the load pressure it stalls at, on the
        syringe it is set up for (``rated_force_n``: its force at 100 %)."""
        return force_limit_pressure_kpa(
            self.force_limit_pct(), rated_force_n, self.read_syringe().diameter_mm
        )

    # ---- rates, target, volumes ----------------------------------------------------

    def set_infuse_rate(self, rate_ml_min: float) -> None:
        self._set_rate("irate", "infuse", rate_ml_min, self._rate_limits("irate"))

    def set_withdraw_rate(self, rate_ml_min: float) -> None:
        self._refuse_withdraw("set a withdraw rate")
        self._set_rate("wrate", "withdraw", rate_ml_min, self._rate_limits("wrate"))

    def _refuse_withdraw(self, doing: str) -> None:
        if not self.can_withdraw:
            raise PumpUnknownCommand(
                "wrate/wrun",
                f"cannot {doing}: the pump on {self.port_name} is infuse-only "
                "(as found at connect); nothing was sent",
            )

    def _set_rate(self, command: str, name: str, rate_ml_min: float, limits) -> None:
        low, high = limits
        if not (math.isfinite(rate_ml_min) and low <= rate_ml_min <= high):
            raise PumpLimitError(
                f"{name} rate {rate_ml_min:g} mL/min is outside this syringe's limits "
                f"{low:.6g} to {high:.6g} mL/min ({command} lim); nothing was sent"
            )
        rate = format_rate(rate_ml_min)
        self._command(f"{command} {rate}")
        self._verify(f"{name} rate", read_rate, self._query(command).text, rate)

    def _read_rate(self, command: str) -> float:
        return parse_rate_ml_min(self._query(command).text)

    def infuse_rate_ml_min(self) -> float:
        return self._read_rate("irate")

    def withdraw_rate_ml_min(self) -> float:
        return self._read_rate("wrate")

    def set_target_volume(self, volume_ml: float) -> None:
        if not (math.isfinite(volume_ml) and volume_ml > 0):
            raise PumpLimitError(f"target volume must be > 0 mL, got {volume_ml:g}")
        volume = format_volume(volume_ml)
        self._command(f"tvolume {volume}")
        self._verify("target volume", read_target, self._query("tvolume").text, volume)

    def target_volume_ml(self) -> float | None:
        """The target volume, or None when none is set."""
        return parse_target_ml(self._query("tvolume").text)

    def clear_volumes(self) -> None:
        """Zero the infused and withdrawn counters and clear the target."""
        with self._status_lock:
            self._command("cvolume")
            # what the pump counts from now: a pump found again must count at least it
            self._counters_ml = dict.fromkeys(_COUNTERS, 0.0)
        self._command("ctvolume")

    def volumes_ml(self) -> tuple[float, float]:
        """(infused, withdrawn) since the last clear; withdrawn is 0 on an infuse-only pump."""
        infused_ml = parse_volume_ml(self._query("ivolume").text)
        return infused_ml, parse_volume_ml(
            self._query("wvolume").text
        ) if self.can_withdraw else 0.0

    def _verify(
        self, what: str, read: Callable[[str], Reading | None], reply: str, sent: str
    ) -> None:
        """The readback ``reply`` must be the value ``sent``, to the digits each was
        printed with: the pump prints in its own unit and precision (``60 ml`` for
        ``60.0000 ml``). ``read`` reads both texts."""
        got = read(reply)
        if got is None or not agrees(got, read(sent)):
            raise PumpError(f"the pump reports {what} {reply!r} after being set to {sent!r}")

    # ---- running -------------------------------------------------------------------

    def infuse(self) -> None:
        """Start infusing at the set infuse rate (until the target, if one is set)."""
        self._run("irun", PumpState.INFUSING)

    def withdraw(self) -> None:
        """Start withdrawing at the set withdraw rate (until the target, if one is set)."""
        self._refuse_withdraw("withdraw")
        self._run("wrun", PumpState.WITHDRAWING)

    def _run(self, command: str, running: PumpState) -> None:
        state = self._command(command).state
        # A target already met is a run that ended at once, not a failure.
        if state not in (running, PumpState.TARGET_REACHED):
            raise PumpError(f"the pump did not start after {command!r}: it reports {state.value}")

    def stop(self) -> None:
        """Stop the motor (and silence a target or stall alarm). Safe from any thread.

        The stop reaches the pump within ``stop_wait_s`` whatever the port is doing; the
        call returns once the pump has confirmed it (or raises saying it did not)."""
        with self._stop_first():
            if not self._io_lock.acquire(timeout=self.stop_wait_s):
                with contextlib.suppress(PumpDisconnected):  # found again below
                    self._write_stop_beside()
                self._io_lock.acquire()
            try:
                if self._lost is not None:
                    self._reconnect_locked()
                state = self._stop_locked()
            finally:
                self._io_lock.release()
        if state in _RUNNING:
            raise PumpError(f"the pump still reports {state.value} after 'stop'")

    def _reconnect_locked(self) -> None:
        """Close the lost port and open its path again (io lock held), for up to
        ``reconnect_s``: the pump re-enumerates under the same by-id path. Host waits
        only: a stop never waits on the rig's clock."""
        lost = self._lost
        if self._reopen is None:
            raise PumpDisconnected(f"the port {self.port_name} was lost earlier ({lost})")
        with contextlib.suppress(serial.SerialException, OSError):
            self._transport.close()
        # a port that did not come back in time is tried once per later stop
        deadline = time.monotonic() + (0.0 if self._not_found else self.reconnect_s)
        while True:
            try:
                transport = self._reopen()
                break
            except (serial.SerialException, OSError, ValueError) as exc:
                if time.monotonic() >= deadline:
                    self._not_found = True
                    raise PumpDisconnected(
                        f"the port {self.port_name} was lost earlier ({lost}) and did not "
                        f"come back within {self.reconnect_s:g} s: the stop was not sent"
                    ) from exc
                time.sleep(REOPEN_PERIOD_S)
        log.warning("the pump's port %s came back after it was lost (%s)", self.port_name, lost)
        self._transport = transport
        self._lost = None
        self._resync_due = self._deaf = False  # a new port: nothing in flight on it
        try:
            self._check_same_pump_locked()
        except PumpNotTheSame as exc:
            with contextlib.suppress(serial.SerialException, OSError):
                transport.close()
            self._lost, self._not_found = exc, True  # later stops look again, once
            raise
        self._not_found = False
        # not under the status lock: a poll holding it waits for this stop
        self._stale_counters.update(_COUNTERS)

    def _check_same_pump_locked(self) -> None:
        """Before a stop goes to a pump found again (io lock held): it must prove to be
        the pump connected to. The same model and firmware, serial number and address
        (``version``), the same syringe settings, and volume counters no lower than the
        last ones read (a pump only counts up until cleared). Raises PumpNotTheSame,
        with what differs, for another pump or a device that does not answer as one."""
        differences = []
        try:
            replies = {
                command: self._transfer(command, expect_payload=True)
                for command in ("ver", "version", "diameter", "svolume", *self._counters())
            }
            for command, reply in replies.items():
                check_refusal(reply, command)
            identity = parse_identity(replies["ver"].text, replies["version"].lines)
            syringe = self._syringe_from(replies["diameter"].text, replies["svolume"].text)
            counted = {c: parse_volume_ml(replies[c].text) for c in self._counters()}
        except PumpError as exc:
            differences.append(f"it does not answer as a PHD ULTRA ({exc})")
        else:
            expected = self.identity
            if expected is not None and identity != expected:
                differences.append(f"{identity.describe()}, not {expected.describe()}")
            if self.syringe is not None and not (
                math.isclose(syringe.diameter_mm, self.syringe.diameter_mm, rel_tol=1e-4)
                and math.isclose(syringe.volume_ml, self.syringe.volume_ml, rel_tol=1e-4)
            ):
                differences.append(
                    f"syringe {syringe.diameter_mm:g} mm {syringe.volume_ml:g} mL, not "
                    f"{self.syringe.diameter_mm:g} mm {self.syringe.volume_ml:g} mL"
                )
            for counter, volume_ml in counted.items():
                if volume_ml < self._counters_ml[counter] - COUNTER_DISPLAY_ML:
                    differences.append(
                        f"'{counter}' {volume_ml:.4f} mL, below the "
                        f"{self._counters_ml[counter]:.4f} mL counted before"
                    )
        if differences:
            raise PumpNotTheSame(
                f"the port {self.port_name} came back, but what answers there is not the "
                f"pump of this run ({'; '.join(differences)}): it was not sent 'stop'",
                "this run's pump may still be running: press Stop on it",
            )

    def _counters(self) -> tuple[str, ...]:
        """The volume counters this pump has: no withdrawn one on an infuse-only pump."""
        return _COUNTERS if self.can_withdraw else _COUNTERS[:1]

    def _write_stop_beside(self) -> None:
        """Write a stop while another thread holds the port: that exchange abandons its
        reply (``_transfer`` sees the count change) and the port must be resynchronised."""
        with self._write_lock:
            self._stops_written += 1
            self._resync_due = True
        self._write(self._frame("stop"))

    def _stop_locked(self) -> PumpState:
        """The stop, io lock held; returns the state the pump confirms. With the line
        out of step (a reply timed out, a stop written beside an exchange) the stop is
        written first, then the late replies are let through and discarded, then a
        second stop is sent and its reply read: the pump is stopped before anything
        waits. Every stop's reply is awaited the full reply timeout: a healthy pump
        can take more than half a second after a target alarm."""
        if self._deaf:
            # no waiting for late replies first: from a deaf pump any that come are
            # replies to stops, as good as this one's
            self._resync_due = False
            try:
                reply = self._transfer("stop", expect_payload=False)
            except PumpTimeout:
                raise PumpTimeout(
                    f"the pump at address {self.address} on {self.port_name} has not "
                    f"answered since an earlier stop; this stop was sent but not "
                    f"confirmed within {self.timeout_s:g} s"
                ) from None
        else:
            if self._resync_due:
                self._write(self._frame("stop"))
                self._discard_for(self.timeout_s)
                self._resync_due = False
            try:
                reply = self._transfer("stop", expect_payload=False)
            except PumpTimeout:
                self._deaf = True
                raise
        check_refusal(reply, "stop")
        return self._confirm_stopped_locked()

    def _confirm_stopped_locked(self) -> PumpState:
        """What the pump reports after a stop (io lock held): ``status`` polls until two
        in a row show the motor standing and the same volume counter (a prompt is one
        character; a method in a pause shows the idle one). A pump still moving is sent
        one more stop; one still moving after it is returned as such for the caller to
        raise."""
        previous = None
        stops = 1
        for _ in range(CONFIRM_POLLS):
            reply = self._transfer("status", expect_payload=True)
            check_refusal(reply, "status")
            line = parse_status_line(reply.lines[-1])
            state = _state(line, reply.state)
            if state in _RUNNING:
                if stops > 1:
                    return state
                check_refusal(self._transfer("stop", expect_payload=False), "stop")
                stops, previous = stops + 1, None
                continue
            if previous == (line.direction, line.volume_ml):
                return state
            previous = (line.direction, line.volume_ml)
        raise PumpError(
            f"the pump on {self.port_name} stands after 'stop', but its volume counter "
            f"changed in each of {CONFIRM_POLLS} status polls: the stop is not confirmed"
        )

    @contextlib.contextmanager
    def _stop_first(self):
        with self._stops_lock:
            self._stops_waiting += 1
            self._no_stop_pending.clear()
        try:
            yield
        finally:
            with self._stops_lock:
                self._stops_waiting -= 1
                if self._stops_waiting == 0:
                    self._no_stop_pending.set()

    # ---- state ---------------------------------------------------------------------

    def read_status_line(self) -> tuple[StatusLine, PumpState]:
        """The raw ``status`` line and the state from its prompt."""
        reply = self._query("status")
        return parse_status_line(reply.lines[-1]), reply.state

    def status(self) -> PumpStatus:
        """State (prompt and status flags) and volumes, stamped on the clock at the
        middle of the query of the counter that is moving (a stamp across several
        queries would be late by part of the exchange time, which a fast simulated clock
        turns into hundredths of a mL); with none moving, the counters are constant and
        the stamp is the middle of the status query.

        A counter changes only while the motor runs its way, so a poll asks only for
        what may have changed, one command at a time: in a motion the last poll saw,
        the moving counter alone, whose prompt (``>`` or ``<``: the motor running that
        way) says the motion goes on; a prompt that says anything else (idle, target,
        stalled, the other way) is followed by the full poll. The full poll is the
        status line, then the moving counter and a resting one whose last reading may
        be out of date (``_stale_counters``). Each exchange is a round trip on the
        port, and the runner polls five times a second: a poll in a steady motion is
        one exchange, a poll at rest the status line alone."""
        with self._status_lock:
            motion = self._last_state
            asked = self._motion_counter()
            if asked is not None and (status := self._motion_poll(asked)) is not None:
                return status
            t0_s = self.clock.now()
            line, prompt_state = self.read_status_line()
            state = _state(line, prompt_state)
            t_s = 0.5 * (t0_s + self.clock.now())
            if asked is not None and state is motion:
                # the counter's prompt said otherwise, the status line says the motion
                # goes on: firmware whose prompt does not show motion gets full polls
                self._prompt_shows_motion = False
            if state is not self._last_state:
                # whatever happened between the polls (a run from the keypad that
                # ended) may have moved either counter
                self._stale_counters.update(_COUNTERS)
            self._last_state = state
            moving = _MOVING_COUNTER.get(state)
            for counter in self._counters():
                if counter != moving and counter not in self._stale_counters:
                    continue
                t0_s = self.clock.now()
                self._counters_ml[counter] = parse_volume_ml(self._query(counter).text)
                if counter == moving:
                    t_s = 0.5 * (t0_s + self.clock.now())
                    self._stale_counters.add(counter)  # read again once it has stopped
                else:
                    self._stale_counters.discard(counter)
            return self._status_at(t_s, state)

    def _motion_counter(self) -> str | None:
        """The counter whose reply alone can tell that the motion the last poll saw goes
        on: the moving one, when no other counter is out of date and this pump's
        prompt shows motion (status lock held)."""
        counter = _MOVING_COUNTER.get(self._last_state)
        if counter is None or not self._prompt_shows_motion:
            return None
        return counter if self._stale_counters <= {counter} else None

    def _motion_poll(self, counter: str) -> PumpStatus | None:
        """The status from ``counter``'s reply if its prompt shows the motor still
        running the same way, else None (the full poll reads the counter again)."""
        t0_s = self.clock.now()
        reply = self._query(counter)
        t_s = 0.5 * (t0_s + self.clock.now())
        if reply.state is not self._last_state:
            return None
        self._counters_ml[counter] = parse_volume_ml(reply.text)
        return self._status_at(t_s, self._last_state)

    def _status_at(self, t_s: float, state: PumpState) -> PumpStatus:
        return PumpStatus(
            t_s=t_s,
            state=state,
            infused_ml=self._counters_ml["ivolume"],
            withdrawn_ml=self._counters_ml["wvolume"],
        )

    def wait_until_stopped(
        self, *, poll_s: float = 1.0, timeout_s: float | None = None, on_status=None
    ) -> PumpStatus:
        """Poll ``status()`` every ``poll_s`` (clock time) until the motor stops; return
        the last status. Raises PumpStalled on a stall, PumpTimeout after ``timeout_s``.
        ``on_status`` sees every status (for progress output)."""
        start_s = self.clock.now()
        while True:
            status = self.status()
            if on_status is not None:
                on_status(status)
            if status.state is PumpState.STALLED:
                raise PumpStalled(
                    f"the pump stalled (load above its force limit) at {status.infused_ml:.4f} mL "
                    f"infused, {status.withdrawn_ml:.4f} mL withdrawn; 'stop' clears the alarm"
                )
            if status.state not in _RUNNING:
                return status
            if timeout_s is not None and self.clock.now() - start_s > timeout_s:
                raise PumpTimeout(f"the pump is still {status.state.value} after {timeout_s:g} s")
            self.clock.sleep(poll_s)

    # ---- the exchange --------------------------------------------------------------

    def _query(self, command: str) -> Reply:
        return self._exchange(command, expect_payload=True)

    def _command(self, command: str) -> Reply:
        return self._exchange(command, expect_payload=False)

    def _setting(self, command: str) -> Reply:
        """A setting whose effect is read back or does not matter for safety (memory
        writes, the force limit): firmware that echoes it with a line of text (seen:
        ``NVRAM off``) has still taken it, so the text is logged, not a fault."""
        reply = self._exchange(command, expect_payload=False, text_allowed=True)
        if reply.lines:
            log.info("the pump answered %r to %r", reply.text, command)
        return reply

    def _exchange(
        self,
        command: str,
        *,
        expect_payload: bool,
        stop_on_fault: bool = True,
        text_allowed: bool = False,
    ) -> Reply:
        self._no_stop_pending.wait()
        with self._io_lock:
            return self._exchange_locked(
                command,
                expect_payload=expect_payload,
                stop_on_fault=stop_on_fault,
                text_allowed=text_allowed,
            )

    def _exchange_locked(
        self,
        command: str,
        *,
        expect_payload: bool,
        stop_on_fault: bool,
        text_allowed: bool = False,
    ) -> Reply:
        try:
            reply = self._transfer(command, expect_payload)
            check_refusal(reply, command)  # a clean refusal: the pump's state is known
            if not expect_payload and reply.lines and not text_allowed:
                raise PumpProtocolError(f"unexpected reply to {command!r}: {reply.text!r}")
        except (PumpTimeout, PumpProtocolError) as exc:
            if not stop_on_fault:
                raise
            raise type(exc)(f"{exc}; {self._stop_after_fault()}") from exc
        return reply

    def _stop_after_fault(self) -> str:
        try:
            state = self._stop_locked()
        except PumpDisconnected:
            raise
        except PumpTimeout:
            return (
                "the stop sent afterwards was not confirmed (no reply in time): the pump may "
                "still be running"
            )
        except PumpError as exc:
            return f"the stop sent afterwards failed too ({exc}): the pump may still be running"
        if state in _RUNNING:
            return f"the pump still reports {state.value} after a stop"
        return "the pump was stopped"

    def _transfer(
        self, command: str, expect_payload: bool, timeout_s: float | None = None
    ) -> Reply:
        """Send one command and read its reply (io lock held) within ``timeout_s``
        (default the driver's)."""
        timeout_s = self.timeout_s if timeout_s is None else timeout_s
        if self._lost is not None:
            raise PumpDisconnected(f"the port {self.port_name} was lost earlier ({self._lost})")
        stops_seen = self._stops_written
        if self._resync_due:
            self._discard_for(self.timeout_s, stops_seen)
            self._resync_due = False
        self._discard_pending()
        if not expect_payload:
            # a command (a run, a stop, a clear; a setting too, to keep this simple) may
            # change the counters: status() reads them again
            self._stale_counters.update(_COUNTERS)
        self._write(self._frame(command))
        deadline = time.monotonic() + timeout_s
        raw = b""
        while True:
            chunk = self._read_some()
            if chunk:
                raw += chunk
                reply = parse_reply(raw, expect_payload=expect_payload, command=command)
                if reply is not None:
                    break
            if self._stops_written != stops_seen:
                raise self._interrupted(command)
            if time.monotonic() > deadline:
                self._resync_due = True
                got = f"got only {raw!r}" if raw else "check the address, baud rate and cable"
                raise PumpTimeout(
                    f"no complete reply from the pump at address {self.address} on "
                    f"{self.port_name} to {command!r} within {timeout_s:g} s ({got})"
                )
        self._deaf = False
        if reply.address is not None and reply.address != self.address:
            raise PumpProtocolError(
                f"the reply to {command!r} came from pump address {reply.address}, "
                f"not {self.address}: check the address"
            )
        return reply

    def _frame(self, command: str) -> bytes:
        return frame_command(command, address=self.address, address_form=self.address_form)

    def _interrupted(self, command: str) -> PumpInterrupted:
        self._resync_due = True
        return PumpInterrupted(
            f"the exchange of {command!r} with the pump on {self.port_name} was cut short by a stop"
        )

    def _write(self, data: bytes) -> None:
        try:
            with self._write_lock:
                self._transport.write(data)
        except serial.SerialTimeoutException as exc:
            raise PumpTimeout(
                f"could not send to {self.port_name} within {self.timeout_s:g} s"
            ) from exc
        except (serial.SerialException, OSError) as exc:
            raise self._disconnected(exc) from exc

    def _read_some(self) -> bytes:
        try:
            return self._transport.read(self._transport.in_waiting or 1)
        except (serial.SerialException, OSError) as exc:
            raise self._disconnected(exc) from exc

    def _disconnected(self, exc: Exception) -> PumpDisconnected:
        self._lost = exc
        return PumpDisconnected(
            f"lost the serial port {self.port_name} ({exc})", "the pump may still be running"
        )

    def _discard_pending(self) -> None:
        try:
            waiting = self._transport.in_waiting
            stray = self._transport.read(waiting) if waiting else b""
        except (serial.SerialException, OSError) as exc:
            raise self._disconnected(exc) from exc
        if stray:
            log.debug("discarded %r (prompts %s) before the next command", stray, prompts_in(stray))

    def _discard_for(self, seconds: float, stops_seen: int | None = None) -> None:
        """Read and drop everything for ``seconds``: the late reply of a timed-out command.
        ``stops_seen``: give up (``PumpInterrupted``) once a stop is written beside."""
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            if stray := self._read_some():
                log.debug("discarded late bytes %r", stray)
            if stops_seen is not None and self._stops_written != stops_seen:
                raise self._interrupted("the resynchronisation")


def _state(line: StatusLine, prompt_state: PumpState) -> PumpState:
    """One state from the prompt and the status flags: a stall wins, then motion, then
    the target flag (some firmware keeps a plain prompt after the target)."""
    if line.stalled or prompt_state is PumpState.STALLED:
        return PumpState.STALLED
    if prompt_state in _RUNNING:
        return prompt_state
    if line.running:
        return PumpState.INFUSING if line.direction == "i" else PumpState.WITHDRAWING
    if prompt_state is PumpState.TARGET_REACHED or line.target_reached:
        return PumpState.TARGET_REACHED
    return PumpState.IDLE
