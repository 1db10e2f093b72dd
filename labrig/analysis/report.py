"""The analysis as tables for a terminal (rich): what ``labrig show`` and ``labrig
compare`` print and what the runner prints after a run (``summary_text``).

Only presentation: every number comes from ``RunRecord`` / ``AnalysisResult``.
"""

from __future__ import annotations

import io
import math

from rich import box
from rich.console import Console, Group, RenderableType
from rich.table import Table
from rich.text import Text

from labrig.analysis.curves import DEFLATE, INFLATE, PHASES
from labrig.analysis.energy import cycle_energy, finite_or_none, transition_energy
from labrig.analysis.results import AnalysisResult
from labrig.analysis.runfile import RunRecord
from labrig.config.protocol import plan
from labrig.vocabulary import ALIASES, beside_fields

DIRECTION = {INFLATE: "inflate", DEFLATE: "deflate"}


class _Titled(Table):
    """A table whose title is a line of its own above it: rich wraps a table's title to
    the table's width, which cuts the units in a title in two."""

    def __init__(self, heading: str, **kwargs) -> None:
        super().__init__(**kwargs)
        self.heading = heading

    def __rich_console__(self, console, options):
        yield Text(f"\n{self.heading}", style="bold")
        yield from super().__rich_console__(console, options)


def _table(title: str, columns, right: tuple[str, ...] = (), wrap: tuple[str, ...] = ()) -> Table:
    """A compact table (no vertical rules, so it stays legible in 80 columns and logs);
    the ``wrap`` columns take the lines a narrow terminal needs, the others keep their
    width."""
    table = _Titled(
        title, box=box.SIMPLE_HEAD, pad_edge=False, collapse_padding=True, show_edge=False
    )
    for name in columns:
        table.add_column(
            name, justify="right" if name in right else "left", no_wrap=name not in wrap
        )
    return table


def _num(value: float, fmt: str = ".2f", unit: str = "") -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "-"
    return f"{value:{fmt}}{unit}"


def run_table(record: RunRecord) -> Table:
    """Metadata and protocol of a run, as a two-column table."""
    protocol = record.protocol
    summary = plan(protocol)
    table = Table(title=f"{record.path}", show_header=False, title_justify="left", box=box.SIMPLE)
    table.add_column(style="bold", no_wrap=True)
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
         + f" (fittings {protocol.specimen.fittings_length_mm:g} mm"
         + ("" if protocol.specimen.has_model else "; labels, no model") + ")"),
        ("limits", f"{protocol.limits.max_pressure_kpa:g} kPa, "
         f"{protocol.limits.max_volume_ml:g} mL"),
        ("acquisition", f"pressure {protocol.acquisition.pressure_rate_hz:g} Hz, camera "
         + (f"{protocol.acquisition.camera_fps:g} fps" if protocol.acquisition.camera_fps
            else "none") + (", video" if protocol.acquisition.video else "")),
        ("analysis", f"mean of the last {protocol.analysis.average_last}, compare with the "
         f"model: {_compared(protocol)}"),
        ("zero offset", _num(record.zero_offset_kpa, ".3f", " kPa")),
        ("labrig", f"{record.versions.get('labrig', '?')} "
         f"(commit {record.versions.get('git_commit', '?')[:12]})"),
    ]  # fmt: skip
    for name, value in rows:
        table.add_row(name, value)
    return table


def _compared(protocol) -> str:
    if not protocol.specimen.has_model:
        return "no (the specimen has no model: specimen.model: none)"
    return "yes" if protocol.analysis.compare_model else "no"


def steps_table(record: RunRecord) -> Table:
    """The protocol's steps, repeats unrolled once (``times`` shown)."""
    table = _table("protocol steps", ("#", "step", "parameters"))
    table.columns[2].no_wrap = False
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
    columns = ["#", "status", "mean", "time", "samples", "v max", "p max"]
    if result.with_length:
        columns.append("l min-max")
    columns.append("transitions")
    units = "time s, v mL, p kPa" + (", l mm" if result.with_length else "")
    title = f"repetitions ({units}; transitions +in/-out at v, seen in p, l)"
    table = _table(title, columns, right=columns[3:7], wrap=("transitions",))
    for rep in result.repetitions:
        row = [
            str(rep.index),
            rep.status,
            "yes" if rep.used_in_mean else "",
            _num(rep.duration_s, ".1f"),
            str(rep.n_pressure),
            _num(rep.v_max_ml),
            _num(rep.p_max_kpa),
        ]
        if result.with_length:
            row.append(f"{_num(rep.l_min_mm, '.1f')}-{_num(rep.l_max_mm, '.1f')}")
        row.append(
            " ".join(
                f"{'+' if t.direction > 0 else '-'}{t.v_ml:.2f}({t.kind})" for t in rep.transitions
            )
            or "-"
        )
        table.add_row(*row)
    return table


def repetition_reasons(result: AnalysisResult) -> list[str]:
    """Why repetitions ended as they did, and pressure samples beyond the range."""
    lines = [
        f"repetition {rep.index} {rep.status}: {rep.reason}"
        for rep in result.repetitions
        if rep.reason
    ]
    lines += [
        f"repetition {rep.index}: {rep.n_out_of_range} pressure samples beyond the sensor's "
        "range (left out)"
        for rep in result.repetitions
        if rep.n_out_of_range
    ]
    return lines


def transitions_table(result: AnalysisResult) -> RenderableType:
    reps = ", ".join(str(i) for i in result.averaged) or "none"
    title = f"transitions in the averaged repetitions ({reps})"
    if not result.transitions:
        return f"{title}: none found"
    columns = ("phase", "v", "spread", "dp", "dl", "seen in")
    table = _table(f"{title} (v mL, dp kPa, dl mm)", columns, right=columns[1:5])
    for t in result.transitions:
        table.add_row(
            DIRECTION[t.direction],
            _num(t.v_ml),
            _num(t.v_std_ml),
            _num(t.dp_kpa, "+.2f"),
            _num(t.dl_mm, "+.2f"),
            f"{t.seen} of {t.of}",
        )
    return table


def rmse_table(result: AnalysisResult) -> RenderableType | None:
    comparison = result.comparison
    if comparison is None:
        return None
    segments = " + ".join(comparison.prediction.segments)
    columns = ("phase", "pressure (kPa)", "length (mm)")
    table = _table(f"RMSE of the mean against the model ({segments})", columns, columns[1:])
    for phase, name in PHASES.items():
        table.add_row(
            name,
            _num(comparison.rmse_p_kpa[phase], ".3f"),
            _num(comparison.rmse_l_mm[phase], ".3f"),
        )
    return table


def matches_table(result: AnalysisResult) -> RenderableType | None:
    comparison = result.comparison
    if comparison is None:
        return None
    title = "transitions: predicted against measured"
    if not comparison.paper_matches:
        return f"{title}: none predicted, none measured"
    columns = ("phase", "type", "v", "v meas", "dv", "dp", "dp meas", "dl", "dl meas")
    table = _table(
        f"{title} (as the paper counts them: the events at one supplied volume are one; "
        "v mL, dp kPa, dl mm)",
        columns,
        right=columns[2:],
    )
    for match in comparison.paper_matches:
        p, m = match.predicted, match.measured
        smooth = p is not None and p.stable
        if p is not None:
            kind = p.type
        else:
            kind = "on the curve" if result.on_the_models_curve(m) else "not predicted"
        table.add_row(
            DIRECTION[match.direction],
            kind,
            _num(p.v_ml) if p else "-",
            _num(m.v_ml) if m else ("-" if smooth else "not seen"),
            _num(match.dv_ml, "+.2f"),
            "-" if smooth or p is None else _num(p.dp_kpa, "+.2f"),
            _num(m.dp_kpa, "+.2f") if m else "-",
            "-" if smooth or p is None else _num(p.dl_mm, "+.2f"),
            _num(m.dl_mm, "+.2f") if m else "-",
        )
    return table


def comparison_json(result: AnalysisResult) -> dict:
    """The comparison as one JSON-ready object (``labrig compare --json``): the RMSE per
    phase and quantity, and each predicted transition with the measured one paired to
    it (null where none was): under ``transitions`` the path's events (every peak
    crossing and every snap), under ``paper_transitions`` the transitions as the paper
    counts them (the events at one supplied volume are one); measured transitions
    that none of those predicts are listed under ``unpredicted``. Each predicted
    transition carries its energies (``labrig.analysis.energy.transition_energy``) and
    ``energy`` the cycle's (``cycle_energy``), in mJ. Each row's names are followed by
    their names in ``labrig.vocabulary`` (``direction`` after ``phase``, ...)."""
    comparison = result.comparison
    rmse = {}
    for phase, name in PHASES.items():
        rmse[f"{name}_pressure_kpa"] = finite_or_none(comparison.rmse_p_kpa[phase])
        rmse[f"{name}_length_mm"] = finite_or_none(comparison.rmse_l_mm[phase])
    transitions, _ = _matched(comparison.matches, result)
    paper, unpredicted = _matched(comparison.paper_matches, result)
    return {
        "rmse": rmse,
        "transitions": transitions,
        "paper_transitions": paper,
        "unpredicted": unpredicted,
        "energy": cycle_energy(result),
    }


def no_model_json(reason: str) -> dict:
    """``labrig compare --json`` for a run with nothing to compare with (a specimen with
    no model): ``no_model``, the reason, before the comparison's fields, empty (every
    RMSE null), so a script reads it as it reads any comparison."""
    rmse = {
        f"{name}_{quantity}": None
        for name in PHASES.values()
        for quantity in ("pressure_kpa", "length_mm")
    }
    return {
        "no_model": reason,
        "rmse": rmse,
        "transitions": [],
        "paper_transitions": [],
        "unpredicted": [],
    }


def _matched(matches, result: AnalysisResult) -> tuple[list[dict], list[dict]]:
    """The JSON rows of ``matches``: (predicted transitions with their measured pair,
    measured transitions alone)."""
    transitions, unpredicted = [], []
    for match in matches:
        p, m = match.predicted, match.measured
        if p is None:
            unpredicted.append(
                beside_fields(
                    {
                        "phase": DIRECTION[match.direction],
                        "v_meas_ml": finite_or_none(m.v_ml),
                        "dp_meas_kpa": finite_or_none(m.dp_kpa),
                        "dl_meas_mm": finite_or_none(m.dl_mm),
                        "on_model_curve": result.on_the_models_curve(m),
                    },
                    ALIASES["comparison"],
                )
            )
            continue
        row = {
            "phase": DIRECTION[match.direction],
            "type": "stable" if p.stable else "snap",
            "alpha": p.alpha,
            "beta": p.beta,
            "v_ml": finite_or_none(p.v_ml),
            "v_meas_ml": finite_or_none(m.v_ml) if m else None,
            "dp_kpa": finite_or_none(p.dp_kpa),
            "dp_meas_kpa": finite_or_none(m.dp_kpa) if m else None,
            "dl_mm": finite_or_none(p.dl_mm),
            "dl_meas_mm": finite_or_none(m.dl_mm) if m else None,
            **transition_energy(result, p, m),
        }
        transitions.append(beside_fields(row, ALIASES["comparison"]))
    return transitions, unpredicted


def comparison_tables(result: AnalysisResult) -> list[RenderableType]:
    return [t for t in (rmse_table(result), matches_table(result)) if t is not None]


def notes(result: AnalysisResult) -> list[str]:
    return [f"note: {note}" for note in result.notes]


def analysis_renderables(result: AnalysisResult) -> list[RenderableType]:
    """Repetitions, transitions, comparison and notes of an analysis."""
    return [
        repetitions_table(result),
        *repetition_reasons(result),
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
