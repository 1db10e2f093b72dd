"""The run file written by a thread of its own, so a slow disk never delays a stop.

A USB stick, a network share or a virus scanner can hold an HDF5 write for seconds.
The acquisition threads judge each sample first (the interlocks) and then only queue
it; this thread writes the queue, in the order it was filled, to the ``RunWriter``.
Order is all the file needs: the queue is filled by one acquisition thread at a time,
in an order the clock decides, so the file's bytes do not depend on when the writes
land. A write that fails faults the run through ``on_error`` (the pump is stopped
there); nothing is written after it, and the file is still finalised with what it
holds.

The thread takes part in the rig's clock like the acquisition loops: on the simulated
rig it writes while time stands still, so the file is written up to the same instant
on any host, and a disk made to take rig time (the soak's slow disk) delays only it.
"""

from __future__ import annotations

import collections
import logging
from collections.abc import Callable

from labrig.errors import LabrigError
from labrig.recording.run_writer import RunWriter
from labrig.time.clock import Clock

log = logging.getLogger(__name__)

# How often (clock seconds) the writer writes what was queued: every two or three DAQ
# blocks, not once per append (each wake-up is a hand-over of the simulated rig's
# clock), and as often as the run file flushes (0.5 s): a live view sees no later data.
WRITE_PERIOD_S = 0.5


class BackgroundWriter:
    """Calls on a ``RunWriter``, made in order by one thread on the clock (``put``),
    then the file finalised (``close``)."""

    def __init__(self, writer: RunWriter, clock: Clock, on_error: Callable[[str], None]) -> None:
        self.writer = writer
        self.clock = clock
        self._on_error = on_error
        self._calls: collections.deque[tuple[Callable, tuple, dict]] = collections.deque()
        self._busy = False  # a call taken from the queue is being made
        self._closing = False
        self.error: str | None = None
        self._thread = clock.start_thread(self._serve, "run file")

    def put(self, call: Callable, *args, **kwargs) -> None:
        """Queue ``call(*args, **kwargs)`` (a method of the writer) behind every earlier
        one."""
        self._calls.append((call, args, kwargs))

    @property
    def idle(self) -> bool:
        """Every call queued so far is made."""
        return not self._calls and not self._busy

    def close(
        self,
        status: str,
        reason: str,
        timeout_s: float,
        hurry: Callable[[], bool],
        *,
        pump_stop_confirmed: bool,
    ) -> None:
        """Make what is queued (``timeout_s`` of clock time at most, or until ``hurry()``:
        a second stop request waits for no disk), then finalise the file, whatever
        became of the queue: the file must end with its status."""
        if not self.clock.wait_for(lambda: self.idle or self._thread.done or hurry(), timeout_s):
            log.error(
                "the run file's writes took over %g s; finalising without the rest", timeout_s
            )
        self._closing = True
        self.clock.wait_for(lambda: self._thread.done or hurry(), timeout_s)
        self.writer.finalise(status, reason, pump_stop_confirmed=pump_stop_confirmed)

    def _serve(self) -> None:
        calls = self._calls
        while True:
            closing = self.clock.wait_for(lambda: self._closing, WRITE_PERIOD_S)
            while calls:
                self._busy = True
                call, args, kwargs = calls.popleft()
                try:
                    if self.error is None:
                        call(*args, **kwargs)
                except LabrigError as exc:  # the file itself failed (full, gone): said so
                    self.error = f"run file: {exc}"
                    self._on_error(self.error)
                except Exception as exc:
                    self.error = f"run file: writing {self.writer.path} failed: {exc!r}"
                    self._on_error(self.error)
                finally:
                    self._busy = False
            if closing:
                return
