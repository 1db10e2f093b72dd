"""A scan's plan: compiled or plain Python by the cost of each, numba's cache read
without importing the solver (an entry counts only for the function's current source),
and the console script's first small scan on an empty cache running as Python,
compiling nothing, into the same file as a compiled scan."""

import importlib
import math
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from support.scan_helpers import assert_same_contents

from labrig.model.scan import plan
from labrig.model.scan.plan import SolverCosts, plan_solver
from labrig.model.scan.run import run_scan
from labrig.model.scan.scan import load_library
from labrig.model.segments.catalog import (
    LIBRARIES,
    LIBRARY_NAMES,
    library_names,
    parse_library_name,
)


@pytest.mark.parametrize(
    ("segments", "n", "workers", "cached", "compiled"),
    [
        (36, 2, 2, False, False),  # the first scan after install: 630 actuators
        (36, 2, 16, False, False),
        (36, 3, 2, False, True),  # 7,140 actuators: minutes of Python, ~2 s compiled
        (36, 3, 16, False, True),
        (36, 4, 2, False, True),
        (36, 5, 64, False, True),
        (36, 2, 2, True, True),  # loading the cache costs less than 630 in Python
        (3, 2, 2, True, False),  # gent's 3 pairs: less than importing numba
        (9, 3, 2, False, False),  # 84 triples of a small measured library
    ],
)
def test_the_plan_picks_the_cheaper_mode(segments, n, workers, cached, compiled):
    costs = SolverCosts()
    actuators = math.comb(segments, n)
    chosen = plan_solver(actuators, n, workers, cached=cached, costs=costs)
    assert chosen.compiled is compiled
    # the figures it chose by, computed here from the costs
    share_s = actuators / workers / 1000
    python_s = share_s * costs.python_ms(n)
    compiled_s = costs.load_s + (0 if cached else costs.compile_s)
    compiled_s += share_s * costs.compiled_ms_per_actuator
    assert chosen.python_s == pytest.approx(python_s)
    assert chosen.compiled_s == pytest.approx(compiled_s)
    assert chosen.compiles_now is (compiled and not cached)


def test_python_costs_by_segments_extend_past_the_table():
    costs = SolverCosts(python_ms_per_actuator=((2, 1.0), (3, 2.0), (4, 3.0)))
    assert [costs.python_ms(n) for n in (2, 3, 4, 6)] == [1.0, 2.0, 3.0, 3.0]


@pytest.mark.parametrize("spec", ["analytical", "si", "gent", " Gent "])
def test_library_sizes_without_loading(spec):
    assert plan.library_size(spec) == len(load_library(spec).curves)
    assert plan.library_size(None) == plan.library_size("analytical")


@pytest.mark.parametrize("library", LIBRARIES)
def test_every_library_prefix_is_a_scan_library(library):
    """``--library paper|calibrated|si`` names the 36 segments as the catalog spells
    them (``paper:B46-T20``), each resolving to its own library's segment."""
    name, names = plan.named_library(f" {library.upper()} ")
    assert name == library and names == library_names(library)
    assert len(names) == 36 and all(parse_library_name(n)[0] == library for n in names)
    assert plan.named_library("analytical")[1] == LIBRARY_NAMES


def test_library_size_of_a_folder(tmp_path):
    for name in ("a", "b", "c"):
        (tmp_path / f"{name}.csv").write_text("volume_ml,pressure_kpa,length_mm\n")
    (tmp_path / "notes.txt").write_text("")
    assert plan.library_size(str(tmp_path)) == 3
    assert plan.library_size(str(tmp_path / "missing")) == 0


_MODULE = """
import numba


@numba.njit(cache=True)
def double(x):
    return {body}
"""


def _module(folder: Path, body: str) -> Path:
    path = folder / "fake_solver.py"
    path.write_text(textwrap.dedent(_MODULE.format(body=body)))
    return path


def test_a_cache_entry_counts_for_the_current_source_only(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(tmp_path))
    path = _module(tmp_path, "2 * x")
    assert not plan._cached("fake_solver", "double")  # nothing compiled yet
    module = importlib.import_module("fake_solver")
    try:
        assert module.double(21) == 42  # compiled and written to the cache
        assert plan._cached("fake_solver", "double")
        assert not plan._cached("fake_solver", "triple")  # no such function
        # a comment added: the same bytecode, but numba's index no longer fits the source
        stamp = path.stat()
        path.write_text(path.read_text() + "# a comment\n")
        assert not plan._cached("fake_solver", "double")
        _module(tmp_path, "2 * x")
        os.utime(path, ns=(stamp.st_atime_ns, stamp.st_mtime_ns))
        assert plan._cached("fake_solver", "double")
        # other bytecode
        _module(tmp_path, "x * 2")
        assert not plan._cached("fake_solver", "double")
    finally:
        sys.modules.pop("fake_solver", None)


def test_the_solver_is_not_cached_in_an_empty_cache(tmp_path):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    code = "from labrig.model.scan import plan; print(plan.solver_cached())"
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert done.stdout.strip() == "False", done.stderr


def test_the_planner_leaves_a_chosen_mode_alone(monkeypatch):
    # this process imported the solver (tests/conftest.py): its mode is fixed
    monkeypatch.delenv(plan.MODE_VARIABLE, raising=False)
    assert plan.choose_solver_mode("analytical", 2, None) is None
    assert plan.MODE_VARIABLE not in os.environ


_CHOOSE = """
import os, sys
from labrig.model.scan import plan
chosen = plan.choose_solver_mode(sys.argv[1], int(sys.argv[2]), None)
print(None if chosen is None else chosen.compiled, os.environ.get(plan.MODE_VARIABLE))
"""


@pytest.mark.parametrize(
    ("library", "n", "user_mode", "expected"),
    [
        ("analytical", 2, None, "False python"),  # an empty cache: Python
        ("analytical", 4, None, "True None"),  # compiles
        ("analytical", 2, "numba", "None numba"),  # the user's choice
        ("analytical", 7, None, "None None"),  # refused by the scan
        ("analytical", 1, None, "None None"),
    ],
)
def test_the_planner_sets_the_mode_for_this_process(tmp_path, library, n, user_mode, expected):
    env = {k: v for k, v in os.environ.items() if k != plan.MODE_VARIABLE}
    env["NUMBA_CACHE_DIR"] = str(tmp_path / "cache")
    if user_mode is not None:
        env[plan.MODE_VARIABLE] = user_mode
    done = subprocess.run(
        [sys.executable, "-c", _CHOOSE, library, str(n)], env=env, capture_output=True, text=True
    )
    assert done.stdout.strip() == expected, done.stderr


def test_a_first_small_scan_runs_as_python_into_the_same_file(tmp_path):
    """``labrig model scan --n 2 --library gent`` as a user runs it, on an empty cache:
    nothing compiled (numba's cache stays empty), no message, and the file equals the
    one this process writes through the compiled path."""
    cache = tmp_path / "cache"
    env = {k: v for k, v in os.environ.items() if k != plan.MODE_VARIABLE}
    env["NUMBA_CACHE_DIR"] = str(cache)
    out = tmp_path / "python.h5"
    argv = ["model", "scan", "--n", "2", "--library", "gent", "--out", str(out)]
    done = subprocess.run(
        [sys.executable, "-m", "labrig", *argv], env=env, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    assert "compiling" not in done.stderr
    assert "3 of 3 actuators (complete)" in done.stdout
    assert not list(cache.rglob("*.nbi"))
    compiled = run_scan(load_library("gent"), 2, tmp_path / "compiled.h5", workers=1)
    assert_same_contents(out, compiled)
