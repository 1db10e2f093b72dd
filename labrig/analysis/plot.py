"""The paper's Fig. 2C for a run: pressure and length against supplied volume.

Pressure on top, length below, sharing the volume axis. Inflation is what the paper
shows: each repetition faint, the mean of the averaged repetitions bold with its spread
(± one standard deviation) as a band; the deflation mean is drawn thin in a second
colour. The model's prediction is dashed, its snap-throughs (its unstable transitions as the
paper counts them, ``compare.paper_counted``) marked with open diamonds;
the measured transitions are marked on the mean curve with their dp and dl, except those
the model's own path makes (a steep stable stretch, ``compare.follows_model``): those get
a small grey mark and no label, so that the snaps stand out.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from labrig.analysis.compare import paper_counted
from labrig.analysis.curves import DEFLATE, INFLATE
from labrig.analysis.results import AnalysisResult

COLOURS = {"p": "tab:blue", "l": "tab:green", "deflate": "tab:orange", "model": "black"}


def _at(grid: np.ndarray, curve: np.ndarray, v_ml: float) -> float:
    """The curve at v_ml, NaN where it has a gap (a marker there would float)."""
    if not len(grid):
        return float("nan")
    return float(np.interp(v_ml, grid, curve))


def run_panels(result: AnalysisResult, force=None) -> int:
    """How many panels the run's figure has: pressure, length (with a camera), force
    (with a load cell)."""
    return 1 + result.with_length + (force is not None)


def plot_run(result: AnalysisResult, path: Path, dpi: int = 130, force=None) -> None:
    """Write the figure to ``path`` (PNG, or any format matplotlib knows by suffix);
    ``force`` (``labrig.analysis.experiments.ForceResult``) adds the blocked actuator's
    force against the model's below."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = run_panels(result, force)
    fig, axes = plt.subplots(rows, 1, sharex=True, figsize=(7.5, 1.5 + 3 * rows), squeeze=False)
    draw_run(list(axes[:, 0]), result, force)
    averaged = ", ".join(str(i) for i in result.averaged) or "none"
    fig.suptitle(f"{result.title}\nmean of repetitions {averaged}", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    plt.close(fig)


def draw_run(axes: list, result: AnalysisResult, force=None) -> None:
    """The figure's panels on ``axes`` (``run_panels`` of them): p-v, l-v (with a
    camera), force (with ``force``)."""
    bottom = axes[-1]
    if force is not None:
        _force_panel(axes[-1], force)
        axes = axes[:-1]
        # the blocked actuator's own pressure (the free model's is drawn dashed)
        axes[0].plot(
            force.model_v_ml,
            force.model_p_kpa,
            ":",
            color=COLOURS["model"],
            lw=1.4,
            label="model, blocked",
        )
    grid = result.grid_ml
    with_length = result.with_length
    quantities = [("p", "pressure p (kPa)")] + ([("l", "length l (mm)")] if with_length else [])
    for ax, (quantity, label) in zip(axes, quantities, strict=True):
        _panel(ax, result, quantity, grid)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        ax.margins(x=0)
    bottom.set_xlabel("supplied volume v (mL)")
    axes[0].set_xlim(0, float(grid[-1]) if len(grid) else 1.0)
    axes[0].legend(loc="lower right", fontsize=8, framealpha=0.9)


def _force_panel(ax, force) -> None:
    """The load cell's force against the supplied volume, the model's dashed, each
    model snap marked with its predicted and measured jump."""
    ax.plot(force.v_ml, force.force_n, color="tab:red", lw=0.8, label="measured")
    ax.plot(
        force.model_v_ml,
        force.model_force_n,
        "--",
        color=COLOURS["model"],
        lw=1.2,
        label=f"model, blocked (rms {force.rms_n:.2f} N)",
    )
    for t in force.transitions:
        seen = "-" if t.force_n is None else f"{t.force_n:+.2f}"
        ax.annotate(
            f"jump {t.force_model_n:+.2f} N (seen {seen})",
            (t.v_ml, 0),
            xycoords=("data", "axes fraction"),
            xytext=(3, 6),
            textcoords="offset points",
            fontsize=8,
        )
        ax.axvline(t.v_ml, color="grey", lw=0.6, ls=":")
    ax.set_ylabel("force F (N)")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", fontsize=8, framealpha=0.9)


def _panel(ax, result: AnalysisResult, quantity: str, grid: np.ndarray) -> None:
    colour = COLOURS[quantity]
    for rep in result.repetitions:
        curves = rep.p_kpa if quantity == "p" else rep.l_mm
        if curves is None:
            continue
        ax.plot(
            grid,
            curves[INFLATE],
            color=colour,
            alpha=0.25,
            linewidth=0.8,
            label="repetitions" if rep is result.repetitions[0] else None,
        )
    means = result.mean_p if quantity == "p" else result.mean_l
    if means is not None:
        inflate = means[INFLATE]
        ax.fill_between(
            grid,
            inflate.mean - inflate.std,
            inflate.mean + inflate.std,
            color=colour,
            alpha=0.25,
            linewidth=0,
            label="spread (±1 s.d.)",
        )
        ax.plot(grid, inflate.mean, color=colour, linewidth=2.0, label="mean, inflation")
        ax.plot(
            grid,
            means[DEFLATE].mean,
            color=COLOURS["deflate"],
            linewidth=1.0,
            label="mean, deflation",
        )
    comparison = result.comparison
    if comparison is not None:
        prediction = comparison.prediction
        values = prediction.p_kpa if quantity == "p" else prediction.l_mm
        for phase, style, name in ((INFLATE, "--", "model"), (DEFLATE, ":", "model, deflation")):
            chosen = prediction.direction == phase
            if np.any(chosen):
                ax.plot(
                    prediction.v_ml[chosen],
                    values[chosen],
                    style,
                    color=COLOURS["model"],
                    linewidth=1.1,
                    label=name,
                )
        snaps = [t for t in paper_counted(prediction.transitions) if not t.stable]
        for k, t in enumerate(snaps):
            curve = comparison.model_p_kpa if quantity == "p" else comparison.model_l_mm
            ax.plot(
                t.v_ml,
                _at(grid, curve[t.direction], t.v_ml),
                "D",
                mfc="none",
                mec=COLOURS["model"],
                ms=7,
                label="model snap-throughs" if k == 0 else None,
            )
    if quantity == "p":
        # from 0 to a little above the measurement (the model may run far up its wall)
        measured = [c.mean for c in means.values()] if means else []
        measured += [c for rep in result.repetitions for c in rep.p_kpa.values()]
        finite = np.concatenate([c[np.isfinite(c)] for c in measured]) if measured else []
        if len(finite):
            ax.set_ylim(min(0.0, float(np.min(finite))), 1.15 * float(np.max(finite)))
    if means is not None:
        _mark_transitions(ax, result, quantity, grid, means)


def _mark_transitions(ax, result: AnalysisResult, quantity: str, grid, means) -> None:
    """A triangle on the mean curve at each measured transition (down on inflation, up on
    deflation) labelled with its jump, the label placed on the side the curve leaves
    free (towards the axis' middle) so it neither hides the jump nor leaves the axes."""
    v_span = float(grid[-1]) if len(grid) else 1.0
    steep = result.steep_stretches
    first = first_steep = True
    for t in result.transitions:
        y = _at(grid, means[t.direction].mean, t.v_ml)
        size = t.dp_kpa if quantity == "p" else t.dl_mm
        if not np.isfinite(y):
            continue
        if t in steep:
            label = "steep stretches on the model's curve" if first_steep else None
            first_steep = False
            marker = "v" if t.direction == INFLATE else "^"
            ax.plot(t.v_ml, y, marker, mfc="none", mec="0.45", ms=6, label=label, zorder=5)
            continue
        colour = "tab:red" if t.direction == INFLATE else "tab:purple"
        marker = "v" if t.direction == INFLATE else "^"
        label = "measured snaps" if steep else "measured transitions"
        label = label if first else None
        first = False
        ax.plot(t.v_ml, y, marker, color=colour, ms=8, label=label, zorder=5)
        if not np.isfinite(size):
            continue
        unit, symbol = ("kPa", "Δp") if quantity == "p" else ("mm", "Δl")
        bottom, top = ax.get_ylim()
        dx = -70 if t.v_ml > 0.75 * v_span else 10
        dy = -34 if y > 0.5 * (bottom + top) else 14
        ax.annotate(
            f"{symbol} {round(size, 1) + 0.0:+.1f} {unit}\nat {t.v_ml:.1f} mL",  # no -0.0
            (t.v_ml, y),
            xytext=(dx, dy),
            textcoords="offset points",
            fontsize=8,
            color=colour,
            bbox={"boxstyle": "round,pad=0.2", "fc": "white", "ec": colour, "alpha": 0.85},
            arrowprops={"arrowstyle": "-", "color": colour, "lw": 0.6},
            zorder=6,
        )
