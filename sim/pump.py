"""A PHD ULTRA on a pseudo-terminal, so the real driver opens a real serial device.

``PumpEmulator`` serves a ``PumpFirmware`` (``sim.pump_firmware``: command set,
settings, plunger on the shared clock) on the master side of an ``os.openpty`` pair
and frames its answers as the pump does: ``LF payload CR`` lines
then ``LF prompt``, the prompt bare at address 0 and ``AA`` + prompt elsewhere, an
unsolicited prompt when the target is reached, nothing when it stalls.

Firmware variants are options, so the driver's tolerance is tested against each: the
reply style (plain lines, or each line prefixed with the prompt as on the Elite), the
target prompt (``T*``, ``T:`` or ``:T*``), and the status line after the prompt (older
pumps); the firmware's own options (poll mode, strict addressing, infuse-only, memory
command) pass through to ``PumpFirmware``. In ``poll on`` each prompt is followed by XON
and no event prompt is sent; in ``poll remote`` no prompt at all. A reply is framed in
the mode in force when its command arrived.
Faults are injected on demand: garbage, dropped or slow replies (to every command or
to some), a disconnect, a stall, a reply line that dies mid-reply (``go_silent``:
commands still arrive and act; ``go_silent_at_stop``: as the next stop arrives), and a
USB link that drops and re-enumerates (``re_enumerate``): the port disappears and comes
back as another pseudo-terminal. Like udev's ``/dev/serial/by-id/...`` links, ``by_id``
gives a stable symbolic link that points at the current one, and is gone while the port
is (a link left pointing at a released pseudo-terminal would lead a driver that reopens
it into whatever terminal the OS hands that number to next); the plunger keeps doing
what it did meanwhile.
``re_enumerate`` can bring another pump back behind the link (``another_pump()``: two
pumps swapped, or two identical ones udev cannot tell apart) while this one's plunger
goes on; ``keypad`` gives commands as at the pump's own keys (a run another program
left going, a method started).
One thread serves the port with ``select`` and a timeout, so it never blocks for long,
and nothing a client sends ends it: any byte is read (non-ASCII as ``?``), a line is
cut at ``MAX_LINE_BYTES``, and each kind of trouble is logged ``LOG_LIMIT`` times, then
counted (``troubles``).

The plunger's own events are timers on the shared clock (``Clock.call_at``), not host
ticks: the target stop at the exact time it is due, and a check of the load every
``LOAD_CHECK_S`` of clock time while the plunger moves (a stall). On the simulated
rig's virtual clock they therefore happen at the same rig time on any host. The serving
thread only answers: a command is executed at the clock time the driver sent it (the
driver holds virtual time still while it waits for the reply), and its motion timer is
set before the reply goes out, so nothing can move time past it unseen.
"""

from __future__ import annotations

import collections
import contextlib
import logging
import math
import os
import random
import re
import select
import threading
import time
import tty
from collections.abc import Callable

from labrig.rig.devices import PumpState
from labrig.time.clock import Clock

from .pump_firmware import DEFAULT_DIAMETER_MM, DEFAULT_SYRINGE_ML, MAX_FORCE_N, PumpFirmware

log = logging.getLogger(__name__)

LOAD_CHECK_S = 0.1  # clock seconds between load (stall) checks while the plunger moves
IDLE_WAIT_S = 0.1  # real seconds the server waits at most (commands wake it at once)
# The longest command line kept: the pump's own input buffer is small, and a client
# that sends bytes with no line end must not grow the emulator's memory. Longer lines
# are cut here (the rest dropped up to the line end) and answered as what was kept.
MAX_LINE_BYTES = 256
# Log records of one kind of trouble (a full output buffer, a line cut short, a
# command the emulator could not answer) before the rest are only counted: a flood of
# bad input must not flood the log.
LOG_LIMIT = 5
_GARBAGE = bytes(range(0x80, 0x100)) + b"#%&~^|"
_LINE_END = re.compile(rb"[\r\n]")
_PROMPTS = {
    PumpState.IDLE: ":",
    PumpState.INFUSING: ">",
    PumpState.WITHDRAWING: "<",
    PumpState.STALLED: "*",
}


class PumpEmulator:
    """A PHD ULTRA served on ``.port`` (a /dev/pts path) once started."""

    def __init__(
        self,
        clock: Clock,
        *,
        address: int = 0,
        reply_style: str = "plain",
        target_prompt: str = "T*",
        status_prompt_first: bool = False,
        diameter_mm: float = DEFAULT_DIAMETER_MM,
        syringe_ml: float = DEFAULT_SYRINGE_ML,
        load_pressure_kpa: Callable[[float], float] | None = None,
        stall_pressure_kpa: float | None = None,
        max_force_n: float = MAX_FORCE_N,
        reply_chunk_bytes: int | None = None,
        chunk_gap_s: float = 0.001,
        seed: int = 0,
        poll_mode: str = "off",
        strict_address_form: str | None = None,
        infuse_only: bool = False,
        memory_command: str | None = "nvram",
        echo_settings: bool = False,
        by_id: str | os.PathLike | None = None,
        **firmware_options,
    ) -> None:
        """The syringe, load and force options are the firmware's (``PumpFirmware``),
        as are ``firmware_options`` (its serial number, its ``metrics``, the mode it
        was left in).
        Replies are written ``reply_chunk_bytes`` at a time, ``chunk_gap_s`` apart, to
        exercise the driver on partial lines; ``seed`` makes injected garbage repeatable.
        ``by_id``: the path of a symbolic link kept pointing at the current port (the
        port the driver should open, as a rig file names /dev/serial/by-id/...)."""
        if reply_style not in ("plain", "prefixed"):
            raise ValueError(f"reply_style must be 'plain' or 'prefixed', got {reply_style!r}")
        if target_prompt not in ("T*", "T:", ":T*"):
            raise ValueError(f"target_prompt must be 'T*', 'T:' or ':T*', got {target_prompt!r}")
        self.clock = clock
        self.firmware = PumpFirmware(
            clock,
            address=address,
            diameter_mm=diameter_mm,
            syringe_ml=syringe_ml,
            load_pressure_kpa=load_pressure_kpa,
            stall_pressure_kpa=stall_pressure_kpa,
            max_force_n=max_force_n,
            on_target_reached=self._announce_target,
            poll_mode=poll_mode,
            strict_address_form=strict_address_form,
            infuse_only=infuse_only,
            memory_command=memory_command,
            echo_settings=echo_settings,
            **firmware_options,
        )
        # the pump that answers on the port: another one after ``re_enumerate`` may
        self.answering = self.firmware
        self.reply_style = reply_style
        self.target_prompt = target_prompt
        self.status_prompt_first = status_prompt_first
        self.received: collections.deque[str] = collections.deque(maxlen=10_000)
        self._chunk_bytes = reply_chunk_bytes
        self._chunk_gap_s = chunk_gap_s
        self._rng = random.Random(seed)
        # Guards what goes out (queue and faults). Taken after the firmware's lock when
        # both are needed (the target announcement), never before it.
        self._lock = threading.Lock()
        self._outgoing: collections.deque[tuple[float, bytes]] = collections.deque()
        self._drop = 0
        self._silent = False  # nothing more is sent (after the half reply ``_cut_next``)
        self._cut_next = False
        self._garble = 0
        self._delay_s = 0.0
        self._slow_commands: frozenset[str] | None = None  # None: every command is slow
        self._silent_at_stop = False
        self._by_id = None if by_id is None else os.fspath(by_id)
        self._closed = False
        self._replug: threading.Timer | None = None  # a re-enumeration's comeback
        self._port: str | None = None
        self._master = self._slave = -1
        self._wake_r = self._wake_w = -1
        self._thread: threading.Thread | None = None
        self._serving = False
        self._inbuf = bytearray()
        self._after_cr = False
        self._cutting = False  # dropping the rest of a line longer than MAX_LINE_BYTES
        self.troubles: collections.Counter[str] = collections.Counter()  # by kind
        self._motion_timer = None
        self._motion_due: float | None = None  # when the motion timer is set to fire
        self._timer_lock = threading.Lock()  # the motion timer's own: taken with no other

    # ---- lifecycle ---------------------------------------------------------------

    @property
    def port(self) -> str:
        """The device path the driver opens: the stable link with ``by_id``, else the
        pseudo-terminal's own path."""
        if self._port is None:
            raise RuntimeError("the emulator is not started")
        return self._by_id or self._port

    @property
    def tty_path(self) -> str | None:
        """The pseudo-terminal the pump is on, or was on last (None before a start)."""
        return self._port

    def start(self, pty: tuple[int, int] | None = None) -> PumpEmulator:
        """Serve on a new pseudo-terminal (or on ``pty``, a (master, slave) pair)."""
        self._master, self._slave = pty or os.openpty()
        # Raw at once: in the default cooked mode the line discipline would echo our own
        # replies back to us until the driver opens the port and sets raw mode.
        tty.setraw(self._slave)
        os.set_blocking(self._master, False)
        self._port = os.ttyname(self._slave)
        if self._by_id is not None:
            _point_link(self._by_id, self._port)
        self._inbuf.clear()
        self._wake_r, self._wake_w = os.pipe()
        os.set_blocking(self._wake_w, False)
        self._serving = True
        self._thread = threading.Thread(target=self._serve, name="pump-emulator", daemon=True)
        self._thread.start()
        return self

    def close(self) -> None:
        """Stop serving and release the pseudo-terminal (and the by-id link)."""
        with self._lock:
            self._closed = True
        if self._replug is not None:
            self._replug.cancel()
            self._replug.join()  # a plug-back under way finishes before the release
        self._shut_down()

    def __enter__(self) -> PumpEmulator:
        return self.start()

    def __exit__(self, *exc_info) -> None:
        self.close()

    def _shut_down(self) -> None:
        with self._lock:
            self._serving = False
        if self._by_id is not None:  # as udev removes it when the device goes
            with contextlib.suppress(FileNotFoundError):
                os.unlink(self._by_id)
        if self._thread is not None:
            self._wake()
            self._thread.join(timeout=5)
            self._thread = None

    def _wake(self) -> None:
        try:
            os.write(self._wake_w, b"x")
        except BlockingIOError:
            pass  # the loop has a wake-up pending already
        except OSError:
            log.debug("wake pipe already closed")

    # ---- what the plant and tests read (the firmware's) ------------------------------

    def net_volume_ml(self, t_s: float) -> float:
        """Infused minus withdrawn at clock time ``t_s``: the physical volume in the
        specimen, unaffected by clearing the pump's counters."""
        return self.firmware.net_volume_ml(t_s)

    @property
    def state(self) -> PumpState:
        return self.firmware.state

    @property
    def stall_pressure_kpa(self) -> float:
        return self.firmware.stall_pressure_kpa

    def stall(self) -> None:
        """Stall now if the plunger moves, else at the next run."""
        self.firmware.stall()
        self._schedule_motion()

    def keypad(self, *commands: str) -> None:
        """Commands given at the pump itself (or by another program before this one
        connects): executed, nothing sent on the line. ``keypad("irun")`` leaves it
        infusing, ``keypad("load prime", "run")`` in a method."""
        for command in commands:
            self.firmware.execute(command)
        self._schedule_motion()

    # ---- faults ------------------------------------------------------------------

    def inject_garbage(self, n_bytes: int = 12, *, into_next_reply: bool = True) -> None:
        """Corrupt the next reply with a line of ``n_bytes`` random bytes, or (with
        ``into_next_reply=False``) send them now, as line noise between replies."""
        with self._lock:
            if into_next_reply:
                self._garble += n_bytes
            else:
                self._queue(self._garbage(n_bytes))

    def drop_next_replies(self, n: int) -> None:
        """Execute the next ``n`` commands but send no reply to them."""
        with self._lock:
            self._drop = n

    def go_silent(self) -> None:
        """The pump's transmit line dies: the next reply stops half-way and nothing is
        sent after it, while commands still arrive and are executed (a stop still stops)."""
        with self._lock:
            self._silent = True
            self._cut_next = True

    def go_silent_at_stop(self) -> None:
        """The reply line dies as the next stop arrives: the stop acts (the plunger
        stops), its reply stops half-way, and nothing is sent after it."""
        with self._lock:
            self._silent_at_stop = True

    def slow_replies(self, delay_s: float, commands: tuple[str, ...] | None = None) -> None:
        """Delay the replies to ``commands`` (default every command) by ``delay_s`` real
        seconds (0 to stop)."""
        with self._lock:
            self._delay_s = delay_s
            self._slow_commands = None if commands is None else frozenset(commands)

    def disconnect(self) -> None:
        """Pull the cable: the port disappears. The plunger keeps doing what it did."""
        self._shut_down()

    def re_enumerate(self, after_s: float, another: PumpFirmware | None = None) -> None:
        """The USB link drops now and the pump comes back ``after_s`` real seconds later
        as another pseudo-terminal (the by-id link follows it), as after a brown-out or
        a cable pulled and plugged back. The plunger keeps doing what it did; whatever
        was in flight on the line is lost. With ``another`` (``another_pump()``), that
        pump answers behind the link instead (two pumps swapped, or two identical ones
        that udev cannot tell apart), while this one's plunger goes on."""
        # the new port is opened while the old one is still open, so it cannot take
        # the old one's number: a driver holding the dead port must find the new path
        pty = os.openpty()
        self._shut_down()
        with self._lock:
            self._outgoing.clear()
            if another is not None:
                self.answering = another
        self._replug = threading.Timer(after_s, self._plug_back, (pty,))
        self._replug.daemon = True
        self._replug.start()

    def _plug_back(self, pty: tuple[int, int]) -> None:
        with self._lock:
            closed = self._closed
        if closed:  # the emulator was closed while unplugged: it stays so
            for fd in pty:
                os.close(fd)
            return
        self.start(pty)

    def another_pump(self, serial_number: str = "EMU00002", **options) -> PumpFirmware:
        """A second pump of the same model on the same clock, at the same address and
        with the same syringe unless ``options`` say otherwise (``re_enumerate``)."""
        firmware = self.firmware
        settings = {
            "address": firmware.address,
            "diameter_mm": firmware._diameter_mm,
            "syringe_ml": firmware._syringe_ml,
            **options,
        }
        return PumpFirmware(self.clock, serial_number=serial_number, **settings)

    def _garbage(self, n_bytes: int) -> bytes:
        return bytes(self._rng.choice(_GARBAGE) for _ in range(n_bytes))

    # ---- serving -----------------------------------------------------------------

    def _serve(self) -> None:
        try:
            while True:
                wait = IDLE_WAIT_S
                with self._lock:
                    if not self._serving:
                        break
                    if self._outgoing:
                        wait = min(wait, max(0.0, self._outgoing[0][0] - time.monotonic()))
                readable, _, _ = select.select([self._master, self._wake_r], [], [], wait)
                if self._wake_r in readable:
                    os.read(self._wake_r, 4096)
                if self._master in readable:
                    self._receive(self._read_master())
                with self._lock:
                    self._send_due()
        finally:
            for fd in (self._master, self._slave, self._wake_r, self._wake_w):
                os.close(fd)
            # Never touch a closed descriptor's number again: the OS reuses it.
            self._master = self._slave = self._wake_r = self._wake_w = -1

    def _read_master(self) -> bytes:
        try:
            return os.read(self._master, 4096)
        except (BlockingIOError, InterruptedError):
            return b""

    def _receive(self, data: bytes) -> None:
        """Split the input into command lines at CR, LF or CR LF (found by ``re`` in C:
        a status poll is three commands, and a byte-by-byte scan in Python cost more
        than executing them). Any byte is taken: one that is not printable ASCII is
        read as ``?`` (the pump answers it as an unknown command or argument), a line
        is cut at ``MAX_LINE_BYTES``."""
        self._inbuf += data
        while (found := _LINE_END.search(self._inbuf)) is not None:
            end = found.start()
            line, separator = bytes(self._inbuf[:end]), self._inbuf[end]
            del self._inbuf[: end + 1]
            if self._cutting:
                self._cutting = False  # the end of a line already answered
                continue
            if separator == ord("\n") and self._after_cr and not line:
                self._after_cr = False  # the LF of a CR LF pair
                continue
            self._after_cr = separator == ord("\r")
            self._answer(line)
        if len(self._inbuf) > MAX_LINE_BYTES:
            if not self._cutting:
                self._trouble("line", "a command line longer than %d bytes cut", MAX_LINE_BYTES)
                self._answer(bytes(self._inbuf[:MAX_LINE_BYTES]))
            self._cutting = True
            self._inbuf.clear()

    def _answer(self, line: bytes) -> None:
        """Execute one line, whatever it holds: nothing a client sends may end the
        serving thread (the port would be gone while the process serves on)."""
        text = line.decode("ascii", errors="replace")
        if not (text.isascii() and text.isprintable()):  # a client's command seldom
            text = "".join(c if c.isprintable() and c.isascii() else "?" for c in text)
        try:
            self._execute(text)
        except Exception:  # a bug answering one line: logged (boundedly), the port lives
            self._trouble("error", "could not answer %r", text, exc_info=True)

    def _trouble(self, kind: str, message: str, *args, exc_info: bool = False) -> None:
        """Log one kind of trouble at most ``LOG_LIMIT`` times, then count it only."""
        self.troubles[kind] += 1
        count = self.troubles[kind]
        if count <= LOG_LIMIT:
            log.warning(message, *args, exc_info=exc_info)
        if count == LOG_LIMIT:
            log.warning("further troubles of this kind (%s) are counted, not logged", kind)

    @property
    def serving(self) -> bool:
        """The port is served (False once closed, unplugged, or its thread ended)."""
        thread = self._thread
        return thread is not None and thread.is_alive()

    def _execute(self, line: str) -> None:
        self.received.append(line)
        firmware = self.answering
        poll_mode = firmware.poll_mode
        answer = firmware.execute(line)
        if answer is None:
            return  # for another pump on the chain
        self._schedule_motion()  # before the reply: the driver moves time on after it
        data = self._frame(answer, poll_mode)
        if not data:
            return  # poll remote: a command without payload gets nothing back
        with self._lock:
            if self._silent_at_stop and answer.command in ("stop", "stp"):
                self._silent_at_stop = False
                self._silent = self._cut_next = True
            if self._silent:
                if not self._cut_next:
                    return
                self._cut_next = False
                data = data[: len(data) // 2]
            if self._drop:
                self._drop -= 1
                return
            if self._garble:
                data = b"\n" + self._garbage(self._garble) + b"\r" + data
                self._garble = 0
            slow = self._slow_commands is None or answer.command in self._slow_commands
            self._queue(data, self._delay_s if slow else 0.0)

    def _frame(self, answer, poll_mode: str) -> bytes:
        prompt = self._prompt(answer.state, self.answering.address)
        prefix = prompt if self.reply_style == "prefixed" else ""
        body = "".join(f"\n{prefix}{text}\r" for text in answer.lines)
        if poll_mode == "remote":
            return body.encode("ascii")
        prompt_first = answer.command == "status" and self.status_prompt_first
        data = f"\n{prompt}{body}\n" if prompt_first else f"{body}\n{prompt}"
        return (data + ("\x11" if poll_mode == "on" else "")).encode("ascii")

    def _schedule_motion(self) -> None:
        """Set the timer of the plunger's next event: its target stop, or the next load
        check, whichever comes first (none while it stands still)."""
        with self._timer_lock:
            now = self.clock.now()
            due = self.firmware.next_event_s  # a target, a method's pause ending
            if self.firmware.running:
                due = min(due, now + LOAD_CHECK_S)
            if math.isinf(due):
                due = None
            if due is not None and due == self._motion_due and due > now:
                return  # set for that instant already (each command of a poll asks again)
            if self._motion_timer is not None:
                self._motion_timer.cancel()
                self._motion_timer = None
            self._motion_due = due
            if due is not None:
                self._motion_timer = self.clock.call_at(due, self._motion_event)

    def _motion_event(self) -> None:
        self.firmware.tick(self.clock.now())
        self._schedule_motion()

    def _prompt(self, state: PumpState, address: int) -> str:
        prompt = self.target_prompt if state is PumpState.TARGET_REACHED else _PROMPTS[state]
        if address or self.reply_style == "prefixed":
            prompt = f"{address:02d}{prompt}"
        return prompt

    def _announce_target(self) -> None:
        """The real pump sends its target prompt unsolicited (with poll mode off)."""
        if self.firmware.poll_mode != "off" or self.answering is not self.firmware:
            return
        prompt = self._prompt(PumpState.TARGET_REACHED, self.firmware.address)
        with self._lock:
            if self._silent:
                return
            self._queue(f"\n{prompt}".encode("ascii"))

    def _queue(self, data: bytes, delay_s: float = 0.0) -> None:
        """Schedule bytes for sending, in order (a serial line never reorders)."""
        due = time.monotonic() + delay_s
        if self._outgoing:
            due = max(due, self._outgoing[-1][0])
        size = self._chunk_bytes or len(data)
        for k, i in enumerate(range(0, len(data), size)):
            self._outgoing.append((due + k * self._chunk_gap_s, data[i : i + size]))
        if threading.current_thread() is not self._thread:
            self._wake()  # the serving thread itself sends what is due before it waits

    def _send_due(self) -> None:
        now = time.monotonic()
        while self._outgoing and self._outgoing[0][0] <= now:
            _, data = self._outgoing.popleft()
            try:
                os.write(self._master, data)
            except BlockingIOError:
                self._trouble("full", "pty buffer full: nobody reads the pump, dropped %r", data)


def _point_link(link: str, target: str) -> None:
    """Point the symbolic link ``link`` at ``target`` in one step (as udev replaces a
    by-id link): a reader never sees it missing or half-made."""
    temporary = f"{link}.{os.getpid()}.new"
    with contextlib.suppress(FileNotFoundError):
        os.unlink(temporary)
    os.symlink(target, temporary)
    os.replace(temporary, link)
