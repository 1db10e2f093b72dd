"""User methods an emulated PHD ULTRA holds: named sequences of steps that the pump
runs by itself once started (``load NAME``, then ``run``), as a technician programs
them on the panel.

A model, not the pump's format: the manual's method-transfer commands are not
answered, so a method cannot be sent over the line; the emulator has these built in,
to be loaded at power-up or with ``load``. What matters to a client is that a pump in
a method moves by itself between commands, and that in a pause it stands still with
the idle prompt while it will move again.
"""

from __future__ import annotations

from dataclasses import dataclass

from .syringe_drive import INFUSE, WITHDRAW


@dataclass(frozen=True)
class MethodStep:
    """One step: ``direction`` ``'i'``/``'w'`` moves ``volume_ml`` at ``rate_ml_min``;
    None waits ``pause_s`` (clock seconds) with the motor standing."""

    direction: str | None
    rate_ml_min: float = 0.0
    volume_ml: float = 0.0
    pause_s: float = 0.0


METHODS: dict[str, tuple[MethodStep, ...]] = {
    # prime a line: push 0.5 mL, let it settle 10 s, push another 0.5 mL
    "prime": (
        MethodStep(INFUSE, rate_ml_min=6.0, volume_ml=0.5),
        MethodStep(None, pause_s=10.0),
        MethodStep(INFUSE, rate_ml_min=6.0, volume_ml=0.5),
    ),
    # a rinse cycle: draw 1 mL, wait 5 s, push it back
    "rinse": (
        MethodStep(WITHDRAW, rate_ml_min=12.0, volume_ml=1.0),
        MethodStep(None, pause_s=5.0),
        MethodStep(INFUSE, rate_ml_min=12.0, volume_ml=1.0),
    ),
}
