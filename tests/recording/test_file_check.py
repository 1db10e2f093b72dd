"""A damaged run file is answered in one line by every reader, never a hang or a crash:
the file is walked by a watched child process before the reader's own process opens it.

The files are real run files (written by ``RunWriter``) damaged as a bad copy or a dying
disk damages them: zeroed ranges, flipped bytes, a cut end. No assert here times
anything: a reader stuck in libhdf5 would hang the test, and ``faulthandler`` ends it
(with the stack) long before any timeout of the suite.
"""

import faulthandler
import os
import shutil
import signal
import sys
import threading

import h5py
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import labrig
from labrig.cli import main
from labrig.errors import InputError
from labrig.recording import file_check
from labrig.recording.run_reader import open_run
from tests.support.simulated_runs import tiny_run

# far longer than a sound read, or the child's watchdog, take on a slow machine
HANG_S = 120


@pytest.fixture(scope="module")
def sound_run(tmp_path_factory):
    return tiny_run(tmp_path_factory.mktemp("sound") / "run.h5")


def damaged(sound, tmp_path, name, damage):
    path = tmp_path / name
    shutil.copyfile(sound, path)
    data = bytearray(path.read_bytes())
    path.write_bytes(damage(data))
    return path


def zeroed(start, length):
    def damage(data):
        data[start : start + length] = bytes(len(data[start : start + length]))
        return bytes(data)

    return damage


def show(path, capsys, command="show"):
    faulthandler.dump_traceback_later(HANG_S, exit=True, file=sys.__stderr__)
    try:
        with pytest.raises(SystemExit) as exited:
            main([command, str(path)])
    finally:
        faulthandler.cancel_dump_traceback_later()
    out, err = capsys.readouterr()
    return exited.value.code, out, err


@pytest.mark.parametrize("command", ["show", "compare", "recover"])
def test_two_kb_zeroed_at_byte_4000_is_one_line(sound_run, tmp_path, capsys, command):
    path = damaged(sound_run, tmp_path, "zeroed.h5", zeroed(4000, 2048))
    before = path.read_bytes()
    code, out, err = show(path, capsys, command)
    assert (code, out) == (2, "")
    (line,) = err.splitlines()
    assert line.startswith(f"error: {path}: damaged: ")
    assert path.read_bytes() == before
    with pytest.raises(InputError, match="damaged"):
        labrig.open_run(path)


def test_a_reader_stuck_in_libhdf5_is_cut_short(tmp_path, monkeypatch):
    """The child is given up on after STALL_S without a sign of life: a child that
    never answers stands for libhdf5 in an endless loop."""
    monkeypatch.setattr(file_check, "STARTUP_S", 0.5)
    monkeypatch.setattr(file_check, "_child_command", lambda paths: ["sleep", "600"])
    path = tmp_path / "a.h5"
    path.write_bytes(b"x")
    (verdict,) = file_check.check_files([path]).values()
    assert verdict == (
        f"{path}: damaged: libhdf5 was still reading one part of it after 0.5 s (a sound "
        "run file takes it milliseconds); not read"
    )


def test_ctrl_c_while_a_file_is_walked_ends_the_walk(tmp_path, monkeypatch):
    """Ctrl-C reaches a reader waiting for the child, and the child goes with it."""
    started = []
    real_popen = file_check.subprocess.Popen

    def popen(*args, **kwargs):
        child = real_popen(*args, **kwargs)
        started.append(child)
        return child

    monkeypatch.setattr(file_check.subprocess, "Popen", popen)
    monkeypatch.setattr(file_check, "_child_command", lambda paths: ["sleep", "600"])
    path = tmp_path / "a.h5"
    path.write_bytes(b"x")
    # Python's own Ctrl-C handler, which a shell running the tests in the background
    # replaces by "ignore" for the whole process
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        threading.Timer(0.5, os.kill, (os.getpid(), signal.SIGINT)).start()
        with pytest.raises(KeyboardInterrupt):
            file_check.check_files([path])
    finally:
        signal.signal(signal.SIGINT, previous)
    (child,) = started
    assert child.returncode is not None  # killed and waited for


def test_a_reader_that_crashes_is_one_line(tmp_path, monkeypatch):
    monkeypatch.setattr(file_check, "_child_command", lambda paths: ["sh", "-c", 'kill -SEGV "$$"'])
    path = tmp_path / "a.h5"
    path.write_bytes(b"x")
    assert file_check.check_files([path])[path] == (
        f"{path}: damaged: reading it crashed libhdf5 (signal 11); not read"
    )


def test_a_huge_stored_protocol_is_refused_unread(sound_run, tmp_path, capsys):
    path = tmp_path / "big.h5"
    shutil.copyfile(sound_run, path)
    with h5py.File(path, "r+") as f:
        del f["entry/protocol"]
        f["entry"]["protocol"] = "#" * 3_000_000
    code, _, err = show(path, capsys)
    assert (code, err) == (
        2,
        f"error: {path}: /entry/protocol holds a text of 3000000 bytes, more than the "
        "1000000 a run file's text may hold\n",
    )


def test_a_link_to_another_file_is_refused(sound_run, tmp_path, capsys):
    path = tmp_path / "linked.h5"
    shutil.copyfile(sound_run, path)
    with h5py.File(path, "r+") as f:
        del f["entry/title"]
        f["entry/title"] = h5py.ExternalLink("/dev/zero", "/x")
    code, _, err = show(path, capsys)
    assert (code, err) == (
        2,
        f"error: {path}: /entry/title is a link elsewhere; a run file holds none\n",
    )


def test_raw_table_of_two_billion_rows_is_refused(sound_run, tmp_path):
    path = tmp_path / "huge.h5"
    shutil.copyfile(sound_run, path)
    with h5py.File(path, "r+") as f:  # chunked and never written: a small file
        group = f["entry/repetitions/rep_01/pressure"]
        for name in list(group):
            dtype = group[name].dtype
            del group[name]
            group.create_dataset(name, shape=(2_000_000_000,), chunks=(1 << 20,), dtype=dtype)
    run = labrig.open_run(path)
    with pytest.raises(InputError, match=r"2000000000 rows asked for, more than the 250000000"):
        run.raw_table(1)


def corruptions():
    """A zeroed range, a few flipped bytes or a cut end, anywhere in the file."""
    where = st.integers(min_value=0, max_value=40_000)
    zero = st.tuples(st.just("zero"), where, st.integers(1, 4096))
    flip = st.tuples(st.just("flip"), st.lists(where, min_size=1, max_size=8), st.just(0))
    cut = st.tuples(st.just("cut"), where, st.just(0))
    return st.one_of(zero, flip, cut)


def corrupt(data: bytearray, how) -> bytes:
    kind, at, length = how
    if kind == "zero":
        data[at : at + length] = bytes(len(data[at : at + length]))
    elif kind == "flip":
        for i in at:
            if i < len(data):
                data[i] ^= 0xFF
    else:
        del data[at:]
    return bytes(data)


@pytest.mark.slow  # a child process per example, and 3 s for each stuck one
@settings(
    max_examples=8,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(how=corruptions())
def test_a_randomly_damaged_run_file_is_one_line_or_read(sound_run, tmp_path, capsys, how):
    path = tmp_path / "random.h5"
    path.write_bytes(corrupt(bytearray(sound_run.read_bytes()), how))
    code, _, err = show(path, capsys)
    assert code in (0, 2), err
    if code == 2:
        (line,) = err.splitlines()
        assert line.startswith(f"error: {path}") and "internal error" not in line
    faulthandler.dump_traceback_later(HANG_S, exit=True, file=sys.__stderr__)
    try:
        labrig.open_run(path).raw_table(1)
    except InputError as exc:
        assert "\n" not in str(exc)
    finally:
        faulthandler.cancel_dump_traceback_later()


def test_a_sound_file_is_walked_once(sound_run, monkeypatch):
    copy = sound_run.with_name("copy.h5")
    shutil.copyfile(sound_run, copy)
    walks = []
    real = file_check._walk_in_child
    monkeypatch.setattr(file_check, "_walk_in_child", lambda p: walks.append(p) or real(p))
    for _ in range(2):
        with open_run(copy) as run:
            assert np.all(run["entry/repetitions/rep_01/pressure/value"][()] >= 0)
    assert walks == [[copy]]
