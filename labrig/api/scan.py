"""``labrig.open_scan``: a scan file (``labrig model scan --out``) as a DataFrame.

The scan file reader keeps the rows in the file until asked for; ``Scan.table`` reads a
range of them, so a scan of millions of transitions is browsed without loading it.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from labrig.errors import InputError
from labrig.vocabulary import ALIASES, beside, with_direction_names

from .axes import panel_axes
from .reading import open_readonly
from .solver_mode import prefer_plain_python

if TYPE_CHECKING:
    from collections.abc import Sequence

    import pandas as pd
    from matplotlib.axes import Axes

    from .model import Actuator


def open_scan(path: str | Path) -> Scan:
    """Open a scan file, complete or cut short; ``InputError`` if it is not one."""
    prefer_plain_python()  # the scan's reader imports the model: see Run.__init__
    from labrig.model.scan.scan_file import read_scan

    return Scan(read_scan(Path(path)))


class Scan:
    """A scan: its metadata as attributes, its transitions as a DataFrame.

    Attributes: ``path``; ``n`` (segments per actuator); ``names`` (the library's
    segments, in the file's order); ``complete``; ``actuators_done`` of
    ``n_combinations``; ``data`` (the scan file reader's ``ScanData``); ``len(scan)``
    is the number of transitions.
    """

    def __init__(self, data) -> None:
        self.data = data
        self.path: Path = data.path
        #: segments per actuator
        self.n: int = data.n
        #: the library's segment names, in the file's order
        self.names: list[str] = list(data.names)
        self.complete: bool = data.complete
        self.actuators_done: int = data.actuators_done
        self.n_combinations: int = data.n_combinations

    def __len__(self) -> int:
        return self.data.row_stop

    def __repr__(self) -> str:
        state = "complete" if self.complete else "incomplete"
        return (
            f"<labrig.Scan {self.path.name}: n = {self.n}, {self.actuators_done:,} of "
            f"{self.n_combinations:,} actuators ({state}), {len(self):,} transitions>"
        )

    def table(self, start: int = 0, stop: int | None = None) -> pd.DataFrame:
        """Transition rows ``start`` to ``stop`` (all by default): ``actuator`` (the
        combination's rank), ``segment1`` ... ``segmentN`` (names), and the fields of
        ``labrig model path --json``: direction ("inflate" or "deflate"; the file's
        +1/-1 as direction_sign), v_ml (mL), alpha, beta, stable, dE, dv, dl, dp
        (normalised)."""
        import pandas as pd

        from labrig.model.scan.scan import TRANSITION_FIELDS

        stop = len(self) if stop is None else min(stop, len(self))
        with open_readonly(self.path) as h5:
            rows = h5["transitions"]
            table = {"actuator": rows["actuator"][start:stop]}
            table.update(self._segment_columns(rows["segments"][start:stop]))
            for name in TRANSITION_FIELDS:
                table[name] = rows[name][start:stop]
        return with_direction_names(pd.DataFrame(table))

    @property
    def transitions(self) -> pd.DataFrame:
        """Every row of the scan: the paths' events (``table()``)."""
        return self.table()

    @property
    def paper_transitions(self) -> pd.DataFrame:
        """The transitions as the paper counts them (the events at one supplied
        volume are one; what ``labrig model scan-summary`` counts and Fig. 4 draws):
        ``actuator``, ``segment1`` ... ``segmentN``, the event fields (dv summed over the
        events, dE, dl, dp compounded), ``events`` and its vocabulary name ``n_events`` (how
        many events it is made of) and ``first``, the row of its first event in
        ``transitions``."""
        import pandas as pd

        from labrig.model.scan.scan_summary import paper_columns

        columns = dict(paper_columns(self.data))
        table = {"actuator": columns.pop("actuator")}
        with open_readonly(self.path) as h5:
            indices = h5["transitions/segments"][:][columns["first"]]
        table.update(self._segment_columns(indices))
        return beside(with_direction_names(pd.DataFrame({**table, **columns})), ALIASES["scan"])

    def _segment_columns(self, indices: np.ndarray) -> dict[str, np.ndarray]:
        """``segment1`` ... ``segmentN``: the names of the segments whose library
        indices are the rows of ``indices`` (rows x n)."""
        names = np.asarray(self.names, dtype=object)
        return {f"segment{i + 1}": names[indices[:, i]] for i in range(self.n)}

    def plot(
        self, ax: Axes | Sequence[Axes] | None = None, transitions: pd.DataFrame | None = None
    ) -> Axes | list[Axes]:
        """Draw what ``labrig model scan --plot`` draws (the paper's Fig. 4 A-C: dv, dl,
        dp against dE of the paper's transitions, coloured by (alpha, beta)) on ``ax``:
        one Axes (dv), three, or None (a new figure). ``transitions``: some rows of
        ``paper_transitions`` to draw instead of all of them, e.g.
        ``scan.plot(transitions=scan.paper_transitions.query("dE < -0.1"))``."""
        from labrig.model.scan.scan_summary import draw_fig4, paper_columns

        if transitions is None:
            columns = paper_columns(self.data)
        else:
            missing = [name for name in FIG4_COLUMNS if name not in transitions]
            if missing:
                raise InputError(
                    f"transitions: no column {', '.join(missing)}; pass rows of "
                    "scan.paper_transitions (or of scan.transitions)"
                )
            columns = {name: transitions[name].to_numpy() for name in FIG4_COLUMNS}
            # the figure's colours read the sign, which the tables keep beside the name
            if "direction_sign" in transitions:
                columns["direction"] = transitions["direction_sign"].to_numpy(np.int8)
        axes, shown = panel_axes(ax, 3)
        draw_fig4(axes, columns)
        return shown

    def actuator(self, row) -> Actuator:
        """The actuator of one row of ``transitions``, ``paper_transitions`` or
        ``table()`` (the row, e.g. ``scan.paper_transitions.loc[7]``, or its
        ``actuator`` rank), as ``labrig.actuator`` builds it from the scanned segments'
        names: ``scan.actuator(row).path()`` solves it again, with its whole path."""
        from labrig.model.scan.plan import named_library
        from labrig.model.scan.scan import combination_at

        from .model import actuator

        rank = row.get("actuator") if hasattr(row, "get") else row
        if isinstance(rank, np.generic):
            rank = rank.item()
        if isinstance(rank, bool) or not isinstance(rank, int):
            raise InputError(
                f"row {rank!r}: a row of the scan's tables (with its 'actuator' column) "
                "or an actuator's rank"
            )
        if not 0 <= rank < self.n_combinations:
            raise InputError(
                f"actuator {rank}: the scan's ranks are 0 to {self.n_combinations - 1}"
            )
        with open_readonly(self.path) as h5:
            label = str(h5.attrs["library"])
        names = [self.names[i] for i in combination_at(rank, len(self.names), self.n)]
        if named_library(label) is None:  # a folder of measured curves: their CSV files
            return actuator(*(Path(label) / f"{name}.csv" for name in names))
        return actuator(*names)


# what Fig. 4 draws of each transition
FIG4_COLUMNS = ("direction", "alpha", "beta", "stable", "dE", "dv", "dl", "dp")
