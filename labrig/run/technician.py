"""The technician's part of a run: prompts answered with Enter at the bench.

A protocol's ``prompt`` step asks for something only hands can do (close the pump's
valve and open the reservoir's), and its ``reservoir`` step asks for a quick push of the
small reservoir's plunger. The runner keeps acquiring while it waits, so the run file
holds everything that happens meanwhile. The simulated rig has its own technician
(``labrig.sim.technician``) who acts on the simulated plumbing instead.

A trip while a prompt is open withdraws it (``withdraw``): the screen must not go on
asking for Enter once the pump has been stopped. ``input`` cannot be cancelled, so the
question is asked from a thread of its own, and the answer is waited for on the clock.
"""

from __future__ import annotations

import threading
from collections.abc import Callable

from labrig.time.clock import Clock

# How often (clock seconds) a waiting prompt looks whether it was withdrawn.
WITHDRAW_POLL_S = 0.1


class ConsoleTechnician:
    """Prompts on the terminal; ``prompt`` returns once Enter is pressed, or at once
    after ``withdraw``."""

    def __init__(self, clock: Clock, ask: Callable[[str], str] = input, show=print) -> None:
        self.clock = clock
        self.ask = ask
        self.show = show
        self._withdrawn = threading.Event()

    def prompt(self, message: str, connect: str | None) -> None:
        """Show what to do, and wait for Enter."""
        to = f" (the specimen is then on the {connect})" if connect else ""
        self._answer(f"\n>>> {message}{to}. Press Enter when done: ")

    def reservoir(self, volume_ml: float, duration_s: float) -> None:
        """Ask for the push; the response is recorded while the technician pushes."""
        self._answer(
            f"\n>>> Press Enter, then push the reservoir's {volume_ml:g} mL in within about "
            f"{duration_s:g} s: "
        )

    def withdraw(self, reason: str) -> None:
        """The run stopped while a question was open: say so instead of it."""
        self._withdrawn.set()
        self.show(f"\n>>> The run stopped ({reason}): do not press Enter, the prompt is withdrawn.")

    def _answer(self, question: str) -> None:
        answered = threading.Event()
        failure: list[BaseException] = []

        def asking() -> None:
            try:
                self.ask(question)
            except BaseException as exc:  # EOF on a closed terminal: raised below
                failure.append(exc)
            answered.set()

        threading.Thread(target=asking, name="technician prompt", daemon=True).start()
        while not (answered.is_set() or self._withdrawn.is_set()):
            self.clock.wait_for(
                lambda: answered.is_set() or self._withdrawn.is_set(), WITHDRAW_POLL_S
            )
        if failure:
            raise failure[0]
