"""``labrig bench``: benchmarks that print numbers (never asserted in timed tests).

A group open to other benches: each adds one line to ``BENCH_COMMANDS``.
"""

from __future__ import annotations

import platform
from pathlib import Path

import click

from labrig.cli import LazyGroup

# name -> ("module", "attribute"), imported on first use.
BENCH_COMMANDS: dict[str, tuple[str, str]] = {
    "model": ("labrig.cli.benchmark", "model_bench"),
}


@click.group(cls=LazyGroup, lazy_commands=BENCH_COMMANDS)
def bench() -> None:
    """Measure labrig's speed and accuracy on this machine."""


@click.command("model")
@click.option("--quick", is_flag=True, help="CI-sized: two pairs, coarse settings, n = 2 scan.")
@click.option(
    "--scans",
    default=None,
    help="Comma-separated n of the full scans to time (default 2,3; 2,3,4 takes minutes; "
    "'' for none).",
)
@click.option(
    "--out",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Also write the tables as Markdown to this file.",
)
@click.option(
    "--write-docs",
    is_flag=True,
    help="Also replace the solver table (and, with scans, the scan table) in the "
    "repository's docs/performance.md, dated.",
)
@click.option(
    "--keep-scans",
    type=click.Path(file_okay=False, path_type=Path),
    help="Keep the scan files (scan_n<N>.h5) in this existing folder.",
)
def model_bench(
    quick: bool, scans: str | None, out: Path | None, write_docs: bool, keep_scans: Path | None
) -> None:
    """Run time against error for each model solver and resolution (the fast path, the
    paper's Nelder-Mead algorithm, the pressure-grid equilibria) on a fixed sample of
    pairs and triples, then the time and memory of full scans."""
    from dataclasses import replace

    from labrig.cli.performance_doc import PerformanceDoc, machine
    from labrig.errors import InputError
    from labrig.model.benchmark import (
        BenchSettings,
        bench_scans,
        bench_solvers,
        markdown,
        scan_table,
        solver_table,
    )

    settings = BenchSettings.quick() if quick else BenchSettings()
    if scans is not None:
        try:
            ns = tuple(int(x) for x in scans.split(",") if x.strip())
        except ValueError:
            raise InputError(f"--scans {scans!r}: comma-separated integers, e.g. 2,3,4") from None
        if any(not 2 <= n <= 6 for n in ns):
            raise InputError(f"--scans {scans!r}: each n must be 2..6")
        settings = replace(settings, scan_ns=ns)
    if out is not None and not out.parent.is_dir():
        raise InputError(f"--out {out}: the folder {out.parent} does not exist")
    if keep_scans is not None:
        if not keep_scans.is_dir():
            raise InputError(f"--keep-scans {keep_scans}: no such folder")
        taken = [keep_scans / f"scan_n{n}.h5" for n in settings.scan_ns]
        if any(f.exists() for f in taken):
            raise InputError(f"--keep-scans {keep_scans}: it holds scan_n<N>.h5 files already")
    sections = ["model-solvers", "model-scans"] if settings.scan_ns else ["model-solvers"]
    doc = PerformanceDoc(sections, write_docs)

    def log(line: str) -> None:
        click.echo(line, err=True)

    log(f"labrig bench model ({machine()}, Python {platform.python_version()}): solvers")
    solvers, sample_size = bench_solvers(settings, log=log)
    if settings.scan_ns:
        log("full scans")
    scan_rows = bench_scans(settings.scan_ns, log=log, keep=keep_scans)
    text = markdown(solvers, sample_size, scan_rows)
    click.echo(text)
    if out is not None:
        out.write_text(text, encoding="utf-8")
        log(f"written: {out}")
    doc.write_section("model-solvers", solver_table(solvers))
    if scan_rows:
        doc.write_section("model-scans", scan_table(scan_rows))
