"""The simulated rig's technician: acts on the plant's plumbing at definite virtual times.

Answering a prompt takes ``answer_s`` of the rig's clock (time stands still for nobody
else: the acquisition goes on meanwhile), then the plant's inlet is switched as the
prompt says. A reservoir push moves the volume evenly over its duration. A run that
stops meanwhile (``withdraw``) ends the wait at once: a slow technician, paced to the
wall clock, would otherwise hold the process for as long as the answer takes.
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
        self._take(self.answer_s)
        if connect is not None and not self.withdrawn:
            self.plant.connect(connect, self.clock.now())

    def withdraw(self, reason: str) -> None:
        """The run stopped: a prompt being answered is not acted on."""
        self.withdrawn = True

    def reservoir(self, volume_ml: float, duration_s: float) -> None:
        self.plant.push_reservoir(volume_ml, duration_s, self.clock.now())
        self._take(duration_s)

    def _take(self, seconds: float) -> None:
        """``seconds`` of the rig's clock, or until the run stops."""
        if seconds > 0:
            self.clock.wait_for(lambda: self.withdrawn, seconds)
        else:  # as a sleep of 0: the others due now go first
            self.clock.sleep(seconds)
