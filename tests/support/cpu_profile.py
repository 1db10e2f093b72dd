"""CPU time per test, with the processes it waited for: ``python -m pytest --cpu-profile``
(tests/conftest.py registers this plugin then). On a shared machine a test's wall time
says more about its neighbours than about it; its CPU time (user + system, of its worker
and of the commands, scans and kernels the worker started and reaped) is what the
suite's order and groups (tests/conftest.py) are balanced on.

Each worker measures its tests (setup, call and teardown together) and sends the figure
to the controller in the teardown report's ``user_properties``; the controller prints
each worker's total, when its last test ended (minutes:seconds of wall time after the
session started: the workers should end together, tests/conftest.py's order) and the
slowest tests at the end, with the load average at the start and at the end (the
suite's own workers count in it); every test's figure is kept in pytest's cache
(``.pytest_cache/v/labrig/cpu_profile``, JSON), for two runs to be compared test by test.
A child reaped during a later test counts there (a module fixture's processes, stopped
after the module's last test)."""

from __future__ import annotations

import os
import resource
import time

import pytest

KEY = "cpu_s"
END = "end_s"  # the wall clock (time.time()) as the test's teardown ended
SHOWN = 30  # the slowest tests listed


def _cpu_s() -> float:
    me = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime + children.ru_utime + children.ru_stime


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    item.stash[_START] = _cpu_s()
    yield


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    if call.when == "teardown" and _START in item.stash:
        properties = outcome.get_result().user_properties
        properties.append((KEY, _cpu_s() - item.stash[_START]))
        properties.append((END, time.time()))


_START = pytest.StashKey[float]()
_MEASURED: list[tuple[float, str, str]] = []  # (CPU s, worker, node id), in the controller
_ENDED: dict[str, float] = {}  # worker: the wall clock as its last test ended
_STARTED = time.time()  # the session's start, near enough: this plugin is loaded then
_LOAD: list[float] = []  # the 1-minute load average at the session's start


def pytest_sessionstart(session):
    global _STARTED
    _STARTED = time.time()
    _LOAD[:] = [os.getloadavg()[0]]


def pytest_runtest_logreport(report):
    if report.when != "teardown":
        return
    node = getattr(report, "node", None)  # xdist's worker, in its controller
    worker = node.gateway.id if node is not None else "main"
    for key, value in report.user_properties:
        if key == KEY:
            _MEASURED.append((value, worker, report.nodeid))
        elif key == END:
            _ENDED[worker] = max(value, _ENDED.get(worker, value))


def pytest_terminal_summary(terminalreporter, config):
    if not _MEASURED:
        return
    write = terminalreporter.write_line
    terminalreporter.section("CPU time of the tests (s, with the processes they reaped)")
    load = f"{_LOAD[0]:.1f}" if _LOAD else "?"
    write(f"load average (1 min): {load} at the start, {os.getloadavg()[0]:.1f} at the end")
    cache = getattr(config, "cache", None)  # None with -p no:cacheprovider
    if cache is not None:
        cache.set("labrig/cpu_profile", {nodeid: round(cpu, 3) for cpu, _, nodeid in _MEASURED})
    workers = sorted({w for _, w, _ in _MEASURED})
    for worker in workers:
        spent = [cpu for cpu, w, _ in _MEASURED if w == worker]
        minutes, seconds = divmod(round(_ENDED.get(worker, _STARTED) - _STARTED), 60)
        ended = f"{minutes}:{seconds:02d}"
        write(f"{worker}: {sum(spent):7.1f} in {len(spent)} tests, the last ended at {ended}")
    write(f"all: {sum(cpu for cpu, _, _ in _MEASURED):7.1f}; the {SHOWN} slowest:")
    for cpu, worker, nodeid in sorted(_MEASURED, reverse=True)[:SHOWN]:
        write(f"{cpu:7.2f} {worker} {nodeid}")
