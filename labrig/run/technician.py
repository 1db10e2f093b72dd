"""The technician's part of a run: prompts answered with Enter at the bench.

A protocol's ``prompt`` step asks for something only hands can do (close the pump's
valve and open the reservoir's), and its ``reservoir`` step asks for a quick push of the
small reservoir's plunger. The runner keeps acquiring while it waits, so the run file
holds everything that happens meanwhile. The simulated rig has its own technician
(``labrig.sim.technician``) who acts on the simulated plumbing instead.

A trip while a prompt is open withdraws it (``withdraw``): the screen must not go on
asking for Enter once the pump has been stopped. So the answer is waited for on the
clock, looking at the terminal's input without blocking (``select``), and a withdrawn
prompt leaves nothing behind. ``input`` cannot be cancelled: where the input cannot be
looked at (Windows, or an ``ask`` function given), the question is asked from a thread
of its own instead (a thread still blocked in ``input`` when Python exits may abort it
while the input is a pipe; on a terminal it does not).
"""

from __future__ import annotations

import select
import sys
import threading
from collections.abc import Callable

from labrig.time.clock import Clock

# How often (clock seconds) a waiting prompt looks whether it was withdrawn.
WITHDRAW_POLL_S = 0.1


class ConsoleTechnician:
    """Prompts on the terminal; ``prompt`` returns once Enter is pressed, or at once
    after ``withdraw``."""

    def __init__(self, clock: Clock, ask: Callable[[str], str] | None = None, show=print) -> None:
        self.clock = clock
        self.ask = ask  # None: the terminal's input, looked at without blocking
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
        if self.ask is None and _selectable(sys.stdin):
            self._answer_from_input(question)
        else:
            self._answer_in_thread(question)

    def _answer_from_input(self, question: str) -> None:
        self.show(question, end="", flush=True)
        stdin = sys.stdin
        while not self._withdrawn.is_set():
            if (
                self.clock.wait_for(
                    lambda: self._withdrawn.is_set() or _readable(stdin), WITHDRAW_POLL_S
                )
                and not self._withdrawn.is_set()
            ):
                if not stdin.readline():
                    raise EOFError("the terminal's input was closed before Enter was pressed")
                return

    def _answer_in_thread(self, question: str) -> None:
        ask = self.ask or input
        answered = threading.Event()
        failure: list[BaseException] = []

        def asking() -> None:
            try:
                ask(question)
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


def _selectable(stream) -> bool:
    """Whether ``stream``'s readiness can be asked without blocking (POSIX files,
    pipes and terminals; not Windows consoles)."""
    if sys.platform == "win32":
        return False
    try:
        select.select([stream], [], [], 0)
    except (OSError, ValueError, TypeError, AttributeError):
        return False
    return True


def _readable(stream) -> bool:
    return bool(select.select([stream], [], [], 0)[0])
