"""The stability model from Python: ``labrig.segment``, ``labrig.actuator``.

A segment is what ``labrig model curve SEG --json`` prints, an actuator's path what
``labrig model path SEG SEG ... --json`` prints: both are built by what those commands
use (``labrig.model.curve_document``, ``labrig.model.path_document``), so the tables'
columns are the JSON's fields (volumes in mL, pressures in kPa, lengths in mm; dE, dv,
dl, dp normalised as in the paper), and a field a command gains appears here too.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from labrig.errors import InputError
from labrig.vocabulary import ALIASES, beside, with_direction_names

from .axes import panel_axes
from .solver_mode import prefer_plain_python

if TYPE_CHECKING:
    from collections.abc import Sequence

    import pandas as pd
    from matplotlib.axes import Axes

    from labrig.model.actuator.path import Path as SolvedPath
    from labrig.model.actuator.path import SampledPath
    from labrig.model.actuator.transitions import Transition
    from labrig.model.segments.curve import SegmentCurve


def segment(spec: str | Path, library_dir: str | Path | None = None) -> Segment:
    """A segment by library name (``B46-T20``), Gent membrane (``gent-a``), measured
    segment name (from ``library_dir``, else $LABRIG_LIBRARY, else ./library) or CSV
    path (header ``volume_ml,pressure_kpa,length_mm``); ``InputError`` if none fits."""
    prefer_plain_python()
    from labrig.model.segments.catalog import load_segment

    directory = None if library_dir is None else Path(library_dir)
    return Segment(str(spec), load_segment(str(spec), library_dir=directory))


@dataclass(frozen=True)
class Segment:
    """One segment's tabulated p(v) and l(v) (supplied volume from the unpressurised
    state); ``model`` is the model's own ``SegmentCurve``, ``spec`` what named it."""

    spec: str
    model: SegmentCurve

    @property
    def name(self) -> str:
        """The segment's name, as the model and the commands print it."""
        return self.model.name

    @property
    def V0_ml(self) -> float:
        """Volume enclosed at zero pressure (mL)."""
        return self.model.V0_ml

    @property
    def peak(self) -> dict[str, float] | None:
        """The pressure peak, ``{"v_ml", "p_kpa"}`` (mL, kPa); None if p(v) only rises."""
        from labrig.model.curve_document import extremum_document

        return extremum_document(self.model.peak)

    @property
    def valley(self) -> dict[str, float] | None:
        """The pressure valley after the peak, ``{"v_ml", "p_kpa"}`` (mL, kPa); None
        without one."""
        from labrig.model.curve_document import extremum_document

        return extremum_document(self.model.valley)

    @property
    def document(self) -> dict[str, Any]:
        """Exactly what ``labrig model curve SEG --json`` prints: name, V0_ml, peak,
        valley, the arrays v_ml, p_kpa, l_mm (each followed by its vocabulary name) and,
        for a measured table, ``measured`` (what was done to it)."""
        from labrig.model.curve_document import curve_document

        return curve_document(self.model)

    @property
    def curve(self) -> pd.DataFrame:
        """The table: v_ml (supplied volume, mL), p_kpa (gauge, kPa), l_mm (mm), the
        arrays ``labrig model curve --json`` prints, each with its vocabulary name beside
        it (``volume_ml``, ``pressure_kpa``, ``segments_length_mm``)."""
        import pandas as pd

        table = {"v_ml": self.model.v_ml, "p_kpa": self.model.p_kpa, "l_mm": self.model.l_mm}
        return beside(pd.DataFrame(table), ALIASES["model curve"])

    def plot(self, ax: Axes | Sequence[Axes] | None = None) -> Axes | list[Axes]:
        """Draw what ``labrig model curve --plot`` draws (p-v and l-v, peak and valley
        marked) on ``ax``: one Axes (p-v), two, or None (a new figure)."""
        from labrig.model.segment_figure import braid_contact_ml, draw_curve

        axes, shown = panel_axes(ax, 2)
        draw_curve(axes, self.model, braid_contact_ml(self.spec))
        return shown

    def __repr__(self) -> str:
        return f"<labrig.Segment {self.name}: {self.model.source}>"


def actuator(
    *segments: str | Path | Segment | Sequence[str | Path | Segment],
    fittings_length_mm: float = 0.0,
) -> Actuator:
    """An actuator of two or more segments sharing one pressure (names, CSV paths or
    ``Segment`` objects), given one by one or as one list:
    ``actuator("B48-T30", "B50-T20")`` or ``actuator(["B48-T30", "B50-T20"])``;
    ``fittings_length_mm`` (mm, the protocol's ``specimen.fittings_length_mm``) is
    what its ``length_mm`` adds to the segments' lengths, as a run's markers see it."""
    if not (
        isinstance(fittings_length_mm, numbers.Real)
        and not isinstance(fittings_length_mm, bool)
        and math.isfinite(fittings_length_mm)
        and fittings_length_mm >= 0
    ):
        raise InputError(
            f"fittings_length_mm={fittings_length_mm!r}: the fittings' length, mm, >= 0"
        )
    if len(segments) == 1 and isinstance(segments[0], list | tuple):
        segments = tuple(segments[0])
    if len(segments) < 2:
        raise InputError(f"an actuator needs at least two segments, got {len(segments)}")
    chosen = [s if isinstance(s, Segment) else segment(s) for s in segments]
    return Actuator(tuple(chosen), float(fittings_length_mm))


@dataclass(frozen=True)
class Actuator:
    """Segments in series, one pressure: the model's combined actuator."""

    segments: tuple[Segment, ...]
    fittings_length_mm: float = 0.0

    @property
    def names(self) -> list[str]:
        """The segments' names, in series order."""
        return [s.name for s in self.segments]

    def path(self, *, deflate: bool = False, v_end_ml: float | None = None) -> ActuatorPath:
        """The quasi-static path under volume-controlled inflation to ``v_end_ml`` (mL;
        default: where no further transition is possible) and, with ``deflate``, back
        to zero, as ``labrig model path`` computes it."""
        prefer_plain_python()  # before the model's first import fixes the solver's mode
        from labrig.model.path_document import checked_end_volume_ml, solve_path

        v_end_ml = checked_end_volume_ml(v_end_ml, named="v_end_ml")
        return ActuatorPath(
            *solve_path([s.model for s in self.segments], v_end_ml, deflate=deflate),
            self.fittings_length_mm,
        )

    def __repr__(self) -> str:
        return f"<labrig.Actuator {' + '.join(self.names)}>"


@dataclass(frozen=True)
class ActuatorPath:
    """A solved path: ``document`` is ``labrig model path --json``'s object, ``path``
    and ``transitions`` its tables."""

    solved: SolvedPath
    sampled: SampledPath
    found: tuple[Transition, ...]
    fittings_length_mm: float = 0.0

    @property
    def document(self) -> dict[str, Any]:
        """Exactly what ``labrig model path ... --json`` prints."""
        from labrig.model.path_document import path_document

        return path_document(self.solved.actuator.names, self.sampled, self.found)

    @property
    def path(self) -> pd.DataFrame:
        """The path sampled in volume: the JSON's v_ml, p_kpa, l_mm (the segments'
        lengths alone), each with its vocabulary name beside it (``volume_ml``,
        ``pressure_kpa``, ``segments_length_mm``), each segment's volume ``v1_ml``,
        ``v2_ml``, ... (the JSON's ``v_i_ml``), ``length_mm`` (with the actuator's
        fittings, as ``Run.model_path``) and ``direction``."""
        import numpy as np
        import pandas as pd

        fields = dict(self.document["path"])
        per_segment = fields.pop("v_i_ml")
        table = beside(pd.DataFrame(fields), ALIASES["model path"])
        table["length_mm"] = table["l_mm"] + self.fittings_length_mm
        table["direction"] = np.asarray(self.sampled.direction)
        table = with_direction_names(table)
        for i, values in enumerate(per_segment, 1):
            table[f"v{i}_ml"] = values
        return table

    @property
    def transitions(self) -> pd.DataFrame:
        """One row per event of the path (every peak crossing and every snap), the
        JSON's ``transitions``: v_ml (supplied volume just before
        it, mL), alpha, beta, stable (False: a snap at constant volume), dE, dv, dl, dp
        (normalised), direction."""
        import pandas as pd

        return pd.DataFrame(self.document["transitions"])

    @property
    def paper_transitions(self) -> pd.DataFrame:
        """The transitions as the paper counts them (the events at one
        supplied volume are one): the JSON's ``paper_transitions``, each with ``events``, the
        rows of ``transitions`` it is made of."""
        import pandas as pd

        return pd.DataFrame(self.document["paper_transitions"])

    def plot(self, ax: Axes | Sequence[Axes] | None = None) -> Axes | list[Axes]:
        """Draw what ``labrig model path --plot`` draws (p-v and l-v with the
        transitions; for two segments the v1-v2 plane) on ``ax``: one Axes (p-v), a
        sequence, or None (a new figure)."""
        from labrig.model.plots import draw_path, path_panels

        axes, shown = panel_axes(ax, path_panels(self.solved))
        draw_path(axes, self.solved, self.sampled, self.found)
        return shown

    def __repr__(self) -> str:
        from labrig.model.actuator.paper_counting import paper_transitions

        names = " + ".join(self.solved.actuator.names)
        counted = len(paper_transitions(self.found))
        return (
            f"<labrig.ActuatorPath {names}: {counted} transitions as the paper counts them "
            f"({len(self.found)} events)>"
        )
