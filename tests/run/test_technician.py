"""The technician's prompts on the terminal: answered with Enter, withdrawn by a trip
without leaving a thread blocked on the input, and an input closed is an error."""

import contextlib
import os
import sys
import threading
from types import SimpleNamespace

import pytest

from labrig.run import technician as technician_module
from labrig.run.technician import ConsoleTechnician
from labrig.time.clock import RealClock

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="select on the input")


@pytest.fixture
def terminal(monkeypatch):
    """The process's input replaced by a pipe the test writes into."""
    read_fd, write_fd = os.pipe()
    stdin = os.fdopen(read_fd, "r")
    monkeypatch.setattr(sys, "stdin", stdin)
    yield write_fd
    stdin.close()
    with contextlib.suppress(OSError):  # the test closed it
        os.close(write_fd)


def shown_by(lines):
    return lambda *text, **kwargs: lines.append("".join(text))


def test_enter_answers_the_prompt(terminal):
    shown = []
    technician = ConsoleTechnician(RealClock(), show=shown_by(shown))
    os.write(terminal, b"\n")
    technician.prompt("close the valve", "reservoir")
    assert shown == [
        "\n>>> close the valve (the specimen is then on the reservoir). Press Enter when done: "
    ]


def test_a_withdrawn_prompt_returns_and_leaves_no_thread(terminal, monkeypatch):
    # The threads the technician starts, not every thread of the process: a thread
    # another test left behind may start one of its own meanwhile on a busy host.
    started: list[threading.Thread] = []

    class RecordedThread(threading.Thread):
        def start(self) -> None:
            started.append(self)
            super().start()

    monkeypatch.setattr(
        technician_module,
        "threading",
        SimpleNamespace(Thread=RecordedThread, Event=threading.Event),
    )
    shown = []
    technician = ConsoleTechnician(RealClock(), show=shown_by(shown))
    trip = threading.Timer(0.05, technician.withdraw, ("stopped by the operator (Ctrl-C)",))
    trip.start()
    technician.prompt("close the valve", None)  # nobody presses Enter
    assert [t.name for t in started if t.is_alive()] == []
    trip.join()
    assert shown[-1] == (
        "\n>>> The run stopped (stopped by the operator (Ctrl-C)): do not press Enter, "
        "the prompt is withdrawn."
    )


def test_a_closed_input_is_an_error_not_an_answer(terminal):
    technician = ConsoleTechnician(RealClock(), show=shown_by([]))
    os.close(terminal)
    with pytest.raises(EOFError, match="closed before Enter was pressed"):
        technician.reservoir(2.0, 5.0)
