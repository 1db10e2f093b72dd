"""Benchmark: build time of the 36 analytical library segments (the default library's,
then three paper-numbers libraries and the SI's), and of loading a raw measured curve
(1 kHz samples at 60 mL/min). Prints numbers; asserts nothing.

Run: python tests/benchmarks/bench_segments.py [--write-docs]
"""

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from labrig.cli.performance_doc import add_write_docs_argument, markdown_table, script_doc


def main() -> None:
    parser = argparse.ArgumentParser()
    add_write_docs_argument(parser)
    doc = script_doc(["segments"], parser.parse_args().write_docs)
    t0 = time.perf_counter()
    from labrig.model.segments import catalog

    t_import = time.perf_counter() - t0
    t0 = time.perf_counter()
    curves = [catalog.analytical_segment(name) for name in catalog.LIBRARY_NAMES]
    t_cold = time.perf_counter() - t0
    t0 = time.perf_counter()
    for name in catalog.LIBRARY_NAMES:
        catalog.analytical_segment(name)
    t_cached = time.perf_counter() - t0
    samples = [len(c.v_ml) for c in curves]
    others = []
    for library in (catalog.PAPER, catalog.PAPER_RADIUS, catalog.PAPER_CLAMPED, catalog.SI):
        t0 = time.perf_counter()
        built = [catalog.analytical_segment(name) for name in catalog.library_names(library)]
        sizes = [len(c.v_ml) for c in built]
        others.append(
            (
                f"build the 36 of `{library}:` (cold)",
                f"{(time.perf_counter() - t0) * 1e3:.1f}",
                f"{min(sizes)}-{max(sizes)} samples per table",
            )
        )

    from labrig.model.segments.measured import load_csv

    clean = catalog.analytical_segment("B46-T20")
    rng = np.random.default_rng(0)
    v = np.arange(0, 21.1, 0.001)
    p = np.round((1.02 * clean.pressure_kpa(v) + 0.8 + rng.normal(0, 0.3, len(v))) / 0.3) * 0.3
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "raw.csv"
        with path.open("w") as fh:
            fh.write("volume_ml,pressure_kpa,length_mm\n")
            np.savetxt(fh, np.column_stack([v, p, clean.length_mm(v)]), delimiter=",", fmt="%.5f")
        t0 = time.perf_counter()
        curve = load_csv(path)
        t_load = time.perf_counter() - t0
    rows = [
        ("import labrig.model.segments.catalog", f"{t_import * 1e3:.1f}", ""),
        (
            f"build all {len(curves)} analytical segments of the default library "
            f"`{catalog.DEFAULT_LIBRARY}:` (cold)",
            f"{t_cold * 1e3:.1f}",
            f"{min(samples)}-{max(samples)} samples per table",
        ),
        ("the same again (cached)", f"{t_cached * 1e3:.3f}", ""),
        *others,
        (
            f"load + fit a raw CSV of {len(v):,} rows (1 kHz at 60 mL/min)",
            f"{t_load * 1e3:.1f}",
            f"{len(curve.v_ml)} samples",
        ),
    ]
    doc.publish("segments", markdown_table(("step", "ms", "table"), rows, right={1}))


if __name__ == "__main__":
    main()
