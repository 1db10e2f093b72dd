"""The run's last word to the pump: a stop, and whether the pump confirmed it.

A run may end with the pump's reply line dead (a stop sent, never answered) or its
USB link gone and not found again. The plunger may then still be moving, and only a
person at the pump can be sure: such a run is faulted whatever stopped it, its reason
leads with ``PUMP_STOP_NOT_CONFIRMED`` (in the run file and on the screen), and
``RunResult.stop_confirmed`` is False.
"""

from __future__ import annotations

from labrig.errors import LabrigError
from labrig.rig.devices import Pump

PUMP_STOP_NOT_CONFIRMED = "PUMP STOP NOT CONFIRMED: press Stop on the pump"


def final_stop(pump: Pump) -> str | None:
    """Stop the pump; None once it confirmed the stop, else what went wrong."""
    try:
        pump.stop()
    except (LabrigError, OSError) as exc:
        return str(exc) or type(exc).__name__
    return None


def unconfirmed_reason(problem: str, reason: str) -> str:
    """The reason of a run whose pump did not confirm its stop: that first, then why
    the run stopped."""
    return f"{PUMP_STOP_NOT_CONFIRMED} ({problem}); {reason or 'the run ended'}"
