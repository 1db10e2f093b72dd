"""The Axes a ``.plot(ax=...)`` draws on: the user's, or a new figure's.

Each ``.plot`` draws what the command draws (``labrig plot``, ``model path --plot``, ...)
through the same drawing function, which fills a fixed number of panels. A user may pass
one Axes (the first panel: pressure against volume), as many as the figure has panels,
or none (a new figure with all of them). Panels the user gave no Axes for are drawn on
a figure that is never shown (matplotlib draws nothing until a figure is rendered), so
the drawing functions stay the commands' own, unchanged.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from labrig.errors import InputError

if TYPE_CHECKING:
    from collections.abc import Sequence

    from matplotlib.axes import Axes


def panel_axes(
    ax: Axes | Sequence[Axes] | None, count: int, *, vertical: bool = False, sharex: bool = False
) -> tuple[list[Axes], Axes | list[Axes]]:
    """(axes to draw on, ``count`` of them; the Axes the user sees: the one given, or
    the list)."""
    if ax is None:
        import matplotlib.pyplot as plt

        shape = (count, 1) if vertical else (1, count)
        size = (7.5, 1.5 + 3 * count) if vertical else (5 * count, 4.5)
        fig, grid = plt.subplots(*shape, figsize=size, sharex=sharex, squeeze=False)
        fig.set_layout_engine("constrained")
        axes = list(np.ravel(grid))
        return axes, axes
    given = [ax] if hasattr(ax, "plot") else list(np.ravel(np.asarray(ax, dtype=object)))
    if not 1 <= len(given) <= count:
        raise InputError(f"ax: {len(given)} Axes given; this figure has 1 to {count} panels")
    if len(given) < count:
        from matplotlib.figure import Figure

        unseen = Figure().subplots(1, count - len(given), squeeze=False)
        given_and_unseen = given + list(np.ravel(unseen))
        return given_and_unseen, given[0] if len(given) == 1 else given
    return given, given[0] if len(given) == 1 else given
