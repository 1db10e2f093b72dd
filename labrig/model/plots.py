"""Pictures of an actuator's path, like the paper's figures.

- p-v and l-v of the combined actuator with its events marked (Fig. 2C / 3E) and each
  transition, as the paper counts them, labelled with its (alpha, beta); deflation
  dashed, so hysteresis shows;
- for two segments, the v1-v2 plane (Fig. 3D): every equilibrium of the pressure grid,
  stable and unstable, with the path on top and each snap as an arrow;
- a library's segments side by side (Fig. 1C and D): p-v and the length change, with
  the paper's measured peak range shaded.

matplotlib is imported inside the function (Agg backend): the model itself never needs it.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path as FilePath

import numpy as np

from labrig.model.actuator.paper_counting import paper_transitions
from labrig.model.actuator.path import DEFLATE, INFLATE, Path, SampledPath
from labrig.model.actuator.transitions import Transition

_STYLE = {INFLATE: ("tab:blue", "-", "inflation"), DEFLATE: ("tab:orange", "--", "deflation")}


def path_panels(path: Path) -> int:
    """How many panels a path's figure has: p-v, l-v and, for two segments, v1-v2."""
    return 3 if path.actuator.n == 2 else 2


def plot_path(
    path: Path,
    sampled: SampledPath,
    found: Sequence[Transition],
    png: FilePath,
    *,
    grid_points: int = 1000,
) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    pair = path_panels(path) == 3
    fig, axes = plt.subplots(
        1, path_panels(path), figsize=(15 if pair else 10, 4.5), constrained_layout=True
    )
    draw_path(list(axes), path, sampled, found, grid_points=grid_points)
    fig.suptitle(" + ".join(path.actuator.names))
    fig.savefig(png, dpi=120)
    plt.close(fig)


def draw_path(
    axes: list,
    path: Path,
    sampled: SampledPath,
    found: Sequence[Transition],
    *,
    grid_points: int = 1000,
) -> None:
    """The figure's panels on ``axes`` (``path_panels`` of them): p-v, l-v and, for
    two segments, the v1-v2 plane."""
    actuator = path.actuator
    ax_p, ax_l = axes[0], axes[1]
    for direction, (color, style, label) in _STYLE.items():
        on = sampled.direction == direction
        if not np.any(on):
            continue
        # keep the turning point in both halves so the two lines meet
        index = np.flatnonzero(on)
        index = np.arange(max(index[0] - 1, 0), index[-1] + 1)
        ax_p.plot(
            sampled.v_ml[index],
            sampled.p_kpa[index],
            style,
            color=color,
            label=label,
            linewidth=1.4,
        )
        ax_l.plot(sampled.v_ml[index], sampled.l_mm[index], style, color=color, linewidth=1.4)
    lengths = [(actuator.length_mm(t.pre.v_i_ml), actuator.length_mm(t.post.v_i_ml)) for t in found]
    for t, (l_pre, l_post) in zip(found, lengths, strict=True):
        if t.stable:
            ax_p.plot(t.v_ml, t.pre.p_kpa, "o", mfc="none", color="tab:green", markersize=7)
            ax_l.plot(t.v_ml, l_pre, "o", mfc="none", color="tab:green", markersize=7)
        else:
            ax_p.plot(
                [t.v_ml, t.v_ml], [t.pre.p_kpa, t.post.p_kpa], "-", color="tab:red", linewidth=2
            )
            ax_l.plot([t.v_ml, t.v_ml], [l_pre, l_post], "-", color="tab:red", linewidth=2)
            ax_p.plot(t.v_ml, t.pre.p_kpa, "v", color="tab:red", markersize=7)
            ax_l.plot(t.v_ml, l_pre, "v", color="tab:red", markersize=7)
    for t in paper_transitions(found):
        ax_p.annotate(
            f"({t.alpha}, {t.beta})",
            xy=(t.v_ml, t.events[0].pre.p_kpa),
            xytext=(0, 6),
            textcoords="offset points",
            ha="center",
            fontsize=7,
            color="tab:green" if t.stable else "tab:red",
        )
    ax_p.plot([], [], "o", mfc="none", color="tab:green", label="stable peak crossing")
    ax_p.plot([], [], "v-", color="tab:red", label="snap at constant volume")
    ax_p.set_ylabel("pressure p (kPa)")
    ax_l.set_ylabel("length l (mm)")
    for ax in (ax_p, ax_l):
        ax.set_xlabel("supplied volume v (mL)")
        ax.set_xlim(0, np.max(sampled.v_ml))
        ax.grid(alpha=0.3)
    ax_p.set_ylim(0, 1.05 * np.max(sampled.p_kpa))
    ax_p.legend(loc="lower right", fontsize=8)
    if actuator.n == 2:
        _plane(axes[2], path, sampled, found, grid_points)


def _plane(
    ax, path: Path, sampled: SampledPath, found: Sequence[Transition], grid_points: int
) -> None:
    """Fig. 3D: equilibria of the pressure grid in the v1-v2 plane, the path on top."""
    actuator = path.actuator
    p_max = 1.05 * float(np.max(sampled.p_kpa))
    eq = actuator.equilibria(actuator.pressure_grid(grid_points, p_max))
    v_max = float(np.max(sampled.v_ml))
    shown = eq.v_ml <= 1.02 * v_max
    for stable, color, label in (
        (True, "tab:blue", "stable equilibria"),
        (False, "tab:red", "unstable equilibria"),
    ):
        sel = shown & (eq.stable == stable)
        ax.plot(
            eq.v_i_ml[sel, 0],
            eq.v_i_ml[sel, 1],
            ".",
            color=color,
            markersize=1.5,
            alpha=0.5,
            label=label,
        )
    for direction, (_, style, label) in _STYLE.items():
        on = sampled.direction == direction
        if not np.any(on):
            continue
        v1, v2 = sampled.v_i_ml[0], sampled.v_i_ml[1]
        jumps = np.flatnonzero(np.abs(np.diff(sampled.v_ml)) < 1e-9) + 1
        pieces = [
            i
            for i in np.split(np.flatnonzero(on), np.searchsorted(np.flatnonzero(on), jumps))
            if len(i)
        ]
        shade = "black" if direction == INFLATE else "dimgrey"
        for k, index in enumerate(pieces):
            ax.plot(
                v1[index],
                v2[index],
                style,
                color=shade,
                linewidth=1.2,
                label=f"path, {label}" if k == 0 else None,
            )
    for t in found:
        if not t.stable:
            ax.annotate(
                "",
                xy=t.post.v_i_ml,
                xytext=t.pre.v_i_ml,
                arrowprops={"arrowstyle": "->", "color": "tab:red", "linewidth": 1.5},
            )
    ax.set_xlabel(f"v1 ({actuator.names[0]}) (mL)")
    ax.set_ylabel(f"v2 ({actuator.names[1]}) (mL)")
    ax.set_xlim(0, v_max)
    ax.set_ylim(0, v_max)
    ax.set_aspect("equal")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right", fontsize=7, markerscale=3)


def plot_library(
    curves: Sequence, png: FilePath, *, peak_range_kpa: tuple[float, float], title: str
) -> None:
    """Fig. 1C and D for a library: every segment's p(v) and l(v) - l(0), coloured by
    L_braid, the paper's measured peak range shaded and each peak marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from labrig.model.segments.catalog import library_geometry

    braids = sorted({library_geometry(c.name)[0] for c in curves})
    colours = plt.get_cmap("viridis")(np.linspace(0.0, 0.9, len(braids)))
    colour_of = dict(zip(braids, colours, strict=True))
    fig, (ax_p, ax_l) = plt.subplots(1, 2, figsize=(11, 4.5), constrained_layout=True)
    ax_p.axhspan(*peak_range_kpa, color="tab:red", alpha=0.12, label="the paper's peaks")
    for curve in curves:
        colour = colour_of[library_geometry(curve.name)[0]]
        ax_p.plot(curve.v_ml, curve.p_kpa, color=colour, linewidth=0.9)
        ax_l.plot(curve.v_ml, curve.l_mm - curve.l_mm[0], color=colour, linewidth=0.9)
        if curve.peak is not None:
            ax_p.plot(curve.peak.v_ml, curve.peak.p_kpa, ".", color=colour, markersize=5)
    for braid in braids:
        ax_p.plot([], [], color=colour_of[braid], label=f"L_braid {braid:g} mm")
    v_max = min(40.0, max(float(c.v_max_ml) for c in curves))
    ax_p.set_ylim(0, 110)
    ax_p.set_ylabel("pressure p (kPa)")
    ax_l.set_ylabel("length change l - l(0) (mm)")
    for ax in (ax_p, ax_l):
        ax.set_xlabel("supplied volume v (mL)")
        ax.set_xlim(0, v_max)
        ax.grid(alpha=0.3)
    ax_p.legend(loc="lower right", fontsize=7)
    fig.suptitle(title)
    fig.savefig(png, dpi=120)
    plt.close(fig)
