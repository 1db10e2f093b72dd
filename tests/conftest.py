"""Shared fixtures: simulated run files, written once per session (see support/simulated_runs.py);
and the order of the suite on pytest-xdist's three workers (pyproject.toml's addopts).

The order: the suite runs on three processes (``-n 3 --dist loadgroup``), which hand out
work units (a test, or a group's tests together: ``GROUPS``) in the order collected; the
long ones (``LONG_FIRST``, the slowest measured on the 2-core machine) are moved to the
front so that no worker is left with one of them at the end while the others idle.
The tests of the compiled path (scans and the compiled path itself, in-process or
through ``labrig model scan``) form one group: on a fresh clone the first of them
compiles ``labrig.model.actuator.compiled_path`` (~1 min of one core: 56 s of CPU,
tests/benchmarks/bench_compile.py; 1.5-3 min before: labrig.model.actuator.jit), and the
fixture ``compiled_path_cached`` does that once, in that worker, before any scan's own
worker processes start (each would compile it at the same time, two cores for one
result; the cache written here is the one they load: measured, no new cache file).
Every compile in the run's workers waits behind its function's lock
(``_each_function_compiled_once``), so that a function is compiled by one worker and
loaded by the others: on a fresh clone the analysis of every simulated run and the
paper's statements (the ``libraries`` group) compile the reference path's kernels, and
two or three workers compiled them side by side. Those need none of the compiled path,
so they do not wait for its compile.

Every module of labrig is imported before the first test (``_import_every_module``), in
each process that runs tests (xdist's controller runs none, so it imports no labrig: the
fixtures import ``support.simulated_runs`` when first used):
hypothesis draws a few of its values from the constants of the local modules already
in ``sys.modules``, so a property test's examples, derandomized or not, would otherwise
depend on which tests ran before it in its process; with workers handing out work
as each finishes, on the host's speed. Seen: test_stress found two failing examples
only when it ran after the compiled path's tests in their worker.
"""

import functools
import gc
import importlib
import os
import pkgutil
import re
import shutil
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

# no scan started by a test compiles in the background
# (labrig.model.scan.background_compile): the suite compiles once, in the foreground
os.environ.setdefault("LABRIG_BACKGROUND_COMPILE", "0")

# node ids (prefixes) of the longest work units, longest first (a group's tests count
# together; seconds of CPU on the 2-core machine with a warm numba cache, from
# --cpu-profile; the live page's and the watcher's take three times that in wall time,
# paced): these start first, in this order (--no-loadscope-reorder: xdist would order
# by test count), so that none starts late and leaves its worker last
LONG_FIRST = (
    "tests/model/actuator/test_jit.py::",  # the compiled path's group: ~100, +60 cold
    "tests/cli/test_model_paper.py::",  # the libraries' group: 55, four libraries' pairs
    "tests/model/segments/test_free_bulge.py::",  # 35: Maxwell's conditions, twice
    "tests/api/test_tutorial.py::test_the_tutorial_runs_top_to_bottom",  # 29: 3 runs
    "tests/rig/test_demo_run.py::",  # the demo's group: 27
    "tests/analysis/test_compare.py::",  # the simulated runs' group: ~25
    "tests/api/test_run.py::",  # the API's run and scan: ~25
    "tests/rig/test_video_and_frames.py::",  # 22
    "tests/cli/test_model_scan.py::test_ctrl_c",  # 18
    "tests/rig/test_experiments_run.py::test_the_blocked",  # 17
    "tests/config/test_rig_bounds.py::test_the_stiffest",  # 16
    "tests/live/test_live_page.py::",  # 14 (45 s of wall time)
    "tests/docs/test_characterising_tutorial.py::test_the_tutorial_runs",  # 14
    "tests/model/segments/test_paper_braided.py::",  # 13: the paper library, built once
    "tests/model/segments/test_gent.py::",  # 13
    "tests/live/test_api_state.py::",  # 12 (45 s of wall time)
    "tests/rig/test_faults.py::",  # 13
    "tests/rig/test_device_deaths.py::",  # 13
    "tests/rig/test_experiments_run.py::",  # 11
    "tests/run/test_endings.py::",  # 11
    "tests/live/test_watch.py::",  # 8 (30 s of wall time)
    "tests/model/segments/test_measured_curves.py::",  # 8
    "tests/model/baselines/test_nelder_mead.py::test_the_papers_named_combinations",  # 11
    "tests/sim/test_pump.py::test_a_flood",  # 7
    "tests/analysis/test_plot_marks.py::",  # one simulated run for both tests
    "tests/model/baselines/test_nelder_mead.py::",
)
# tests that share something costly, each group run by one worker: the compiled path
# (see the module docstring), the demo's run (a session fixture, rig/conftest.py), the
# simulated runs of this file and the API's run (session fixtures); a fixture's scope is
# per process, so tests spread over two workers made it twice (seen: the video run, 3 s
# of CPU each). A module with a module-scoped fixture is a group of its own (``_group``).
COMPILED_GROUP = "compiled_path"
GROUPS = {
    "tests/cli/test_benchmark.py::": COMPILED_GROUP,
    "tests/model/actuator/test_compiled_path.py::": COMPILED_GROUP,
    "tests/model/actuator/test_jit.py::": COMPILED_GROUP,
    "tests/model/scan/test_background_compile.py::": COMPILED_GROUP,
    "tests/model/scan/test_plan.py::test_a_first_small_scan": COMPILED_GROUP,
    "tests/model/scan/test_scan.py::": COMPILED_GROUP,
    "tests/model/scan/test_scan_distributed.py::": COMPILED_GROUP,
    "tests/model/scan/test_scan_failures.py::": COMPILED_GROUP,
    "tests/rig/test_demo_run.py::": "demo_run",
    "tests/rig/test_determinism.py::": "demo_run",
    "tests/analysis/test_compare.py::": "simulated_runs",
    "tests/analysis/test_results.py::": "simulated_runs",
    "tests/analysis/test_transitions.py::": "simulated_runs",
    "tests/cli/test_review.py::": "simulated_runs",
    "tests/cli/test_library_add.py::": "simulated_runs",
    "tests/docs/test_run_file_doc.py::": "simulated_runs",
    # the paper's statements and the catalog's check of every library segment build the
    # same libraries' 36 segments (labrig.model.segments.catalog keeps them per process)
    "tests/cli/test_model_paper.py::": "libraries",
    "tests/model/segments/test_catalog.py::test_every_library_segment": "libraries",
    # tests/api/conftest.py's run and scan: every module that reads them (spread, the
    # run was recorded by two workers and the scan by two, ~3 s of CPU each)
    "tests/api/test_run.py::": "api_quick_run",
    "tests/api/test_matches_the_cli.py::": "api_quick_run",
    "tests/api/test_run_energy.py::": "api_quick_run",
    "tests/api/test_solver_mode.py::": "api_quick_run",
    "tests/api/test_vocabulary.py::": "api_quick_run",
    "tests/api/test_model_and_scan.py::": "api_quick_run",
}


# labrig's packages (drivers/ and sim/ are mapped to labrig.drivers and labrig.sim)
PACKAGES = ("labrig", "labrig.drivers", "labrig.sim")


def _import_every_module() -> None:
    """All of labrig in sys.modules: the same constants for hypothesis in every worker,
    whatever ran before (see the module docstring)."""
    for name in PACKAGES:
        package = importlib.import_module(name)
        for module in pkgutil.walk_packages(package.__path__, f"{name}."):
            if not module.name.endswith(".__main__"):  # __main__ runs the CLI
                importlib.import_module(module.name)


def pytest_configure(config):
    """Every module of labrig imported where tests run: not in xdist's controller,
    which hands out work and runs none (~3 s of CPU it need not spend).

    Bytecode is kept (``__pycache__``, where numba keeps its cache) even where
    ``PYTHONDONTWRITEBYTECODE`` is set: without it each of the three workers rewrote
    every test module's asserts again (collection took 10 s of CPU, 5 s with the
    bytecode kept) and every command a test starts compiled labrig's modules again;
    the processes the tests start still write none, they read what is there."""
    sys.dont_write_bytecode = False
    controller = (
        not hasattr(config, "workerinput")
        and config.getoption("dist", "no") != "no"
        and not config.getoption("collectonly")
    )
    if controller:
        _rewrite_test_modules_once(config)
    else:
        _import_every_module()
        # what the imports made lives as long as the process: out of the collector's
        # way (gc.freeze), a full collection no longer walks it again (a fifth of the
        # garbage collector's CPU in a worker)
        gc.freeze()
    if config.getoption("cpu_profile"):
        from support import cpu_profile

        config.pluginmanager.register(cpu_profile, "cpu_profile")


def _rewrite_test_modules_once(config) -> None:
    """pytest's cached pyc of every test module and conftest (their asserts rewritten)
    written by xdist's controller before its workers start: on a fresh clone the three
    workers each rewrote all of them at once (a worker's collection took 12 s of CPU
    without them, 7 s with them). One that is current is read, not written again; the
    names are pytest's private ones, and where they moved the workers rewrite as before."""
    try:
        from _pytest.assertion import assertstate_key
        from _pytest.assertion.rewrite import (
            PYC_TAIL,
            _read_pyc,
            _rewrite_test,
            _write_pyc,
            get_cache_dir,
            try_makedirs,
        )
    except ImportError:
        return
    state = config.stash.get(assertstate_key, None)
    if state is None:  # --assert=plain: nothing is rewritten
        return
    for source in sorted((ROOT / "tests").rglob("*.py")):
        if not (source.name.startswith("test_") or source.name == "conftest.py"):
            continue
        folder = get_cache_dir(source)
        pyc = folder / (source.name[:-3] + PYC_TAIL)
        if _read_pyc(source, pyc) is None and try_makedirs(folder):
            source_hash, code = _rewrite_test(source, config)
            _write_pyc(state, code, source_hash, pyc)


def pytest_addoption(parser):
    parser.addoption(
        "--cpu-profile",
        action="store_true",
        help="print each worker's and the slowest tests' CPU time (tests/support/cpu_profile.py)",
    )


# every property test draws the same examples on every run and on every machine
# (derandomized, no example database): a new example found by chance on a busy CI
# machine would fail a submission that passed here; what hypothesis finds while a test
# is written is kept as an @example. No deadline and no "too slow" check: both are a
# verdict on the host's speed, not on the code
settings.register_profile(
    "labrig",
    derandomize=True,
    database=None,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.load_profile("labrig")


def _rank(nodeid: str) -> int:
    return next((i for i, p in enumerate(LONG_FIRST) if nodeid.startswith(p)), len(LONG_FIRST))


ROOT = Path(__file__).resolve().parents[1]  # pytest's rootdir: node ids are relative to it
# a fixture made once per module (or class) of tests
_SHARED_FIXTURE = re.compile(r"@pytest\.fixture\([^)]*scope\s*=\s*[\"'](module|class)[\"']")


@functools.cache
def _shares_a_fixture(path: str) -> bool:
    """Whether the test module at ``path`` makes a module- or class-scoped fixture: its
    tests then run on one worker, which makes the fixture once (spread over three
    workers, a module's fixture was made up to three times: seen, the paper library's
    36 segments in test_paper_braided, the simulated run of test_plot_marks)."""
    try:
        return _SHARED_FIXTURE.search((ROOT / path).read_text()) is not None
    except OSError:
        return False


def _group(nodeid: str) -> str | None:
    """The tests' group (``GROUPS``), else the module's when it shares a fixture."""
    group = next((g for p, g in GROUPS.items() if nodeid.startswith(p)), None)
    module = nodeid.split("::", 1)[0]
    return group or (module if _shares_a_fixture(module) else None)


def pytest_collection_modifyitems(items):
    """The long tests first (a stable sort: the rest keep their order)."""
    items.sort(key=lambda item: _rank(item.nodeid))


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    """``--dist loadgroup`` with ``GROUPS`` as the groups. xdist's own marks the groups
    by a suffix to each test's node id, which pytest 9.2 no longer takes (its node ids
    are not strings set on the item): the marked tests were spread over both workers.
    Its scheduler is kept; only the grouping is this file's."""
    if config.getvalue("dist") != "loadgroup":
        return None
    from xdist.scheduler import LoadGroupScheduling

    class Groups(LoadGroupScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return _group(nodeid) or nodeid

    return Groups(config, log)


@pytest.fixture(scope="session", autouse=True)
def _each_function_compiled_once(tmp_path_factory):
    """In each of the run's workers, before its first test: every compile behind its
    function's lock, shared by the workers (their temporary folders' parent is the
    run's), so that on an empty cache one worker compiles it and the others load it
    (support/compile_once.py). One process needs none."""
    from labrig.model.actuator import jit

    if jit.COMPILED and os.environ.get("PYTEST_XDIST_WORKER"):
        from support import compile_once

        compile_once.install(tmp_path_factory.getbasetemp().parent)


@pytest.fixture(scope="session")
def compiled_path_cached():
    """The compiled path compiled in this process for the scans' argument types, which
    writes numba's cache for every process after it (a no-op when the cache is warm).
    A function another worker compiles meanwhile is waited for and loaded
    (``_each_function_compiled_once``)."""
    from labrig.model.actuator import jit

    if not jit.COMPILED:
        return
    from labrig.model.scan.background_compile import compile_solver

    compile_solver()


@pytest.fixture(autouse=True)
def _compiled_path_first(request):
    if _group(request.node.nodeid) == COMPILED_GROUP:
        request.getfixturevalue("compiled_path_cached")


@pytest.fixture(scope="session")
def snap_run(tmp_path_factory):
    """SI-B46-T20 + SI-B46-T22 (the paper's Fig. 2 pair) inflated at 20 mL/min to 22 mL, five
    times, through water-like flow resistance (R = 1 kPa s/mL): the plant snaps through
    on inflation; pressure noise 0.3 kPa, the top of the issue's range."""
    from support.simulated_runs import simulate_run

    path = tmp_path_factory.mktemp("runs") / "snap.h5"
    return simulate_run(path, ("SI-B46-T20", "SI-B46-T22"), volume_ml=22.0, noise_kpa=0.3, seed=11)


@pytest.fixture(scope="session")
def library_run(tmp_path_factory):
    """SI-B44-T22 + SI-B50-T20 in the slow limit (R = 0.05 kPa s/mL), where the plant follows
    the model's quasi-static path: one snap on inflation, one on deflation."""
    from support.simulated_runs import simulate_run

    path = tmp_path_factory.mktemp("runs") / "library.h5"
    return simulate_run(
        path,
        ("SI-B44-T22", "SI-B50-T20"),
        volume_ml=36.0,
        resistance_kpa_s_per_ml=0.05,
        noise_kpa=0.1,
        seed=12,
    )


@pytest.fixture(scope="session")
def segment_run(tmp_path_factory):
    """A single segment, SI-B46-T20, past its valley onto the stiffening wall; the third
    repetition faulted (so the mean is of repetitions 1, 2, 4 and 5)."""
    from support.simulated_runs import simulate_run

    path = tmp_path_factory.mktemp("runs") / "segment.h5"
    statuses = ("complete", "complete", "faulted", "complete", "complete")
    return simulate_run(
        path, ("SI-B46-T20",), volume_ml=20.8, noise_kpa=0.15, statuses=statuses, seed=13
    )


@pytest.fixture
def copy_of(tmp_path):
    """A private copy of a session run file, for tests that write to it."""

    def copy(run, name="copy.h5"):
        target = tmp_path / name
        shutil.copyfile(run.path, target)
        return target

    return copy


@pytest.fixture
def tiny_file(tmp_path):
    """A small complete run (2 repetitions of 2 mL, p = 5 v, l = 30 + v)."""
    from support.simulated_runs import tiny_run

    return tiny_run(tmp_path / "tiny.h5")


@pytest.fixture
def killed_file(tmp_path):
    """A run file left by a SIGKILLed writer: flagged open, status running."""
    from support.simulated_runs import killed_run

    return killed_run(tmp_path)


@pytest.fixture(autouse=True)
def _signal_handlers_restored():
    """Each test starts with the worker's own Ctrl-C and SIGTERM handlers: one left
    behind by an earlier test (a run's stop handler) would make Ctrl-C stop raising
    KeyboardInterrupt in every later test of its worker. A test that leaves one is
    named in the run's warnings, for the leak to be found where it happens."""
    import signal
    import warnings

    before = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    yield
    left = {s: signal.getsignal(s) for s, h in before.items() if signal.getsignal(s) is not h}
    for signum in left:
        signal.signal(signum, before[signum])
    if left:
        warnings.warn(
            "the test left its own handler behind (put back): "
            + ", ".join(
                f"{s.name}: {_handler_name(h)} where it began with {_handler_name(before[s])}"
                for s, h in left.items()
            ),
            pytest.PytestWarning,
            stacklevel=1,
        )


def _handler_name(handler) -> str:
    return f"{getattr(handler, '__module__', '')}.{getattr(handler, '__qualname__', handler)}"
