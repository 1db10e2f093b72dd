"""The technician's part of a run: prompts answered with Enter at the bench.

A protocol's ``prompt`` step asks for something only hands can do (close the pump's
valve and open the reservoir's), and its ``reservoir`` step asks for a quick push of the
small reservoir's plunger. The runner keeps acquiring while it waits, so the run file
holds everything that happens meanwhile. The simulated rig has its own technician
(``labrig.sim.technician``) who acts on the simulated plumbing instead.
"""

from __future__ import annotations

from collections.abc import Callable


class ConsoleTechnician:
    """Prompts on the terminal; ``ask`` returns once Enter is pressed."""

    def __init__(self, ask: Callable[[str], str] = input) -> None:
        self.ask = ask

    def prompt(self, message: str, connect: str | None) -> None:
        """Show what to do, and wait for Enter."""
        to = f" (the specimen is then on the {connect})" if connect else ""
        self.ask(f"\n>>> {message}{to}. Press Enter when done: ")

    def reservoir(self, volume_ml: float, duration_s: float) -> None:
        """Ask for the push; the response is recorded while the technician pushes."""
        self.ask(
            f"\n>>> Press Enter, then push the reservoir's {volume_ml:g} mL in within about "
            f"{duration_s:g} s: "
        )
