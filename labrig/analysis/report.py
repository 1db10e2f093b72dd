"""The analysis as tables for a terminal (rich): what ``labrig show`` and ``labrig
compare`` print and what the runner prints after a run (``summary_text``).

Only presentation: every number comes from ``RunRecord`` / ``AnalysisResult``.
"""

from __future__ import annotations

import io
import math

from rich.console import Console, Group, RenderableType
from rich.table import Table

from labrig.analysis.curves import DEFLATE, INFLATE, PHASES
from labrig.analysis.results import AnalysisResult
from labrig.analysis.runfile import RunRecord
from labrig.protocol import plan

DIRECTION = {INFLATE: "inflate", DEFLATE: "deflate"}


def _num(value: float, fmt: str = ".2f", unit: str = "") -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "-"
    return f"{value:{fmt}}{unit}"


def run_table(record: RunRecord) -> Table:
    """Metadata and protocol of a run, as a two-column table."""
    protocol = record.protocol
    summary = plan(protocol)
    table = Table(title=f"{record.path}", show_header=False, title_justify="left")
    table.add_column(style="bold")
    table.add_column()
    status = record.status + (f" ({record.reason})" if record.reason else "")
    rows = [
        ("title", record.title),
        ("status", status),
        ("started", record.start_time or "-"),
        ("ended", record.end_time or "-"),
        ("protocol", f"{protocol.name}: {summary.repetitions} repetitions, "
         f"{summary.duration_s / 60:.1f} min, up to {summary.max_volume_ml:g} mL"),
        ("specimen", " + ".join(protocol.specimen.segments)
         + f" (fittings {protocol.specimen.fittings_length_mm:g} mm)"),
        ("limits", f"{protocol.limits.max_pressure_kpa:g} kPa, "
         f"{protocol.limits.max_volume_ml:g} mL"),
        ("acquisition", f"pressure {protocol.acquisition.pressure_rate_hz:g} Hz, camera "
         + (f"{protocol.acquisition.camera_fps:g} fps" if protocol.acquisition.camera_fps
            else "none")),
        ("analysis", f"mean of the last {protocol.analysis.average_last}, compare with the "
         f"model: {'yes' if protocol.analysis.compare_model else 'no'}"),
        ("zero offset", _num(record.zero_offset_kpa, ".3f", " kPa")),
        ("labrig", f"{record.versions.get('labrig', '?')} "
         f"(commit {record.versions.get('git_commit', '?')[:12]})"),
    ]  # fmt: skip
    for name, value in rows:
        table.add_row(name, value)
    return table


def steps_table(record: RunRecord) -> Table:
    """The protocol's steps, repeats unrolled once (``times`` shown)."""
    table = Table(title="protocol steps", title_justify="left")
    for name in ("#", "step", "parameters"):
        table.add_column(name)
    for index, step in enumerate(record.protocol.steps):
        kind, params = next(iter(step.model_dump().items()))
        if kind == "repeat":
            inner = "; ".join(
                f"{next(iter(s))} {_params(next(iter(s.values())))}" for s in params["steps"]
            )
            table.add_row(str(index), f"repeat x{params['times']}", inner)
        else:
            table.add_row(str(index), kind, _params(params))
    return table


def _params(params: dict) -> str:
    return ", ".join(f"{key} {value:g}" for key, value in params.items())


def repetitions_table(result: AnalysisResult) -> Table:
    table = Table(title="repetitions", title_justify="left")
    columns = ["#", "status", "mean", "time (s)", "samples", "v max (mL)", "p max (kPa)"]
    if result.with_length:
        columns.append("l (mm)")
    columns.append("transitions (mL)")
    for name in columns:
        table.add_column(name, justify="right" if name not in ("status",) else "left")
    for rep in result.repetitions:
        status = rep.status + (f": {rep.reason}" if rep.reason else "")
        samples = f"{rep.n_pressure}" + (
            f" ({rep.n_out_of_range} out of range)" if rep.n_out_of_range else ""
        )
        row = [
            str(rep.index),
            status,
            "yes" if rep.used_in_mean else "",
            _num(rep.duration_s, ".1f"),
            samples,
            _num(rep.v_max_ml),
            _num(rep.p_max_kpa),
        ]
        if result.with_length:
            row.append(f"{_num(rep.l_min_mm, '.1f')} to {_num(rep.l_max_mm, '.1f')}")
        row.append(
            ", ".join(f"{'+' if t.direction > 0 else '-'}{t.v_ml:.2f}" for t in rep.transitions)
            or "-"
        )
        table.add_row(*row)
    return table


def transitions_table(result: AnalysisResult) -> Table:
    reps = ", ".join(str(i) for i in result.averaged) or "none"
    table = Table(title=f"transitions in the averaged repetitions ({reps})", title_justify="left")
    for name in ("phase", "v (mL)", "spread (mL)", "dp (kPa)", "dl (mm)", "seen in"):
        table.add_column(name, justify="right")
    for t in result.transitions:
        table.add_row(
            DIRECTION[t.direction],
            _num(t.v_ml),
            _num(t.v_std_ml),
            _num(t.dp_kpa, "+.2f"),
            _num(t.dl_mm, "+.2f"),
            f"{t.seen} of {t.of}",
        )
    if not result.transitions:
        table.add_row("none", "", "", "", "", "")
    return table


def comparison_tables(result: AnalysisResult) -> list[RenderableType]:
    comparison = result.comparison
    if comparison is None:
        return []
    prediction = comparison.prediction
    fit = Table(
        title=f"model: {' + '.join(prediction.segments)} (RMSE against the mean)",
        title_justify="left",
    )
    for name in ("phase", "pressure (kPa)", "length (mm)"):
        fit.add_column(name, justify="right")
    for phase, name in PHASES.items():
        fit.add_row(
            name,
            _num(comparison.rmse_p_kpa[phase], ".3f"),
            _num(comparison.rmse_l_mm[phase], ".3f"),
        )
    table = Table(title="transitions: predicted against measured", title_justify="left")
    columns = ("phase", "type", "v model", "v meas.", "dv", "dp model", "dp meas.",
               "dl model", "dl meas.")  # fmt: skip
    for name in columns:
        table.add_column(name, justify="right")
    for match in comparison.matches:
        p, m = match.predicted, match.measured
        table.add_row(
            DIRECTION[match.direction],
            p.type if p is not None else "not predicted",
            _num(p.v_ml) if p else "-",
            _num(m.v_ml) if m else ("-" if p is None or p.stable else "not seen"),
            _num(match.dv_ml, "+.2f"),
            _num(p.dp_kpa, "+.2f") if p else "-",
            _num(m.dp_kpa, "+.2f") if m else "-",
            _num(p.dl_mm, "+.2f") if p else "-",
            _num(m.dl_mm, "+.2f") if m else "-",
        )
    if not comparison.matches:
        table.add_row("none", "", "", "", "", "", "", "", "")
    return [fit, table]


def notes(result: AnalysisResult) -> list[str]:
    return [f"note: {note}" for note in result.notes]


def analysis_renderables(result: AnalysisResult) -> list[RenderableType]:
    """Repetitions, transitions, comparison and notes of an analysis."""
    return [
        repetitions_table(result),
        transitions_table(result),
        *comparison_tables(result),
        *notes(result),
    ]


def summary_text(result: AnalysisResult, width: int = 110) -> str:
    """The analysis as plain text (tables drawn with characters), for the runner's
    terminal summary or a log."""
    buffer = io.StringIO()
    console = Console(file=buffer, width=width, color_system=None, force_terminal=False)
    console.print(Group(*analysis_renderables(result)))
    return buffer.getvalue()
