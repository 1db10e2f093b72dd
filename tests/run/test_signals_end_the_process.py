"""Every signal ends every process: Ctrl-C, SIGTERM and SIGHUP at a prompt of a slow
simulated technician, and SIGTERM on a run paced far below real time, end the process
with the run aborted. Host timeouts here are deadlock guards, not measurements."""

import signal
import subprocess
import sys
import textwrap
import threading
import time

import h5py
import pytest

from labrig.time.virtual import VirtualClock

PROMPT = textwrap.dedent(
    """\
    name: prompt
    specimen: {segments: [B44-T30, B48-T26], fittings_length_mm: 10, fluid: water}
    rig: slow.yaml
    limits: {max_pressure_kpa: 95, max_volume_ml: 45}
    acquisition: {pressure_rate_hz: 100}
    steps:
      - zero_pressure: {duration_s: 0.2}
      - infuse: {rate_ml_min: 60, volume_ml: 1}
      - prompt: {message: close the valve, connect: reservoir}
      - hold: {seconds: 1}
    analysis: {average_last: 1, compare_model: false}
    """
)
# a technician who takes the longest a rig file allows (30 s), paced at half real time
SLOW_TECHNICIAN = (
    "pump: {port: emulator, syringe: {diameter_mm: 27.6, volume_ml: 50}}\n"
    "sim: {answer_s: 30, speed: 0.5}\n"
)


def test_stop_pacing_ends_a_wait_for_the_wall_clock():
    clock = VirtualClock(speed=0.001)  # a virtual second takes a thousand real ones
    done = threading.Event()

    def sleeper():
        clock.sleep(1000.0)
        done.set()

    with clock.participate():
        clock.start_thread(sleeper, "sleeper")
        threading.Timer(0.2, clock.stop_pacing).start()
        clock.sleep(2000.0)
    assert done.wait(60)
    assert clock.now() == 2000.0  # the same timeline, only faster


def signalled_when(process, ready, signum, settle_s=0.0) -> str:
    """Send ``signum`` once ``ready()`` (a 60 s guard) and ``settle_s`` more, then the
    process's stderr once it has ended (a 120 s guard: unfixed, it never ends)."""
    try:
        for _ in range(600):
            if ready():
                break
            time.sleep(0.1)
        assert ready(), "the run never got there"
        time.sleep(settle_s)
        process.send_signal(signum)
        return process.communicate(timeout=120)[1]
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()


def rows_in(path, dataset: str) -> int:
    """Rows a live run file holds in ``dataset`` (0 before it has any)."""
    try:
        with h5py.File(path, "r", libver="latest", swmr=True, locking=False) as run:
            return len(run[dataset])
    except (OSError, KeyError):
        return 0


@pytest.mark.slow  # a paced run in a process of its own: ~5 s each
@pytest.mark.parametrize(
    ("signum", "reason"),
    [
        (signal.SIGINT, "stopped by the operator (Ctrl-C)"),
        (signal.SIGTERM, "stopped by SIGTERM"),
        (signal.SIGHUP, "stopped: the terminal or SSH session was closed (SIGHUP)"),
    ],
)
def test_a_signal_at_a_slow_technicians_prompt_ends_the_process(tmp_path, signum, reason):
    (tmp_path / "slow.yaml").write_text(SLOW_TECHNICIAN)
    (tmp_path / "p.yaml").write_text(PROMPT)
    out = tmp_path / "r.h5"
    process = subprocess.Popen(
        [sys.executable, "-m", "labrig", "run", "p.yaml", "--out", "r.h5"],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    err = signalled_when(process, lambda: rows_in(out, "entry/events/time"), signum)
    assert process.returncode == 1
    assert "aborted: r.h5" in err and reason in " ".join(err.split())
    with h5py.File(out, "r") as run:
        assert run["entry/status"][()] == b"aborted"


@pytest.mark.slow  # a paced run in a process of its own: ~5 s
def test_sigterm_ends_a_run_paced_far_below_real_time(tmp_path):
    (tmp_path / "p.yaml").write_text(
        PROMPT.replace("rig: slow.yaml", "rig: sim").replace(
            "  - prompt: {message: close the valve, connect: reservoir}\n",
            "  - hold: {seconds: 100}\n",
        )
    )
    out = tmp_path / "r.h5"
    process = subprocess.Popen(
        [sys.executable, "-m", "labrig", "run", "p.yaml", "--sim", "--speed=0.01", "--out=r.h5"],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    # the layout is written, in SWMR mode: the stop handlers follow within milliseconds
    laid_out = "entry/repetitions/status"
    err = signalled_when(process, lambda: rows_in(out, laid_out), signal.SIGTERM, settle_s=1.0)
    assert process.returncode == 1
    assert "stopped by SIGTERM" in err
