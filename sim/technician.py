"""The simulated rig's technician: acts on the plant's plumbing at definite virtual times.

Answering a prompt takes ``answer_s`` of the rig's clock (time stands still for nobody
else: the acquisition goes on meanwhile), then the plant's inlet is switched as the
prompt says. A reservoir push moves the volume evenly over its duration.
"""

from __future__ import annotations

from labrig.time.clock import Clock


class SimTechnician:
    def __init__(self, clock: Clock, plant, answer_s: float = 2.0) -> None:
        self.clock = clock
        self.plant = plant
        self.answer_s = float(answer_s)
        self.withdrawn = False

    def prompt(self, message: str, connect: str | None) -> None:
        self.clock.sleep(self.answer_s)
        if connect is not None and not self.withdrawn:
            self.plant.connect(connect, self.clock.now())

    def withdraw(self, reason: str) -> None:
        """The run stopped: a prompt being answered is not acted on."""
        self.withdrawn = True

    def reservoir(self, volume_ml: float, duration_s: float) -> None:
        self.plant.push_reservoir(volume_ml, duration_s, self.clock.now())
        self.clock.sleep(duration_s)
