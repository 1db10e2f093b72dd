"""Benchmark of the model's solvers: run time against error, and full-scan times.

Every solver runs on the same fixed sample of actuators (the paper's named combinations
plus pairs and triples of the library drawn with a fixed seed), inflating to the same
volume, side by side in one process. The sample is of the SI's segments (``SI-B46-T20``):
on the calibrated ones a segment that crosses its peak and snaps at once is one
transition to the references (the paper's way of counting) and two to the fast path (a
stable crossing, then the snap), so their sequences would not compare.

- ``fast``: the continuation of ``labrig.model.actuator.path`` at its accuracy settings (the
  fold screen's margin, the flow's local error per step);
- ``nelder-mead``: the paper's incremental algorithm (``labrig.model.baselines.nelder_mead``) at
  several volume increments;
- ``grid``: the path read off the equilibria on an equispaced pressure grid
  (``labrig.model.baselines.grid_path``, the paper's Fig. S5 method) at several grid sizes.

The "very fine reference" is the fast path at its tightest settings (``REFERENCE``): the
sum 1/k_i computed exactly at every sample pressure of every segment along every
softening piece (no screen), and the flow after a snap integrated to 1e-3 of a sample
spacing per step (~1e-4 mL; the flow tolerance is in units of the tables' mean sample
spacing, ``labrig.model.actuator.descent.settle``).
Its transition volumes are not samples: a fold is a root of sum 1/k_i (Eq. 10) to
1e-11 kPa and a peak crossing is an exact sample of the segment's table, so no
increment or grid limits it; the tight settings only guard against a fold hidden
between screened points and a flow that ends in another basin. That this reference is
right is not taken on trust: the Nelder-Mead rows, which share nothing with it but the
curves, converge to it as the increment shrinks (errors of the order of one increment),
which is the independent check.

Errors: the largest and mean |v - v_ref| over all transitions (mL) and the largest
|dE - dE_ref| over snaps. A stable transition's dE depends only on the increment of the
method (the paper says so; labrig uses a fixed 1e-4 mL window), so it is not compared.
An actuator whose sequence of transition types differs from the reference's counts as
a mismatch, and its transitions are left out of the errors.
"""

from __future__ import annotations

import math
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from labrig.model.actuator.descent import FLOW_TOL
from labrig.model.actuator.equilibria import Actuator
from labrig.model.actuator.path import SCREEN_MARGIN
from labrig.model.segments.catalog import SI_NAMES, analytical_segment

NAMED_PAIRS = (
    ("SI-B46-T20", "SI-B46-T22"),
    ("SI-B48-T30", "SI-B50-T20"),
    ("SI-B44-T30", "SI-B48-T26"),
)
NAMED_TRIPLE = ("SI-B40-T28", "SI-B44-T30", "SI-B50-T24")
# (fold screen margin, flow tolerance in sample spacings): the defaults, the tightest
DEFAULT_FAST = (SCREEN_MARGIN, FLOW_TOL)
REFERENCE = (math.inf, 1e-3)
SEED = 2016


@dataclass(frozen=True)
class BenchSettings:
    pairs: int = 10
    triples: int = 5
    fast_settings: tuple[tuple[float, float], ...] = ((0.05, 1.0), DEFAULT_FAST)
    nm_increments_ml: tuple[float, ...] = (0.05, 0.02, 0.01)
    grid_points: tuple[int, ...] = (250, 1000, 4000)
    # n = 4 takes minutes on two cores: asked for with --scans 2,3,4
    scan_ns: tuple[int, ...] = (2, 3)

    @classmethod
    def quick(cls) -> BenchSettings:
        """CI-sized: two named pairs, coarse increments, the n = 2 scan only."""
        return cls(
            pairs=2,
            triples=0,
            fast_settings=(DEFAULT_FAST,),
            nm_increments_ml=(0.1, 0.05),
            grid_points=(250, 1000),
            scan_ns=(2,),
        )


def bench_sample(pairs: int, triples: int, seed: int = SEED) -> list[tuple[str, ...]]:
    """The paper's named combinations first, then distinct random ones of the library."""
    rng = np.random.default_rng(seed)
    chosen: list[tuple[str, ...]] = []
    for size, count, named in ((2, pairs, NAMED_PAIRS), (3, triples, (NAMED_TRIPLE,))):
        picked = list(named[:count])
        while len(picked) < count:
            combo = tuple(sorted(rng.choice(len(SI_NAMES), size, replace=False)))
            names = tuple(SI_NAMES[i] for i in combo)
            if names not in picked:
                picked.append(names)
        chosen += picked
    return chosen


@dataclass(frozen=True)
class Found:
    """A transition as every solver can report it."""

    alpha: int
    beta: int
    stable: bool
    v_ml: float
    dE: float  # NaN for stable transitions (not compared)


def _from_states(actuator: Actuator, found) -> list[Found]:
    """Transitions that carry the states before and after (the Nelder-Mead and grid
    solvers): dE of a snap from the energies of those states."""
    return [
        Found(
            t.alpha,
            t.beta,
            t.stable,
            t.v_ml,
            math.nan
            if t.stable
            else actuator.energy_mj(t.v_i_post_ml) / actuator.energy_mj(t.v_i_pre_ml) - 1.0,
        )
        for t in found
    ]


def solve_fast(
    actuator: Actuator, v_end_ml: float | None, setting: tuple[float, float]
) -> list[Found]:
    from labrig.model.actuator.path import quasi_static_path
    from labrig.model.actuator.transitions import transitions

    margin, flow_tol = setting
    path = quasi_static_path(actuator, v_end_ml, screen_margin=margin, flow_tol=flow_tol)
    found = transitions(path)
    return [Found(t.alpha, t.beta, t.stable, t.v_ml, math.nan if t.stable else t.dE) for t in found]


def solve_nelder_mead(actuator: Actuator, v_end_ml: float, dv_ml: float) -> list[Found]:
    """The paper's algorithm; a transition's volume is its last increment before it, and
    a snap's state after is one increment later (as the algorithm sees them)."""
    from labrig.model.baselines.nelder_mead import reference_path

    return _from_states(actuator, reference_path(actuator, v_end_ml, dv_ml=dv_ml).transitions)


def solve_grid(actuator: Actuator, v_end_ml: float, n_points: int) -> list[Found]:
    from labrig.model.baselines.grid_path import grid_path

    return _from_states(actuator, grid_path(actuator, v_end_ml, n_points=n_points))


@dataclass(frozen=True)
class SolverRow:
    solver: str
    setting: str
    parameter: object  # fast settings, increment (mL) or grid points
    seconds: float  # total over the sample
    actuators: int
    matched: int  # actuators with the reference's sequence of transition types
    failed: int
    v_error_max_ml: float
    v_error_mean_ml: float
    dE_error_max: float

    @property
    def ms_per_actuator(self) -> float:
        return 1e3 * self.seconds / self.actuators


def _compare(rows: list[tuple[list[Found] | None, list[Found]]]):
    matched = failed = 0
    v_errors: list[float] = []
    dE_errors: list[float] = []
    for found, reference in rows:
        if found is None:
            failed += 1
            continue
        if [(f.alpha, f.beta, f.stable) for f in found] != [
            (r.alpha, r.beta, r.stable) for r in reference
        ]:
            continue
        matched += 1
        for f, r in zip(found, reference, strict=True):
            v_errors.append(abs(f.v_ml - r.v_ml))
            if not r.stable:
                dE_errors.append(abs(f.dE - r.dE))
    return (
        matched,
        failed,
        max(v_errors, default=math.nan),
        float(np.mean(v_errors)) if v_errors else math.nan,
        max(dE_errors, default=math.nan),
    )


def bench_solvers(settings: BenchSettings, log=print) -> tuple[list[SolverRow], int]:
    """Every solver on the sample; returns the rows and the sample size."""
    sample = bench_sample(settings.pairs, settings.triples)
    actuators = [Actuator([analytical_segment(n) for n in names]) for names in sample]
    for a in actuators:
        a.kernels  # noqa: B018 (built before any timing: every solver shares them)
    references, v_ends = [], []
    for a in actuators:
        first = solve_fast(a, None, REFERENCE)
        v_end = max((t.v_ml for t in first), default=20.0) + 1.0  # the story ends there
        v_ends.append(v_end)
        references.append(solve_fast(a, v_end, REFERENCE))
    solvers = [
        ("fast", f"screen margin {margin:g}, flow tol {tol:g}", solve_fast, (margin, tol))
        for margin, tol in settings.fast_settings
    ]
    solvers += [
        ("nelder-mead", f"dv = {dv:g} mL", solve_nelder_mead, dv)
        for dv in settings.nm_increments_ml
    ]
    solvers += [("grid", f"{k:,} pressures", solve_grid, k) for k in settings.grid_points]
    out = []
    for name, label, solve, parameter in solvers:
        # once before the clock starts: loads (or on a fresh install compiles) the
        # solver's compiled code, a cost paid once per process, not per actuator
        solve(actuators[0], v_ends[0], parameter)
        pairs = []
        started = time.perf_counter()
        for a, v_end, reference in zip(actuators, v_ends, references, strict=True):
            try:
                found = solve(a, v_end, parameter)
            except Exception:  # a solver that fails on an actuator is counted, not fatal
                found = None
            pairs.append((found, reference))
        seconds = time.perf_counter() - started
        row = SolverRow(name, label, parameter, seconds, len(actuators), *_compare(pairs))
        log(f"  {name:12s} {label:22s} {row.ms_per_actuator:10.2f} ms per actuator")
        out.append(row)
    return out, len(sample)


@dataclass(frozen=True)
class ScanRow:
    n: int
    actuators: int
    transitions: int
    failed: int
    wall_s: float  # the command, start-up included
    scan_s: float  # the scan itself
    workers: int
    parent_peak_mib: float
    worker_peak_mib: float


def bench_scan(n: int, folder: Path) -> ScanRow:
    """A full scan of the analytical library by the real command in a fresh process
    (so that its peak memory is its own)."""
    from labrig.model.scan.scan_file import read_scan

    out = folder / f"scan_n{n}.h5"
    command = [sys.executable, "-m", "labrig", "model", "scan", "--n", str(n), "--out", str(out)]
    started = time.perf_counter()
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - started
    data = read_scan(out)
    return ScanRow(
        n,
        data.n_combinations,
        data.row_stop,
        len(data.failed_actuator),
        wall,
        data.elapsed_s,
        data.workers,
        data.parent_peak_rss_mib,
        data.worker_peak_rss_mib,
    )


def bench_scans(ns, log=print, keep: Path | None = None) -> list[ScanRow]:
    """The scans of ``ns``; their files in ``keep`` (scan_n<N>.h5, for their failures
    or a ranking) or in a temporary folder removed at the end."""
    if keep is not None:
        return [_logged(bench_scan(n, keep), log) for n in ns]
    with tempfile.TemporaryDirectory() as folder:
        return [_logged(bench_scan(n, Path(folder)), log) for n in ns]


def _logged(row: ScanRow, log) -> ScanRow:
    log(f"  scan n = {row.n}: {row.scan_s:.1f} s, {row.failed} failed")
    return row


def markdown(solvers: list[SolverRow], sample_size: int, scans: list[ScanRow]) -> str:
    """The two tables as Markdown, each after a sentence saying what it holds."""
    lines = [
        f"Solvers on {sample_size} actuators (run side by side; errors against the fast path "
        f"at its tightest settings: no fold screen, flow tol {REFERENCE[1]:g}):",
        "",
        solver_table(solvers),
    ]
    if scans:
        lines += [
            "",
            "Full scans of the 36-segment library (`labrig model scan --n N`, all cores):",
            "",
            scan_table(scans),
        ]
    return "\n".join(lines) + "\n"


def solver_table(solvers: list[SolverRow]) -> str:
    """Time and error of each solver and setting; time relative to the fast path at its
    default settings."""
    fast = [r for r in solvers if r.solver == "fast"]
    unit = next((r for r in fast if r.parameter == DEFAULT_FAST), fast[0] if fast else None)
    lines = [
        "| solver | setting | ms per actuator | time / fast path | same transitions | "
        "max / mean abs error of v (mL) | max abs error of dE (snaps) |",
        "|---|---|---:|---:|---:|---:|---:|",
    ]
    for r in solvers:
        ratio = f"{r.seconds / unit.seconds:,.3g}" if unit else "–"
        failed = f" ({r.failed} failed)" if r.failed else ""
        lines.append(
            f"| {r.solver} | {r.setting} | {r.ms_per_actuator:,.2f} | {ratio} | "
            f"{r.matched}/{r.actuators}{failed} | {_num(r.v_error_max_ml)} / "
            f"{_num(r.v_error_mean_ml)} | {_num(r.dE_error_max)} |"
        )
    return "\n".join(lines)


def scan_table(scans: list[ScanRow]) -> str:
    """Size, time and memory of each full scan."""
    lines = [
        "| n | actuators | transitions | failed | scan (s) | actuators/s | workers | "
        "peak memory parent / worker (MiB) |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for s in scans:
        lines.append(
            f"| {s.n} | {s.actuators:,} | {s.transitions:,} | {s.failed} | "
            f"{s.scan_s:,.1f} | {s.actuators / s.scan_s:,.0f} | {s.workers} | "
            f"{s.parent_peak_mib:.0f} / {s.worker_peak_mib:.0f} |"
        )
    return "\n".join(lines)


def _num(x: float) -> str:
    if math.isnan(x):
        return "–"
    return "0" if x == 0 else f"{x:.2g}"
