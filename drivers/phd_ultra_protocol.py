"""The PHD ULTRA's serial language as pure functions: how a command is framed, when a
reply is complete, what its prompt means, and how each reply reads as a value in mL,
mL/min or mm.

Nothing here touches a port, so every rule is checked with message tables; the port,
the lock and the timeouts live in ``phd_ultra.py``. The framing is read tolerantly,
because it varies between firmware versions (docs/reference/pump.md lists what is
assumed):

- a reply is ``LF payload CR`` lines, then ``LF prompt`` (no CR after the prompt);
- the prompt is ``[:<>*]`` or a target prompt ``T*``, ``T:`` or ``:T*``, with an
  optional 1–2 digit address in front (bare at address 0 on a PHD ULTRA, ``01:``
  elsewhere);
- a pump in ``poll on`` ends each prompt with XON (0x11): every XON is dropped;
- some firmware repeats the prompt with its address at the start of each payload line
  (``00:15.3 ml/min``), and a stray ``T*`` can leak into a line: both are dropped;
- older firmware sends the ``status`` line after the prompt instead of before it;
- anything before the first LF (an echo, a CR left from an earlier reply) is ignored.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

from labrig.rig.devices import PumpState

from .phd_ultra_errors import (
    PumpArgumentError,
    PumpCommandError,
    PumpProtocolError,
    PumpRangeError,
    PumpUnknownCommand,
)

# chembot drives a real PHD ULTRA with CR alone; a CR LF pair risks being read as two
# lines (a command and an empty one) by firmware that ends a line at either byte.
TERMINATOR = b"\r"

# A pump in `poll on` sends XON each time it is ready for the next command.
XON = b"\x11"

ADDRESS_FORMS = ("digits", "colon", "none")
# "auto": try the forms of ``candidate_address_forms`` in turn and keep the one answered.
AUTO_ADDRESS_FORM = "auto"

_PROMPT = re.compile(r"^(?P<address>\d{1,2})?(?P<prompt>:?T[:*]|[:<>*])$")
# A target prompt leaked into the start of a payload line (flowchem's observation).
_LEAKED_TARGET = re.compile(r"^\d{0,2}:?T[:*]")
_FORCE = re.compile(r"^\s*(?P<pct>\d{1,3})\s*%\s*$")
_PROMPT_STATES = {
    ":": PumpState.IDLE,
    ">": PumpState.INFUSING,
    "<": PumpState.WITHDRAWING,
    "*": PumpState.STALLED,
}

# Unit factors: volumes to mL, time units to minutes. Replies are printable ASCII
# (anything else is a protocol error), so the units are the ASCII forms a pump prints:
# `ul`, never `µl`; a rate's time base as `min`, `hr` or `sec`, or their one-letter forms.
_VOLUME_ML = {"ml": 1.0, "ul": 1e-3, "nl": 1e-6, "pl": 1e-9}
_TIME_MIN = {"min": 1.0, "m": 1.0, "hr": 60.0, "h": 60.0, "sec": 1 / 60, "s": 1 / 60}
_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_QUANTITY = re.compile(rf"^\s*(?P<value>{_NUMBER})\s*(?P<unit>[^\s\d]\S*)\s*$")
# The capability line of `metrics` (flowchem reads it from a Pump 11 Elite):
# `Direction          Infuse/withdraw`, or `Infuse only` on an infuse-only model.
_DIRECTION_LINE = re.compile(r"^\s*direction\b\s*(?P<value>.*)$", re.IGNORECASE)

# The pump's refusals, most specific first: "Out of range" comes as the detail line of
# an "Argument error", "Unknown command" as the detail of a "Command error".
_REFUSALS: tuple[tuple[str, type[PumpCommandError]], ...] = (
    ("out of range", PumpRangeError),
    ("range error", PumpRangeError),
    ("unknown command", PumpUnknownCommand),
    ("argument error", PumpArgumentError),
    ("command error", PumpCommandError),
)

FL_PER_ML = 1e12

# Rate limits scale with the plunger area (the lead screw's speed range is fixed). The
# reference pair is the `irate lim` reply chembot quotes from a real PHD ULTRA with its
# 9.525 mm syringe.
REFERENCE_DIAMETER_MM = 9.525
REFERENCE_RATE_LIMITS_ML_MIN = (14.7792e-6, 15.3477)


def rate_limits_ml_min(diameter_mm: float) -> tuple[float, float]:
    """(min, max) rate a PHD ULTRA drives a syringe of this inner diameter at, in mL/min.

    The emulator answers ``irate lim`` with it, and protocols are checked against it
    before a run; on the bench the driver checks again against the pump's own answer.
    """
    scale = (diameter_mm / REFERENCE_DIAMETER_MM) ** 2
    low, high = REFERENCE_RATE_LIMITS_ML_MIN
    return low * scale, high * scale


def candidate_address_forms(address: int) -> tuple[str, ...]:
    """The address forms to try, most likely first. The manual sends an address only
    when it is not 0, as ``N:cmd`` (a real PHD ULTRA 3.0.5 is driven with none); the
    ``00cmd`` of Pico Plus code comes second. At a non-zero address no form without
    the address is tried: that would command pump 0 of the chain."""
    if address == 0:
        return ("none", "digits")
    return ("colon", "digits")


def frame_command(command: str, *, address: int, address_form: str = "digits") -> bytes:
    """The bytes that send ``command`` to the pump at ``address``.

    ``digits`` is ``00irate`` (BioCAT, flowchem), ``colon`` is ``0:irate`` (the manual's
    ``12:irat``), ``none`` sends no address (chembot, a single pump). Which forms a given
    firmware accepts is unverified, so the choice is the caller's.
    """
    if not 0 <= address <= 99:
        raise ValueError(f"pump address must be 0-99, got {address}")
    prefix = {"digits": f"{address:02d}", "colon": f"{address}:", "none": ""}[address_form]
    return (prefix + command).encode("ascii") + TERMINATOR


@dataclass(frozen=True)
class Reply:
    """One complete reply: its payload lines (prefixes dropped) and its final prompt."""

    lines: tuple[str, ...]
    prompt: str
    address: int | None

    @property
    def state(self) -> PumpState:
        if "T" in self.prompt:
            return PumpState.TARGET_REACHED
        return _PROMPT_STATES[self.prompt]

    @property
    def text(self) -> str:
        """The payload as one line, for values and messages."""
        return " / ".join(self.lines)


def prompts_in(raw: bytes) -> list[str]:
    """Every prompt in bytes that arrived with no command pending (unsolicited events,
    such as the target-reached prompt), in order."""
    text = raw.replace(XON, b"").decode("ascii", errors="replace")
    return [m["prompt"] for part in text.split("\n") if (m := _PROMPT.match(part))]


def parse_reply(raw: bytes, *, expect_payload: bool, command: str = "") -> Reply | None:
    """The reply in ``raw`` if it is complete, else None (wait for more bytes).

    Complete means: a prompt as the last thing received, or (older firmware) a prompt
    followed by the payload line; and at least one payload line if ``expect_payload``.
    A prompt that arrived earlier than the last one (an unsolicited target prompt just
    before the reply) is superseded by the last. XON bytes (``poll on``) are dropped
    wherever they are. Raises PumpProtocolError when the complete reply holds bytes
    that are not printable ASCII.
    """
    text = raw.replace(XON, b"").decode("ascii", errors="replace")
    elements = text.split("\n")[1:]  # what precedes the first LF is not part of a reply
    if not elements:
        return None
    payload: list[str] = []
    prompts: list[re.Match[str]] = []
    for element in elements[:-1]:
        if match := _PROMPT.match(element):
            prompts.append(match)  # followed by more: status-after-prompt, or unsolicited
        elif element.strip("\r"):
            payload.append(element.rstrip("\r"))
    last = elements[-1]
    if match := _PROMPT.match(last):
        prompts.append(match)
    elif not (last == "" and prompts and payload and elements[-2].endswith("\r")):
        return None
    if not prompts or (expect_payload and not payload):
        return None
    prompt = prompts[-1]  # the latest state; an earlier one was an event before the reply
    # Longest first, so '00T*' is not cut as if it were '00T'.
    prefixes = sorted({match[0] for match in prompts}, key=len, reverse=True)
    lines = tuple(_clean_line(line, prefixes) for line in payload)
    joined = "".join(lines)
    if not (joined.isascii() and joined.isprintable()):
        raise PumpProtocolError(f"unreadable reply to {command!r}: {raw!r}")
    address = prompt["address"]
    return Reply(lines, prompt["prompt"], int(address) if address else None)


def _clean_line(line: str, prefixes: list[str]) -> str:
    """Drop what some firmware puts before a payload line: a prompt of the same reply
    with its address (``00:15.3 ml/min``; the prompt may have changed by the end of
    the reply, so any prompt received with it counts), or a leaked target prompt."""
    for prefix in prefixes:
        if line.startswith(prefix):
            line = line[len(prefix) :]
            break
    return _LEAKED_TARGET.sub("", line, count=1).strip()


def check_refusal(reply: Reply, command: str) -> None:
    """Raise the typed exception for a reply that carries one of the pump's error texts."""
    lowered = reply.text.lower()
    for needle, error in _REFUSALS:
        if needle in lowered:
            raise error(command, reply.text)


@dataclass(frozen=True)
class Reading:
    """A value read from the pump, in mL, mL/min or mm, and half a step of its last
    printed digit in the same unit: how far the true value may be from it
    (``'60 ml'``: 0.5 mL; ``'15.3477 ml/min'``: 0.00005 mL/min)."""

    value: float
    half_step: float


def _quantity(text: str, what: str) -> tuple[float, str, float]:
    """(value, unit, half a step of the last printed digit) of ``'1.5 ml'``."""
    match = _QUANTITY.match(text)
    if match is None:
        raise PumpProtocolError(f"expected a {what} with its unit, got {text!r}")
    mantissa, _, exponent = match["value"].lower().partition("e")
    decimals = len(mantissa.partition(".")[2]) - int(exponent or 0)
    return float(match["value"]), match["unit"].lower(), 0.5 * 10.0**-decimals


def read_volume(text: str) -> Reading:
    """``'1.234 ml'``, ``'0 ul'`` -> mL, with the printed resolution."""
    value, unit, half_step = _quantity(text, "volume")
    if unit not in _VOLUME_ML:
        raise PumpProtocolError(f"unknown volume unit in {text!r}")
    return Reading(value * _VOLUME_ML[unit], half_step * _VOLUME_ML[unit])


def read_rate(text: str) -> Reading:
    """``'15.3477 ml/min'``, ``'14.7792 nl/min'``, ``'2 ul/hr'`` -> mL/min, with the
    printed resolution."""
    value, unit, half_step = _quantity(text, "rate")
    volume_unit, _, time_unit = unit.partition("/")
    if volume_unit not in _VOLUME_ML or time_unit not in _TIME_MIN:
        raise PumpProtocolError(f"unknown rate unit in {text!r}")
    factor = _VOLUME_ML[volume_unit] / _TIME_MIN[time_unit]
    return Reading(value * factor, half_step * factor)


def read_diameter(text: str) -> Reading:
    """``'9.5250 mm'`` -> mm, with the printed resolution."""
    value, unit, half_step = _quantity(text, "diameter")
    if unit != "mm":
        raise PumpProtocolError(f"expected a diameter in mm, got {text!r}")
    return Reading(value, half_step)


def parse_volume_ml(text: str) -> float:
    """``'1.234 ml'``, ``'0 ul'`` -> mL."""
    return read_volume(text).value


def parse_rate_ml_min(text: str) -> float:
    """``'15.3477 ml/min'``, ``'14.7792 nl/min'``, ``'2 ul/hr'`` -> mL/min."""
    return read_rate(text).value


def parse_diameter_mm(text: str) -> float:
    """``'9.5250 mm'`` -> mm."""
    return read_diameter(text).value


def agrees(reading: Reading, sent: Reading) -> bool:
    """Whether a readback is the value that was sent, to the precision both were
    printed with (the pump may print fewer digits, or another unit, than were sent)."""
    tolerance = reading.half_step + sent.half_step + 1e-9 * abs(sent.value)
    return abs(reading.value - sent.value) <= tolerance


def parse_can_withdraw(lines: tuple[str, ...]) -> bool | None:
    """The ``metrics`` reply's Direction line: True for ``Infuse/withdraw``, False for
    an infuse-only model, None when the reply has no Direction line."""
    for line in lines:
        if match := _DIRECTION_LINE.match(line):
            return "withdraw" in match["value"].lower()
    return None


def parse_rate_limits(text: str) -> tuple[float, float]:
    """``'14.7792 nl/min to 15.3477 ml/min'`` -> (min, max) in mL/min."""
    low, sep, high = text.partition(" to ")
    if not sep:
        raise PumpProtocolError(f"expected rate limits 'A unit to B unit', got {text!r}")
    limits = parse_rate_ml_min(low), parse_rate_ml_min(high)
    if not 0 < limits[0] <= limits[1]:
        raise PumpProtocolError(f"rate limits out of order: {text!r}")
    return limits


def parse_force_pct(text: str) -> int:
    """``'100%'`` -> 100 (the ``force`` query: percent of the pump's rated force)."""
    match = _FORCE.match(text)
    if match is None or not 1 <= int(match["pct"]) <= 100:
        raise PumpProtocolError(f"expected a force limit '1%' to '100%', got {text!r}")
    return int(match["pct"])


def force_limit_pressure_kpa(force_pct: float, rated_force_n: float, diameter_mm: float) -> float:
    """The load pressure at which the pump stalls: ``force_pct`` of its rated linear
    force over the plunger area. An upper bound: the plunger's friction and the
    tubing's resistance take their share of the force before the specimen does."""
    area_m2 = math.pi / 4 * (diameter_mm * 1e-3) ** 2
    return force_pct / 100 * rated_force_n / area_m2 / 1e3


def parse_target_ml(text: str) -> float | None:
    """``'5 ml'`` -> 5.0; ``'Target volume not set'`` -> None."""
    reading = read_target(text)
    return None if reading is None else reading.value


def read_target(text: str) -> Reading | None:
    """The ``tvolume`` reply with its printed resolution; None when no target is set."""
    if "not set" in text.lower():
        return None
    return read_volume(text)


@dataclass(frozen=True)
class StatusLine:
    """The ``status`` reply: rate, time and volume for the current direction, and flags.

    The time field is in seconds: the PHD ULTRA manual, "The second integer is the
    infuse time in seconds". (chembot parses it as milliseconds, but quotes no reply
    that shows it.) Nothing in labrig relies on it.
    """

    rate_ml_min: float
    time_s: int
    volume_ml: float
    direction: str  # "i" or "w"
    running: bool
    stalled: bool
    target_reached: bool


_STATUS = re.compile(r"^(\d+)\s+(\d+)\s+(\d+)\s+([iIwW][.A-Za-z]{4,5})$")


def parse_status_line(text: str) -> StatusLine:
    """``'16666666667 15 25000000000 I..TI.'`` -> StatusLine (fL/s, s, fL, flags).

    Flags (as chembot reads them from real pumps): direction (upper case while running),
    limit switch, stall ``S``, trigger, direction port, and on newer firmware a sixth
    flag ``T`` for target reached.
    """
    match = _STATUS.match(text.strip())
    if match is None:
        raise PumpProtocolError(f"expected 'rate time volume flags' from status, got {text!r}")
    rate_fl_s, time_s, volume_fl, flags = match.groups()
    return StatusLine(
        rate_ml_min=int(rate_fl_s) * 60 / FL_PER_ML,
        time_s=int(time_s),
        volume_ml=int(volume_fl) / FL_PER_ML,
        direction=flags[0].lower(),
        running=flags[0].isupper(),
        stalled=flags[2] == "S",
        target_reached=len(flags) == 6 and flags[5] == "T",
    )


def _scaled(value: float, units: tuple[tuple[str, float], ...]) -> tuple[float, str]:
    """``value`` in the largest unit that keeps it >= 1 (the smallest unit otherwise)."""
    for unit, factor in units:
        if value >= factor:
            return value / factor, unit
    unit, factor = units[-1]
    return value / factor, unit


def format_rate(rate_ml_min: float) -> str:
    """A rate argument: 4 decimals (as chembot sends to a real PHD ULTRA) in a unit that
    keeps at least 5 significant digits: ``'10.0000 ml/min'``, ``'250.0000 ul/min'``."""
    value, unit = _scaled(rate_ml_min, (("ml/min", 1.0), ("ul/min", 1e-3), ("nl/min", 1e-6)))
    return f"{value:.4f} {unit}"


def format_volume(volume_ml: float, *, smallest: str = "nl") -> str:
    """A volume argument, ``'5.0000 ml'``; ``svolume`` takes only ml or ul, so callers
    can stop the scale at ``smallest='ul'``."""
    units = (("ml", 1.0), ("ul", 1e-3), ("nl", 1e-6))
    cut = [name for name, _ in units].index(smallest) + 1
    value, unit = _scaled(volume_ml, units[:cut])
    return f"{value:.4f} {unit}"


@dataclass(frozen=True)
class PumpIdentity:
    """Who the pump is: the ``ver`` reply (model and firmware, ``PHD ULTRA 3.0.5``)
    and the ``version`` reply's lines (``Firmware: v3.0.5``, ``Pump address: 0``,
    ``Serial number: D401460``), with the serial number and address read from them
    (None where a line is missing)."""

    ver: str
    version_lines: tuple[str, ...]
    serial_number: str | None
    address: int | None

    @property
    def model(self) -> str:
        """``PHD ULTRA`` of ``PHD ULTRA 3.0.5`` (the whole reply if it has no version)."""
        model, _, version = self.ver.rpartition(" ")
        return model if model and any(c.isdigit() for c in version) else self.ver

    @property
    def firmware(self) -> str:
        """The firmware version: the ``version`` reply's ``Firmware:`` line, else the
        last word of ``ver``."""
        said = _field(self.version_lines, "firmware")
        return (said or self.ver.rpartition(" ")[2]).removeprefix("v")

    def describe(self) -> str:
        serial = self.serial_number or "no serial number"
        address = "?" if self.address is None else self.address
        return f"{self.model} {self.firmware}, serial {serial}, address {address}"


def _field(lines: tuple[str, ...], name: str) -> str | None:
    """The value of the ``Name: value`` line whose name starts with ``name``."""
    for line in lines:
        key, sep, value = line.partition(":")
        if sep and key.strip().lower().startswith(name):
            return value.strip()
    return None


def parse_identity(ver: str, version_lines: tuple[str, ...]) -> PumpIdentity:
    address = _field(version_lines, "pump address")
    return PumpIdentity(
        ver=ver,
        version_lines=tuple(version_lines),
        serial_number=_field(version_lines, "serial") or None,
        address=int(address) if address and address.isdigit() else None,
    )


# The Quick Start variants as `mode` names them, and as `load qs ...` takes them.
QUICK_START_VARIANTS = {
    "infuse": "i",
    "withdraw": "w",
    "infuse/withdraw": "iw",
    "withdraw/infuse": "wi",
}


def parse_mode(text: str) -> str | None:
    """The Quick Start variant of a ``mode`` reply (``Quick Start Infuse/Withdraw`` ->
    ``'iw'``), or None for anything else (a user method: ``Method prime``)."""
    words = text.strip().lower()
    if not words.startswith("quick start"):
        return None
    return QUICK_START_VARIANTS.get(words.removeprefix("quick start").strip())
