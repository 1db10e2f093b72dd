"""The background compile: started by ``labrig model scan`` after a scan in plain Python
on an empty cache (and only then), detached, in numba's mode, switched off by
``LABRIG_BACKGROUND_COMPILE=0``; one at a time. And what the scan command says it
compiles, once the scan's input is accepted."""

import os
import subprocess
import sys

import pytest

from labrig.cli import main
from labrig.model.scan import background_compile, plan
from labrig.model.scan.plan import SolverPlan


class _Finished:
    def wait(self) -> int:
        return 0


class _Spawned:
    def __init__(self) -> None:
        self.calls = []

    def __call__(self, argv, **options):
        self.calls.append((argv, options))


def test_start_detaches_a_process_in_numbas_mode(monkeypatch):
    spawned = _Spawned()
    monkeypatch.setattr(background_compile.subprocess, "Popen", spawned)
    monkeypatch.delenv(background_compile.SWITCH_VARIABLE, raising=False)
    monkeypatch.setenv(plan.MODE_VARIABLE, plan.PYTHON)
    assert background_compile.start()
    [(argv, options)] = spawned.calls
    assert argv == [sys.executable, "-m", "labrig.model.scan.background_compile"]
    assert plan.MODE_VARIABLE not in options["env"]
    assert options["start_new_session"]
    assert options["stdout"] == options["stderr"] == subprocess.DEVNULL


def test_the_compile_beside_a_scan_is_its_children_at_its_priority(monkeypatch):
    spawned = _Spawned()
    monkeypatch.setattr(background_compile.subprocess, "Popen", spawned)
    monkeypatch.setenv(background_compile.SWITCH_VARIABLE, "0")  # only the background's switch
    monkeypatch.setenv(plan.MODE_VARIABLE, plan.PYTHON)
    background_compile.compile_beside()
    module = [sys.executable, "-m", "labrig.model.scan.background_compile"]
    assert [argv for argv, _ in spawned.calls] == [
        [*module, "reference"],  # at the lowest priority, not waited for
        [*module, "--now", "compiled"],
    ]
    for _, options in spawned.calls:
        assert plan.MODE_VARIABLE not in options["env"]
        assert not options["start_new_session"]  # a Ctrl-C at the scan stops it too
    niced, compiled = [], []
    monkeypatch.setattr(background_compile.os, "nice", niced.append, raising=False)
    monkeypatch.setattr(background_compile, "solver_cached", lambda entries: False)
    monkeypatch.setattr(background_compile, "compile_solver", compiled.append)
    for args, lowest, parts in (
        ([], [19], ("compiled", "reference")),
        (["--now", "reference"], [], ("reference",)),
    ):
        niced.clear()
        monkeypatch.setattr(sys, "argv", ["background_compile", *args])
        background_compile.main()
        assert niced == lowest
        assert compiled.pop() == parts


def test_start_is_switched_off(monkeypatch):
    spawned = _Spawned()
    monkeypatch.setattr(background_compile.subprocess, "Popen", spawned)
    monkeypatch.setenv(background_compile.SWITCH_VARIABLE, "0")
    assert not background_compile.start()
    assert spawned.calls == []


def test_one_compile_at_a_time(tmp_path, monkeypatch):
    """One compile at a time into one cache; this test's own cache, so a compile into
    the suite's cache elsewhere neither blocks it nor is blocked."""
    cache = tmp_path / "cache"
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(cache))
    env = {k: v for k, v in os.environ.items() if k != plan.MODE_VARIABLE}
    with background_compile.one_at_a_time() as mine:
        assert mine
        with background_compile.one_at_a_time() as second:
            assert not second
        # another process leaves at once, without compiling into the empty cache
        done = subprocess.run(
            [sys.executable, "-m", "labrig.model.scan.background_compile"],
            env=env,
            capture_output=True,
            text=True,
            timeout=300,  # a guard against a hang, not a measure: compiling writes files
        )
        assert done.returncode == 0, done.stderr
    assert not list(cache.rglob("*.nbi"))
    with background_compile.one_at_a_time() as again:
        assert again  # released
    with (
        background_compile.one_at_a_time(("compiled",)) as mine,
        background_compile.one_at_a_time(("reference",)) as other,
    ):
        assert mine and other  # the other part writes other functions: no wait
    with background_compile.one_at_a_time() as mine:
        monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "another cache"))
        with background_compile.one_at_a_time() as other:
            assert mine and other  # a compile into another cache does not wait for it


@pytest.mark.parametrize(
    ("compiled", "cached", "before", "after"),
    [
        (False, False, False, True),  # Python on an empty cache: compile for the next
        (False, True, False, False),  # a tiny scan beside a cached solver
        (True, False, True, False),  # compiles now, and says so first
        (True, True, False, False),
    ],
)
def test_the_scan_command_says_what_it_compiles(
    tmp_path, capsys, monkeypatch, compiled, cached, before, after
):
    chosen = SolverPlan(compiled, cached, python_s=1.0, compiled_s=1.0)
    monkeypatch.setattr(plan, "choose_solver_mode", lambda *args: chosen)
    started, beside = [], []
    monkeypatch.setattr(background_compile, "start", lambda: started.append(1) or True)
    monkeypatch.setattr(
        background_compile, "compile_beside", lambda part: beside.append(part) or _Finished()
    )
    out = tmp_path / "gent.h5"
    with pytest.raises(SystemExit) as exited:
        main(["model", "scan", "--n", "2", "--library", "gent", "--out", str(out)])
    err = capsys.readouterr().err
    assert exited.value.code == 0, err
    assert ("compiling the solver once" in err) is before
    assert ("compiling the solver in the background" in err) is after
    assert started == ([1] if after else [])
    # beside the library's tables; measured curves would run the reference
    assert beside == (["compiled"] if before else [])


def test_no_compile_is_announced_for_a_scan_refused(tmp_path, capsys, monkeypatch):
    chosen = SolverPlan(True, False, python_s=100.0, compiled_s=50.0)
    monkeypatch.setattr(plan, "choose_solver_mode", lambda *args: chosen)
    out = tmp_path / "taken.h5"
    out.write_bytes(b"precious")
    with pytest.raises(SystemExit) as exited:
        main(["model", "scan", "--n", "2", "--library", "gent", "--out", str(out)])
    err = capsys.readouterr().err
    assert exited.value.code == 2 and "the file exists" in err
    assert "compiling" not in err
