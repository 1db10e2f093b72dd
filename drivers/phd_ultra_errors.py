"""What can go wrong with the PHD ULTRA, one exception type per thing a caller handles
differently.

All derive from ``labrig.errors.DeviceError`` (CLI exit code 3), so the runner's device
fault interlock catches every one of them with a single ``except``. The pump's own
refusals keep the pump's text, because that text is what the manual and the vendor's
support talk about.
"""

from __future__ import annotations

from labrig.errors import DeviceError, InputError, LinkLost


class PumpError(DeviceError):
    """Base of every PHD ULTRA driver error."""


class PumpPortError(PumpError):
    """The serial port could not be opened (missing, no permission, or held by another
    program through its exclusive lock)."""


class PumpDisconnected(PumpError, LinkLost):
    """The serial port went away while in use (cable pulled, pump switched off). The
    pump may still be running: nothing more can be sent to it until the port is found
    again."""

    found_again = "the pump was found again and stopped"


class PumpNotTheSame(PumpDisconnected):
    """The port of a lost pump came back, but the pump (or device) answering there is
    not the one this driver connected to: another pump behind the same by-id link, two
    identical pumps swapped. It is not sent ``stop``; the lost pump may still run."""


class PumpModeError(PumpError):
    """The pump is in a mode labrig cannot run in (a user method, a Quick Start
    variant that refuses a direction) and would not be switched to the one it needs."""


class PumpTimeout(PumpError):
    """The pump did not finish its reply in time."""


class PumpInterrupted(PumpError):
    """An exchange given up because a stop was written to the pump beside it: its reply
    is lost among the stop's, and the pump has been told to stop."""


class PumpProtocolError(PumpError):
    """A reply that does not follow the pump's framing or cannot be read as a value:
    line noise, a garbled byte, a reply from another address."""


class PumpStalled(PumpError):
    """The pump stopped by itself because the load exceeded its force limit."""


class PumpLimitError(PumpError):
    """A value the driver refused before sending it (a rate outside the syringe's
    limits). Nothing was sent, so it is reported as bad input (exit code 2)."""

    exit_code = InputError.exit_code


class PumpCommandError(PumpError):
    """The pump answered a command with one of its error texts.

    ``pump_text`` is the pump's own text (every line of it), ``command`` what was sent.
    The subclasses name the kind of refusal; ``Command error`` itself means the command
    is not allowed now (wrong mode, motor running, or the pump is not in Quick Start).
    """

    def __init__(self, command: str, pump_text: str) -> None:
        super().__init__(f"the pump refused {command!r}: {pump_text}")
        self.command = command
        self.pump_text = pump_text


class PumpUnknownCommand(PumpCommandError):
    """The pump does not know the command (wrong pump model or firmware)."""


class PumpArgumentError(PumpCommandError):
    """The pump did not accept an argument of the command."""


class PumpRangeError(PumpArgumentError):
    """A numeric argument is outside what the pump accepts."""
