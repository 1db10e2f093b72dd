"""What a scan found: counts and ranges per transition type, the designs with the
largest snap, and the paper's Fig. 4 A-C for the scan.

A transition's type is (alpha, beta) — segments right of their pressure peak before and
after — with its stability (a snap at constant volume or a stable change) and its
direction; the paper's Fig. 4 colours (0, 1) blue, (1, 1) red and (1, 2) green. This
module works on ``ScanData`` arrays and leaves files and terminals to others.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from labrig.model.scan_file import ScanData

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
    transitions: int
    actuators_with_snap: int
    types: list[TypeSummary]
    ranges: dict[str, tuple[float, float]]  # over every transition


def summarise(data: ScanData) -> ScanSummary:
    c = data.columns
    keys = np.stack([-c["direction"].astype(int), c["alpha"], c["beta"], ~c["stable"]], axis=1)
    types = []
    if len(keys):
        unique, inverse = np.unique(keys, axis=0, return_inverse=True)
        inverse = inverse.reshape(-1)
        for j, (neg_direction, alpha, beta, unstable) in enumerate(unique):
            rows = inverse == j
            types.append(
                TypeSummary(
                    direction=-int(neg_direction),
                    alpha=int(alpha),
                    beta=int(beta),
                    stable=not bool(unstable),
                    count=int(rows.sum()),
                    actuators=len(np.unique(data.actuator[rows])),
                    ranges={m: _range(c[m][rows]) for m in METRICS},
                )
            )
    snaps = ~c["stable"]
    return ScanSummary(
        actuators_done=data.actuators_done,
        actuators_total=data.n_combinations,
        failed=len(data.failed_actuator),
        transitions=len(data.actuator),
        actuators_with_snap=len(np.unique(data.actuator[snaps])),
        types=types,
        ranges={m: _range(c[m]) for m in METRICS},
    )


def _range(values: np.ndarray) -> tuple[float, float]:
    if len(values) == 0:
        return (float("nan"), float("nan"))
    return (float(values.min()), float(values.max()))


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


def rank_designs(data: ScanData, by: str, top: int) -> list[RankedDesign]:
    """The ``top`` actuators whose largest transition by |metric| is largest (dE: the
    energy released, dv: the volume that changes segment, dl: the length jump, dp: the
    pressure jump, each relative). One row per actuator, with that transition; ties go
    to the lower combination rank, so the table is deterministic."""
    if by not in METRICS:
        raise ValueError(f"rank by one of {METRICS}, not {by!r}")
    c = data.columns
    size = np.abs(c[by])
    order = np.lexsort((np.arange(len(size)), data.actuator, -size))
    # the first row of each actuator in that order is its largest transition
    _, first = np.unique(data.actuator[order], return_index=True)
    best = order[np.sort(first)][:top]
    return [
        RankedDesign(
            rank=k + 1,
            actuator=int(data.actuator[i]),
            segments=data.segment_names(data.segments[i]),
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
    """Fig. 4 A-C: dv, dl and dp against dE for every transition of the scan, coloured
    by (alpha, beta); snaps filled, stable transitions open, deflation as triangles."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    c = data.columns
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.8), constrained_layout=True)
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
            f"({alpha}, {beta}) {'stable' if stable else 'snap'}"
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
    names = f"{len(data.names)} segments"
    fig.suptitle(
        f"All transitions of the {data.actuators_done:,} actuators of n = {data.n} from {names}"
        f" ({len(data.actuator):,} transitions)"
    )
    fig.savefig(png, dpi=110)
    plt.close(fig)
