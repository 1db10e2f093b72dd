"""The PHD ULTRA settings that do not move the plunger: the system commands (address,
baud, echo, dim, clock, remote, analog scale), the method commands (catalog, load, mode,
lock, unlock) and the method-free I/O (trigger input, outputs, sync port, valve).

Each handler takes the argument text and returns the payload lines (none for a
setting), or raises ``Refused`` with the pump's error text. The values are kept and
shown back; none of them changes the framing of the serial line (a pseudo-terminal has
no baud rate, and the USB echo is not modelled: docs/reference/pump.md).
"""

from __future__ import annotations

import datetime

from .pump_methods import METHODS
from .pump_refusals import argument_error, command_error, range_error, word_setting

BAUD_RATES = (9600, 19200, 38400, 57600, 115200)
# Quick Start variants `load qs ...` takes: infuse only, withdraw only, both (either
# order), as the Ultra's Quick Start menu offers them.
QUICK_START_MODES = {
    "i": "Infuse",
    "w": "Withdraw",
    "iw": "Infuse/Withdraw",
    "wi": "Withdraw/Infuse",
}
_CLOCK_FORMAT = "%m/%d/%y %H:%M:%S"
_ON_OFF = ("on", "off")


class PanelSettings:
    """What a technician sets on the keypad or from a terminal, besides the syringe and
    the run. ``quick_start`` is the loaded Quick Start variant (``iw`` at power-up
    unless given), ``method`` the loaded user method (``sim.pump_methods``; None in
    Quick Start); ``locked``: the method lock is on, and ``load`` is refused."""

    def __init__(
        self,
        address: int,
        *,
        quick_start: str = "iw",
        method: str | None = None,
        locked: bool = False,
    ) -> None:
        if quick_start not in QUICK_START_MODES:
            raise ValueError(f"quick_start must be one of {tuple(QUICK_START_MODES)}")
        if method is not None and method not in METHODS:
            raise ValueError(f"method must be one of {tuple(METHODS)} or None")
        self.address = address
        self.baud = 115200
        self.echo = "off"
        self.remote = "off"
        self.dim_pct = 100
        self.ascale_pct = 100
        self.clock_offset = datetime.timedelta()
        self.quick_start = quick_start
        self.method = method
        self.locked = locked
        self.outputs = {"1": "low", "2": "low"}
        self.sync = "low"
        self.valve = "off"
        self.handlers = {
            "address": self.address_command,
            "baud": self.baud_command,
            "echo": lambda arg: word_setting(self, "echo", arg, _ON_OFF),
            "remote": lambda arg: word_setting(self, "remote", arg, _ON_OFF),
            "dim": lambda arg: self._percent("dim_pct", arg, 0, "Brightness"),
            "ascale": lambda arg: self._percent("ascale_pct", arg, 1, "Analog scale"),
            "time": self.time_command,
            "cat": lambda arg: ["Quick Start", *METHODS],
            "load": self.load_command,
            "mode": self.mode_command,
            "lock": self.lock_command,
            "unlock": self.unlock_command,
            "input": lambda arg: ["High"],  # idle high, as the status line's trigger flag
            "output": self.output_command,
            "sync": lambda arg: word_setting(self, "sync", arg, ("high", "low")),
            "valve": lambda arg: word_setting(self, "valve", arg, ("on", "off", "auto")),
        }

    def address_command(self, arg: str) -> list[str]:
        if not arg:
            return [str(self.address)]
        if not arg.isdigit():
            raise argument_error(arg)
        if not 0 <= int(arg) <= 99:
            raise range_error(arg, "Address", "0", "99")
        self.address = int(arg)
        return []

    def baud_command(self, arg: str) -> list[str]:
        if not arg:
            return [str(self.baud)]
        if not arg.isdigit() or int(arg) not in BAUD_RATES:
            raise argument_error(arg)
        self.baud = int(arg)
        return []

    def _percent(self, attribute: str, arg: str, low: int, what: str) -> list[str]:
        if not arg:
            return [f"{getattr(self, attribute)}%"]
        if not arg.isdigit():
            raise argument_error(arg)
        if not low <= int(arg) <= 100:
            raise range_error(arg, what, f"{low}%", "100%")
        setattr(self, attribute, int(arg))
        return []

    def time_command(self, arg: str) -> list[str]:
        """The pump's clock: shown as ``mm/dd/yy hh:mm:ss``, set in the same form."""
        now = datetime.datetime.now()
        if not arg:
            return [(now + self.clock_offset).strftime(_CLOCK_FORMAT)]
        try:
            wanted = datetime.datetime.strptime(arg, _CLOCK_FORMAT)
        except ValueError:
            raise argument_error(arg) from None
        self.clock_offset = wanted - now
        return []

    def load_command(self, arg: str) -> list[str]:
        """``load qs {i|w|iw|wi}``: a Quick Start variant; ``load NAME``: one of the
        methods of ``sim.pump_methods``. Refused while the method lock is on."""
        words = arg.lower().split()
        if self.locked and words:
            raise command_error("load", "Method locked")
        if len(words) == 1 and words[0] in METHODS:
            self.method = words[0]
            return []
        if len(words) != 2 or words[0] != "qs" or words[1] not in QUICK_START_MODES:
            raise argument_error(arg or "load")
        self.quick_start, self.method = words[1], None
        return []

    def mode_command(self, arg: str) -> list[str]:
        if arg:
            raise argument_error(arg)
        if self.method is not None:
            return [f"Method {self.method}"]
        return [f"Quick Start {QUICK_START_MODES[self.quick_start]}"]

    def lock_command(self, arg: str) -> list[str]:
        if arg.lower() not in ("", "on"):
            raise argument_error(arg)
        self.locked = True
        return []

    def unlock_command(self, arg: str) -> list[str]:
        if arg:
            raise argument_error(arg)
        self.locked = False
        return []

    def output_command(self, arg: str) -> list[str]:
        words = arg.lower().split()
        if not words or words[0] not in self.outputs or len(words) > 2:
            raise argument_error(arg or "output")
        if len(words) == 1:
            return [self.outputs[words[0]].capitalize()]
        level = {"hi": "high", "high": "high", "lo": "low", "low": "low"}.get(words[1])
        if level is None:
            raise argument_error(words[1])
        self.outputs[words[0]] = level
        return []

    def refusal(self, direction: str) -> str | None:
        """Why a run in ``direction`` ('i' or 'w') started by ``irun``/``wrun`` is not
        allowed (a method loaded, a Quick Start variant without it); None if it is."""
        if self.method is not None:
            return f"Not allowed in method {self.method}"
        if direction not in self.quick_start:
            return f"Not allowed in Quick Start {self.quick_start}"
        return None
