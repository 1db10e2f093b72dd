"""What a scan found: counts and ranges per transition type, the designs with the
largest snap, and the paper's Fig. 4 A-C for the scan.

Transitions are counted as the paper counts them: the scan file's rows are the path's
fine-grained events, and the events at one supplied volume are one transition
(``labrig.model.actuator.paper_counting``). A transition's type is (alpha, beta) —
segments right of their pressure peak before and after — with its stability (unstable
if it holds a snap at constant volume) and its direction; the paper's Fig. 4 colours
(0, 1) blue, (1, 1) red and (1, 2) green. This module works on ``ScanData`` arrays and
leaves files and terminals to others.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from labrig.model.actuator.paper_counting import group_paper_transitions
from labrig.model.scan.scan_file import BLOCK_ROWS, ScanData

METRICS = ("dE", "dv", "dl", "dp")
# the paper's colours for its three n = 2 types; anything else gets its own
PAPER_COLOURS = {(0, 1): "tab:blue", (1, 1): "tab:red", (1, 2): "tab:green"}
OTHER_COLOURS = ("tab:orange", "tab:purple", "tab:brown", "tab:pink", "tab:olive", "tab:cyan")


@dataclass(frozen=True)
class TypeSummary:
    direction: int
    alpha: int
    beta: int
    stable: bool
    count: int
    actuators: int  # how many actuators have at least one transition of this type
    ranges: dict[str, tuple[float, float]]  # metric -> (min, max)


@dataclass(frozen=True)
class ScanSummary:
    actuators_done: int
    actuators_total: int
    failed: int
    transitions: int  # as the paper counts them
    events: int  # the scan file's rows: the paths' fine-grained events
    actuators_with_snap: int
    types: list[TypeSummary]
    ranges: dict[str, tuple[float, float]]  # over every transition


def paper_columns(data: ScanData) -> dict[str, np.ndarray]:
    """The scan's transitions as the paper counts them, as columns (with ``actuator``
    and ``first``, the row of each one's first event)."""
    return group_paper_transitions(data.columns, data.actuator)


def paper_blocks(data: ScanData, block_rows: int = BLOCK_ROWS):
    """``paper_columns`` block by block (memory bounded by the block): the rows of the
    last actuator of a block wait for the next block, so every actuator's transitions
    come whole in one block."""
    held: dict[str, np.ndarray] | None = None
    start = 0
    for actuator, c in data.row_blocks(block_rows):
        rows = {"actuator": actuator, "row": np.arange(start, start + len(actuator)), **c}
        start += len(actuator)
        if held is not None:
            rows = {name: np.concatenate([held[name], rows[name]]) for name in rows}
        whole = rows["actuator"] != rows["actuator"][-1]
        held = {name: values[~whole] for name, values in rows.items()}
        if whole.any():
            yield _grouped({name: values[whole] for name, values in rows.items()})
    if held is not None and len(held["actuator"]):
        yield _grouped(held)


def _grouped(rows: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The transitions of whole actuators' rows, ``first`` numbered in the file."""
    grouped = group_paper_transitions(rows, rows["actuator"])
    grouped["first"] = rows["row"][grouped["first"]]
    return grouped


def summarise(data: ScanData, block_rows: int = BLOCK_ROWS) -> ScanSummary:
    """Counts and ranges per transition type, as the paper counts transitions, read
    block by block (memory bounded by the block, not by the scan). Rows are sorted by
    actuator, so an actuator is counted once per type even when its rows straddle two
    blocks."""
    types: dict[tuple, _TypeTally] = {}
    overall = {m: (math.inf, -math.inf) for m in METRICS}
    snapping = _ActuatorTally()
    transitions = events = 0
    for c in paper_blocks(data, block_rows):
        actuator = c["actuator"]
        transitions += len(actuator)
        events += int(c["events"].sum())
        for m in METRICS:
            overall[m] = _merge(overall[m], c[m])
        snapping.add(actuator[~c["stable"]])
        code = (
            (c["direction"].astype(np.int64) + 1) * 1_000_000
            + c["alpha"].astype(np.int64) * 1_000
            + c["beta"].astype(np.int64) * 2
            + ~c["stable"]
        )
        for value in np.unique(code):
            rows = code == value
            first = int(np.flatnonzero(rows)[0])
            key = (
                -int(c["direction"][first]),
                int(c["alpha"][first]),
                int(c["beta"][first]),
                not bool(c["stable"][first]),
            )
            tally = types.setdefault(key, _TypeTally())
            tally.count += int(rows.sum())
            tally.actuators.add(actuator[rows])
            for m in METRICS:
                tally.ranges[m] = _merge(tally.ranges[m], c[m][rows])
    return ScanSummary(
        actuators_done=data.actuators_done,
        actuators_total=data.n_combinations,
        failed=len(data.failed_actuator),
        transitions=transitions,
        events=events,
        actuators_with_snap=snapping.count,
        types=[
            TypeSummary(
                direction=-neg_direction,
                alpha=alpha,
                beta=beta,
                stable=not unstable,
                count=tally.count,
                actuators=tally.actuators.count,
                ranges={m: _finite(tally.ranges[m]) for m in METRICS},
            )
            for (neg_direction, alpha, beta, unstable), tally in sorted(types.items())
        ],
        ranges={m: _finite(overall[m]) for m in METRICS},
    )


class _ActuatorTally:
    """How many distinct actuators, from blocks of sorted actuator numbers."""

    def __init__(self) -> None:
        self.count = 0
        self.last = None

    def add(self, sorted_actuators: np.ndarray) -> None:
        if len(sorted_actuators) == 0:
            return
        distinct = np.unique(sorted_actuators)
        self.count += len(distinct) - int(distinct[0] == self.last)
        self.last = distinct[-1]


class _TypeTally:
    def __init__(self) -> None:
        self.count = 0
        self.actuators = _ActuatorTally()
        self.ranges = {m: (math.inf, -math.inf) for m in METRICS}


def _merge(span: tuple[float, float], values: np.ndarray) -> tuple[float, float]:
    if len(values) == 0:
        return span
    return (min(span[0], float(values.min())), max(span[1], float(values.max())))


def _finite(span: tuple[float, float]) -> tuple[float, float]:
    """A range, NaN where nothing was seen."""
    return span if span[0] <= span[1] else (math.nan, math.nan)


@dataclass(frozen=True)
class RankedDesign:
    rank: int
    actuator: int
    segments: list[str]
    v_ml: float
    direction: int
    alpha: int
    beta: int
    stable: bool
    value: float  # the metric ranked by
    metrics: dict[str, float]


def rank_designs(
    data: ScanData, by: str, top: int, block_rows: int = BLOCK_ROWS
) -> list[RankedDesign]:
    """The ``top`` actuators whose largest transition (as the paper counts them) by
    |metric| is largest (dE: the energy released, dv: the volume that changes segment,
    dl: the length jump, dp: the pressure jump, each relative). One row per actuator,
    with that transition; ties go to the lower combination rank, so the table is
    deterministic."""
    if by not in METRICS:
        raise ValueError(f"rank by one of {METRICS}, not {by!r}")
    # each actuator's largest transition, block by block (an actuator is whole in one)
    best_parts = []
    for c in paper_blocks(data, block_rows):
        size = np.abs(c[by])
        order = np.lexsort((np.arange(len(size)), c["actuator"], -size))
        _, first = np.unique(c["actuator"][order], return_index=True)
        best_parts.append({name: values[order[first]] for name, values in c.items()})
    if not best_parts:
        return []
    c = {name: np.concatenate([part[name] for part in best_parts]) for name in best_parts[0]}
    best = np.lexsort((c["actuator"], -np.abs(c[by])))[:top]
    return [
        RankedDesign(
            rank=k + 1,
            actuator=int(c["actuator"][i]),
            segments=data.names_at_row(int(c["first"][i])),
            v_ml=float(c["v_ml"][i]),
            direction=int(c["direction"][i]),
            alpha=int(c["alpha"][i]),
            beta=int(c["beta"][i]),
            stable=bool(c["stable"][i]),
            value=float(c[by][i]),
            metrics={m: float(c[m][i]) for m in METRICS},
        )
        for k, i in enumerate(best)
    ]


def type_colour(alpha: int, beta: int, others: dict[tuple[int, int], str]) -> str:
    key = (alpha, beta)
    if key in PAPER_COLOURS:
        return PAPER_COLOURS[key]
    if key not in others:
        others[key] = OTHER_COLOURS[len(others) % len(OTHER_COLOURS)]
    return others[key]


def plot_fig4(data: ScanData, png: Path) -> None:
    """Fig. 4 A-C: dv, dl and dp against dE for every transition of the scan as the
    paper counts them, coloured by (alpha, beta); unstable filled, stable open,
    deflation as triangles."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    c = paper_columns(data)
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.8), constrained_layout=True)
    draw_fig4(list(axes), c)
    names = f"{len(data.names)} segments"
    fig.suptitle(
        f"All transitions of the {data.actuators_done:,} actuators of n = {data.n} from {names}"
        f" ({len(c['v_ml']):,} transitions as the paper counts them)"
    )
    fig.savefig(png, dpi=110)
    plt.close(fig)


def draw_fig4(axes: list, c: dict[str, np.ndarray]) -> None:
    """The figure's three panels on ``axes``: dv, dl and dp against dE of the
    transitions ``c`` (``paper_columns``)."""
    others: dict[tuple[int, int], str] = {}
    types = sorted(
        {
            (int(d), int(a), int(b), bool(s))
            for d, a, b, s in zip(c["direction"], c["alpha"], c["beta"], c["stable"], strict=True)
        },
        key=lambda t: (-t[0], t[1], t[2], t[3]),
    )
    for direction, alpha, beta, stable in types:
        rows = (
            (c["direction"] == direction)
            & (c["alpha"] == alpha)
            & (c["beta"] == beta)
            & (c["stable"] == stable)
        )
        colour = type_colour(alpha, beta, others)
        label = (
            f"({alpha}, {beta}) {'stable' if stable else 'unstable'}"
            f"{'' if direction > 0 else ', deflating'} ({int(rows.sum())})"
        )
        style = {
            "marker": "o" if direction > 0 else "v",
            "s": 10 if stable else 14,
            "linewidths": 0.6,
            "label": label,
        }
        if stable:
            style.update(facecolors="none", edgecolors=colour)
        else:
            style.update(color=colour, alpha=0.6)
        for ax, metric in zip(axes, ("dv", "dl", "dp"), strict=True):
            ax.scatter(c["dE"][rows], c[metric][rows], **style)
    titles = {"dv": "A  volume flow Δv̂", "dl": "B  length change Δl̂", "dp": "C  pressure change Δp̂"}
    for ax, metric in zip(axes, ("dv", "dl", "dp"), strict=True):
        ax.set_xlabel("energy change ΔÊ")
        ax.set_ylabel(metric.replace("d", "Δ") + " (relative)")
        ax.set_title(titles[metric], loc="left")
        ax.axvline(0.0, color="0.7", lw=0.6, zorder=0)
        ax.axhline(0.0, color="0.7", lw=0.6, zorder=0)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8, loc="upper right")
