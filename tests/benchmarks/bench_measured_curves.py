"""Benchmark: measured curves from anywhere. B42-T24 + B50-T22 (two snaps in the
library) written as CSV tables at several row counts, quantisation steps and
noise levels, read back through ``load_csv`` and run through the path: prints the import
time (CSV parse + resolution + tabulate or fit, both curves), the path time, the route,
the number of snaps and the snap-volume error against the clean curves (the worst snap
of a table; the mean and the worst over noise seeds). Then random synthetic
rise-fall-rise pairs, noisy (0.1 or 0.3 kPa, rows dense enough to average it out, raw,
10-bit-like or 14-bit-like steps): how many give the clean curves' snaps, how many a
spurious one, how many miss one.
Asserts nothing.

Run: python tests/benchmarks/bench_measured_curves.py [--write-docs]
"""

import argparse
import contextlib
import sys
import tempfile
import time
from pathlib import Path
from unittest import mock

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from support.measured_tables import (
    ADC_STEP_KPA,
    dip_hidden_by_step,
    noisy_synthetic_pair,
    sample_table,
    snap_details,
    snap_volumes,
    unresolved_fold_pair,
    write_table,
)

from labrig.cli.performance_doc import add_write_docs_argument, markdown_table, script_doc
from labrig.model.actuator.equilibria import Actuator
from labrig.model.actuator.path import quasi_static_path
from labrig.model.actuator.transitions import table_resolution, transitions
from labrig.model.segments import measured
from labrig.model.segments.catalog import (
    BRAID_LENGTHS_MM,
    TUBE_LENGTHS_MM,
    analytical_segment,
)
from labrig.model.segments.measured import curve_from_table, load_csv

PAIR = ("B42-T24", "B50-T22")
SEEDS = (0, 10, 20)


def one(folder: Path, spacing_ml: float, round_to_kpa, noise_kpa: float, seed: int):
    paths = []
    for k, name in enumerate(PAIR):
        table = sample_table(
            analytical_segment(name),
            spacing_ml,
            round_to_kpa=round_to_kpa,
            noise_kpa=noise_kpa,
            seed=seed + k,
        )
        paths.append(write_table(table, folder / f"{name}-{seed}.csv"))
    started = time.perf_counter()
    curves = [load_csv(p) for p in paths]
    imported = time.perf_counter() - started
    started = time.perf_counter()
    path = quasi_static_path(Actuator(curves))
    snaps = [t.v_ml for t in transitions(path) if not t.stable]
    solved = time.perf_counter() - started
    route = "/".join(c.measured.route[0] for c in curves)
    rows = curves[1].measured.resolution.rows
    return rows, route, imported, solved, snaps


def row(folder, label, spacing_ml, round_to_kpa, noise_kpa, clean) -> tuple:
    """One table row: the rows and route of the B50 table, the mean import and path
    times, the counts of snaps found and the mean and worst snap-volume errors."""
    seeds = SEEDS if noise_kpa else SEEDS[:1]
    results = [one(folder, spacing_ml, round_to_kpa, noise_kpa, s) for s in seeds]
    # the worst of a table's snaps against the clean curves', where it found as many
    errors = [
        max(abs(a - b) for a, b in zip(r[4], clean, strict=True))
        for r in results
        if len(r[4]) == len(clean)
    ]
    counts = sorted({len(r[4]) for r in results})
    return (
        label,
        results[0][0],
        results[0][1],
        f"{np.mean([r[2] for r in results]) * 1e3:.0f}",
        f"{np.mean([r[3] for r in results]) * 1e3:.0f}",
        ",".join(map(str, counts)),
        f"{np.mean(errors):.3f}" if errors else "-",
        f"{max(errors):.3f}" if errors else "-",
    )


def table_rows() -> str:
    """The pair's tables at every resolution, step and noise level, as a table."""
    clean_curves = [analytical_segment(n) for n in PAIR]
    clean = [t.v_ml for t in transitions(quasi_static_path(Actuator(clean_curves))) if not t.stable]
    v_max = clean_curves[1].v_max_ml
    snaps = ", ".join(f"{v:.3f}" for v in clean)
    print(f"clean snaps at {snaps} mL; {len(SEEDS)} noise seeds per noisy row")
    rows = []
    with tempfile.TemporaryDirectory() as scratch:
        folder = Path(scratch)
        for n_rows in (40, 500, 2000, 8000, 50_000):
            label = f"{n_rows} rows, full precision"
            rows.append(row(folder, label, v_max / n_rows, None, 0.0, clean))
        for n_rows in (2000, 8000):
            label = f"{n_rows} rows, 5 decimals"
            rows.append(row(folder, label, v_max / n_rows, 1e-5, 0.0, clean))
        for step in (0.01, ADC_STEP_KPA, 0.1, 0.27, 0.5):
            label = f"8000 rows, step {step:.3g} kPa"
            rows.append(row(folder, label, v_max / 8000, step, 0.0, clean))
        rows.append(row(folder, "0.05 mL, step 0.27 kPa", 0.05, 0.27, 0.0, clean))
        for per_ml in (50, 1000):
            for noise in (0.05, 0.1, 0.2, 0.3, 0.5):
                step = ADC_STEP_KPA if per_ml == 1000 else None
                label = f"{per_ml}/mL, noise {noise} kPa" + (", 14-bit" if step else "")
                rows.append(row(folder, label, 1.0 / per_ml, step, noise, clean))
    header = (
        "table (B42-T24 + B50-T22)",
        "rows (B50)",
        "route",
        "import ms",
        "path ms",
        "snaps",
        "mean err mL",
        "max err mL",
    )
    return markdown_table(header, rows, right={1, 3, 4, 5, 6, 7})


def tabled(clean, spacing_ml, seed, **table) -> list:
    """Each clean curve sampled as a table (``sample_table``, segment k with seed + k)
    and read back as a measured curve."""
    return [
        curve_from_table(
            sample_table(c, spacing_ml, seed=seed + k, **table), name=c.name, where=c.name
        )
        for k, c in enumerate(clean)
    ]


def synthetic_rates(seeds=(1, 2, 3), cases=40) -> list[str]:
    counts = {"same": 0, "spurious": 0, "missed": 0}
    unresolved = 0  # clean fold pairs whose slope deficit the rows cannot resolve
    errors = []
    for seed in seeds:
        for case in range(cases):
            try:
                shapes, noise, spacing, rounding, table_seed = noisy_synthetic_pair(seed, case)
            except AssertionError:  # equal peaks: not drawn further
                continue
            curves = tabled(shapes, spacing, table_seed, round_to_kpa=rounding, noise_kpa=noise)
            # a clean fold pair whose slope deficit the measured rows do not resolve is
            # not a snap those tables can show (``transitions``): not counted as missed
            tables = table_resolution(Actuator(curves))
            details = [c for c in snap_details(shapes) if c[1] > 0.01]
            shown = [c for c in details if not unresolved_fold_pair(c, tables)]
            unresolved += len(details) - len(shown)
            clean = [c[0] for c in shown]
            got = snap_volumes(curves)
            got = [v for k, v in enumerate(got) if k == 0 or v - got[k - 1] > 1e-3]
            if len(got) > len(clean):
                counts["spurious"] += 1
            elif len(got) < len(clean):
                counts["missed"] += 1
            else:
                counts["same"] += 1
                errors += [abs(a - b) for a, b in zip(clean, got, strict=True)]
    total = sum(counts.values())
    return [
        f"noisy synthetic pairs: {total}; clean snaps {counts['same']}, spurious snap "
        f"{counts['spurious']}, a snap missed {counts['missed']} (clean fold pairs below "
        f"the rows' slope resolution, not counted: {unresolved}); snap volume error rms "
        f"{np.sqrt(np.mean(np.square(errors))):.3f} mL, max {max(errors):.3f} mL"
    ]


def staircases() -> list[str]:
    """Undithered staircases coarser than 0.2 kPa every 0.1 mL (uniform rows and rows
    jittered by +-45 %), on the SI's pairs where they are worst (dips of a few kPa; the
    calibrated segments' dips of 20-60 kPa are far above any step): the snap-volume
    error against the clean curves, with the peak and valley from the stair edges and,
    for comparison, with the stair values (the edge estimate switched off)."""
    lines = []
    for names, step in (
        (("SI-B46-T20", "SI-B42-T20"), 0.27),
        (("SI-B46-T22", "SI-B48-T20"), 0.5),
    ):
        clean = [analytical_segment(n) for n in names]
        (want,) = snap_volumes(clean)
        for uniform in (True, False):
            results = []
            for edges in (True, False):
                with contextlib.ExitStack() as stack:
                    if not edges:
                        stack.enter_context(
                            mock.patch.object(measured, "refine_extrema", lambda *_: None)
                        )
                    curves = [
                        curve_from_table(
                            sample_table(c, 0.1, uniform=uniform, round_to_kpa=step, seed=k),
                            name=c.name,
                            where=c.name,
                        )
                        for k, c in enumerate(clean)
                    ]
                    got = snap_volumes(curves)
                error = max(abs(v - want) for v in got) if len(got) == 1 else float("nan")
                route = "/".join(c.measured.route[0] for c in curves)
                results.append(f"route {route}, {len(got)} snap(s), error {error:.2f} mL")
            lines.append(
                f"{' + '.join(names)}, step {step} kPa every 0.1 mL, "
                f"{'uniform' if uniform else 'jittered'}: stair edges {results[0]}; "
                f"stair values {results[1]}"
            )
    return lines


def staircase_sweep(draws: int = 200, seed: int = 12345) -> list[str]:
    """Random library pairs and triples (braids distinct) as undithered staircases: a
    step of 0.27 or 0.5 kPa, and one uniform in 0.27-0.5 kPa (off any decimal), rows
    every 0.05-0.5 mL (log-uniform), uniform or jittered. Per step draw: how many give
    the clean snaps (none spurious, none missed but a jump within the step or a fold
    pair the rows do not resolve) within max(0.5 mL, 2 x the widest gap); the
    draws with a dip shallower than the step (``dip_hidden_by_step``: no table of that
    step holds it) are counted apart, as are their misses; the worst error of the rest."""
    lines = []
    for label, steps in (("0.27/0.5 kPa", None), ("0.27-0.5 kPa", (0.27, 0.5))):
        rng = np.random.default_rng(seed)
        within, hidden, hidden_within, worst, misses = 0, 0, 0, 0.0, []
        for _ in range(draws):
            n = int(rng.integers(2, 4))
            braids = rng.choice(BRAID_LENGTHS_MM, n, replace=False)
            tubes = rng.choice(TUBE_LENGTHS_MM, n)
            names = [f"SI-B{b}-T{t}" for b, t in zip(braids, tubes, strict=True)]
            step = float(rng.uniform(*steps) if steps else rng.choice([0.27, 0.5]))
            spacing = float(10 ** rng.uniform(np.log10(0.05), np.log10(0.5)))
            uniform = bool(rng.integers(0, 2))
            table_seed = int(rng.integers(0, 1000))
            clean = [analytical_segment(name) for name in names]
            curves = tabled(clean, spacing, table_seed, uniform=uniform, round_to_kpa=step)
            tables = table_resolution(Actuator(curves))
            unmatched = list(snap_details(clean))
            got = snap_volumes(curves)
            got = [v for k, v in enumerate(got) if k == 0 or v - got[k - 1] > 1e-3]
            widest = max(c.measured.resolution.spacing_max_ml for c in curves)
            error, spurious = 0.0, False
            for v in got:
                nearest = min(unmatched, key=lambda c, v=v: abs(c[0] - v), default=None)
                if nearest is None:
                    spurious = True
                    continue
                error = max(error, abs(nearest[0] - v))
                unmatched.remove(nearest)
            missed = any(
                c[1] > max(step, 0.01) and not unresolved_fold_pair(c, tables) for c in unmatched
            )
            good = not spurious and not missed and error <= max(0.5, 2 * widest)
            if dip_hidden_by_step(clean, step):
                hidden += 1
                hidden_within += good
                continue
            within += good
            worst = max(worst, error)
            if not good:
                what = "spurious snap" if spurious else "missed snap" if missed else "off"
                misses.append(
                    f"{'+'.join(names)} every {spacing:.3f} mL "
                    f"{'uniform' if uniform else 'jittered'}, step {step:.3g} kPa, "
                    f"seed {table_seed}: {what} (error {error:.2f} mL)"
                )
        lines.append(
            f"staircases at {label}, {draws} random library draws: {within} of "
            f"{draws - hidden} within max(0.5 mL, 2 x the widest gap), worst snap-volume error "
            f"{worst:.2f} mL; "
            f"{hidden} with a dip under the step counted apart ({hidden_within} of them "
            "within it all the same)"
        )
        lines += [f"beyond it: {miss}" for miss in misses]
    return lines


def steps_written_with_decimals() -> list[str]:
    """The quantisation step read from B50-T22 at 8,000 rows on a lattice written with
    few decimals (as another tool writes it): the lattice's step is the answer."""
    curve = analytical_segment("B50-T22")
    v = np.linspace(0.0, curve.v_max_ml, 8000)
    lines = []
    for step, decimals in ((0.5, 1), (0.27, 2), (ADC_STEP_KPA, 2), (ADC_STEP_KPA, 3)):
        p = np.round(curve.pressure_kpa(v) / step) * step
        written = np.array([float(f"{x:.{decimals}f}") for x in p])
        table = np.column_stack([v, written, curve.length_mm(v)])
        read = curve_from_table(table, name="q", where="q").measured.resolution.step_kpa
        lines.append(f"step {step:.4g} kPa written with {decimals} decimals: read {read:.4g} kPa")
    return lines


def noisiest_triple() -> list[str]:
    """The SI's B40-T20 + B42-T26 + B44-T20 at 1,000 rows/mL, 0.5 kPa noise on a 0.27
    kPa step (SI-B42-T26's dip is 0.6 kPa, under three steps): snap-volume error over
    seeds."""
    names = ("SI-B40-T20", "SI-B42-T26", "SI-B44-T20")
    clean = [analytical_segment(n) for n in names]
    (want,) = snap_volumes(clean)
    errors = []
    for seed in (0, 1, 2):
        curves = [
            curve_from_table(
                sample_table(c, 0.001, round_to_kpa=0.27, noise_kpa=0.5, seed=seed + k),
                name=c.name,
                where=c.name,
            )
            for k, c in enumerate(clean)
        ]
        got = snap_volumes(curves)
        errors.append(max(abs(v - want) for v in got) if len(got) == 1 else float("nan"))
    return [
        f"{' + '.join(names)}, 1000/mL, noise 0.5 kPa, step 0.27 kPa: snap errors "
        + ", ".join(f"{e:.2f}" for e in errors)
        + " mL"
    ]


def main() -> None:
    parser = argparse.ArgumentParser()
    add_write_docs_argument(parser)
    doc = script_doc(["measured-curves", "measured-curves-snaps"], parser.parse_args().write_docs)
    doc.publish("measured-curves", table_rows())
    lines = [
        *synthetic_rates(),
        *staircases(),
        *staircase_sweep(),
        *steps_written_with_decimals(),
        *noisiest_triple(),
    ]
    doc.publish("measured-curves-snaps", "\n".join(f"- {line}" for line in lines))


if __name__ == "__main__":
    main()
