"""``labrig.open_run``: one run file as pandas and xarray objects, read-only and lazy.

Opening reads only the run's metadata (title, status, protocol, the repetitions'
statuses and sizes); each series is read when asked for, and only the rows asked for
(``start_s``/``stop_s`` find their rows by bisection on the time axis, a few reads),
so memory stays flat however long the run. The averaged curves, the transitions and the
comparison with the model come from the analysis the commands use: the one stored in
the file, or, for a file without one (a live or killed run), one computed in memory from
the data so far. A file still flagged open by its writer (recording now, or killed)
is read as of the writer's last flush, and says so (``writer_open``, ``live`` and a
``RunOpenWarning``); nothing is ever written to it.
"""

from __future__ import annotations

import bisect
import numbers
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, fields
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from labrig.errors import InputError
from labrig.recording.run_layout import LOG_DESCRIPTION, LOG_FIELDS, repetition_name
from labrig.recording.run_reader import decode, read_rows
from labrig.vocabulary import ALIASES, beside, with_direction_names

from .axes import panel_axes
from .reading import open_readonly, open_run_file, writer_state
from .solver_mode import prefer_plain_python

if TYPE_CHECKING:
    import pandas as pd
    import xarray as xr
    from matplotlib.axes import Axes

    from labrig.analysis.results import AnalysisResult
    from labrig.config.protocol import Protocol

LOGS = ("pressure", "pump", "length", "force")


class RunOpenWarning(UserWarning):
    """A run file read while its writer has it open (a live run), or left open by a
    writer that was killed: the data are those of the writer's last flush."""


@dataclass(frozen=True)
class TransitionFrame:
    """A video frame at a measured transition: ``image`` is (height, width, 3) RGB,
    uint8; ``t_s`` the frame's time on the run's clock (s)."""

    label: str
    repetition: int
    t_s: float
    frame_index: int
    image: np.ndarray


class _Rows(Sequence):
    """A time dataset's first ``n`` values, read one at a time (for bisection)."""

    def __init__(self, dataset, n: int) -> None:
        self.dataset, self.n = dataset, n

    def __len__(self) -> int:
        return self.n

    def __getitem__(self, i):
        return float(self.dataset[i])


def open_run(path: str | Path) -> Run:
    """Open the run file at ``path`` read-only (a finished run, a live one or one a
    killed writer left); ``InputError`` (one line) if it is not a readable run file."""
    return Run(Path(path))


class Run:
    """One run file: metadata, protocol and outcome at once, data when asked for.

    Series and curves are ``xarray.Dataset`` objects (named dimensions, ``units`` and
    ``nexus_path`` attributes, the file's NeXus field names) or ``pandas.DataFrame``
    objects with units in the column names, as ``labrig export --csv`` writes them.

    Attributes read at open: ``path``; ``title``; ``status`` (running, complete,
    aborted or faulted: how the run ended, or ``running`` while it is recorded or after
    its writer was killed); ``reason`` (why it ended so); ``start_time``, ``end_time``
    (ISO 8601); ``protocol_text`` and ``rig_config_text`` (YAML as run); ``versions``;
    ``has_video``; ``writer_open`` (the file still carries its writer's "open" flag: it
    is being recorded, or its writer was killed); ``live`` (open, and a labrig process
    holds the run's lock: being recorded now).
    """

    def __init__(self, path: Path) -> None:
        # what a run's calls solve is one actuator (its comparison, its plot, a step
        # run's prediction): the model's loops as plain Python, chosen here, before any
        # of them imports the analysis, whose comparison imports the model
        prefer_plain_python()
        self.path = path
        with open_run_file(path) as h5:
            try:
                self._read_metadata(h5["entry"])
            except (KeyError, OSError, ValueError) as exc:
                raise InputError(f"{path}: not a readable labrig run file ({exc})") from None
        if not self.protocol_text:
            raise InputError(f"{path}: missing /entry/protocol")
        self.writer_open, self.live = writer_state(path, self.status)
        if self.writer_open:
            how = (
                "being recorded"
                if self.live
                else "still flagged open, and no process holds it (its writer was killed?)"
            )
            warnings.warn(
                f"{path} is {how}: read as of its last flush (status {self.status!r})"
                + ("" if self.live else f"; `labrig recover {path}` closes a killed run's file"),
                RunOpenWarning,
                stacklevel=3,
            )

    def __repr__(self) -> str:
        flag = " (live)" if self.live else " (writer open)" if self.writer_open else ""
        return (
            f"<labrig.Run {self.path.name}: {self.title!r}, {self.status}{flag}, "
            f"{self.n_repetitions} repetitions>"
        )

    # --- metadata -----------------------------------------------------------------
    def _read_metadata(self, entry) -> None:
        """The metadata and the logs' sizes, from the open file's ``/entry``."""

        def text(name: str) -> str:
            return decode(entry[name][()]) if name in entry else ""

        self.title: str = text("title")
        #: how the run ended: running, complete, aborted or faulted
        self.status: str = text("status") or "unknown"
        #: why it ended so (a tripped interlock names itself); empty when complete
        self.reason: str = text("reason")
        self.start_time: str = text("start_time")
        self.end_time: str = text("end_time")
        #: the protocol's YAML text as run
        self.protocol_text: str = text("protocol")
        self.rig_config_text: str = text("rig_config")
        self.versions: dict[str, str] = (
            {k: decode(v[()]) for k, v in entry["versions"].items()} if "versions" in entry else {}
        )
        if "repetitions" not in entry:
            raise InputError(f"{entry.file.filename}: missing /entry/repetitions")
        reps = entry["repetitions"]
        self._rep_status = [decode(s) for s in reps["status"][()]]
        self._rep_reason = [decode(s) for s in reps["reason"][()]]
        n = len(self._rep_status)
        self._t_start = reps["t_start"][()] if "t_start" in reps else np.full(n, np.nan)
        self._t_end = reps["t_end"][()] if "t_end" in reps else np.full(n, np.nan)
        self._rows: dict[tuple[int, str], int] = {}
        for index in range(1, n + 1):
            group = reps.get(repetition_name(index))
            for log in LOGS if group is not None else ():
                if log in group:
                    self._rows[index, log] = _complete_rows(group[log])
        self.has_video: bool = "video" in entry

    @property
    def complete(self) -> bool:
        """True when the run finished with status ``complete``."""
        return self.status == "complete"

    @cached_property
    def protocol(self) -> Protocol:
        """The protocol as run, validated (``labrig.config.protocol.Protocol``)."""
        from labrig.config.protocol import parse_protocol

        return parse_protocol(self.protocol_text, f"{self.path}:/entry/protocol")

    @property
    def n_repetitions(self) -> int:
        """Repetitions the protocol asks for (each has a status, maybe ``pending``)."""
        return len(self._rep_status)

    @cached_property
    def seed(self) -> int | None:
        """The simulated rig's seed (None for the bench rig)."""
        import yaml

        config = yaml.safe_load(self.rig_config_text or "{}") or {}
        sim = config.get("sim") if isinstance(config, dict) else None
        return int(sim["seed"]) if isinstance(sim, dict) and "seed" in sim else None

    @property
    def metadata(self) -> dict[str, Any]:
        """The run at a glance: file, title, protocol, specimen, times, outcome, flags."""
        return {
            "file": str(self.path),
            "title": self.title,
            "protocol": self.protocol.name,
            "specimen": list(self.protocol.specimen.segments),
            "seed": self.seed,
            "start_time": self.start_time,
            "end_time": self.end_time,
            "status": self.status,
            "reason": self.reason,
            "repetitions": self.n_repetitions,
            "writer_open": self.writer_open,
            "live": self.live,
            "labrig_version": self.versions.get("labrig", ""),
        }

    @property
    def repetitions(self) -> pd.DataFrame:
        """One row per repetition: status, reason, start and end on the run's clock (s),
        and how many samples each log holds so far."""
        import pandas as pd

        n = self.n_repetitions
        table = pd.DataFrame(
            {
                "status": self._rep_status,
                "reason": self._rep_reason,
                "t_start_s": self._t_start,
                "t_end_s": self._t_end,
            },
            index=pd.RangeIndex(1, n + 1, name="repetition"),
        )
        for log in LOGS:
            if any(key[1] == log for key in self._rows):
                table[f"n_{log}"] = [self._rows.get((i, log), 0) for i in range(1, n + 1)]
        return table

    # --- raw series -----------------------------------------------------------------
    def _check(self, repetition: int, log: str) -> None:
        if isinstance(repetition, bool) or not isinstance(repetition, numbers.Integral):
            raise InputError(
                f"{self.path}: repetition {repetition!r}: a whole number, 1 to {self.n_repetitions}"
            )
        if not 1 <= repetition <= self.n_repetitions:
            raise InputError(
                f"{self.path}: repetition {repetition}: the run has 1 to {self.n_repetitions}"
            )
        if (repetition, log) not in self._rows:
            found = sorted(lg for (i, lg) in self._rows if i == repetition)
            raise InputError(
                f"{self.path}: repetition {repetition} has no {log!r} log (it has {found})"
            )

    def _read_log(
        self, repetition: int, log: str, start_s: float | None, stop_s: float | None
    ) -> dict[str, np.ndarray]:
        """The NXlog's fields (NeXus names) over [start_s, stop_s), one read each."""
        self._check(repetition, log)
        n = self._rows[repetition, log]
        where = f"entry/repetitions/{repetition_name(repetition)}/{log}"
        with open_readonly(self.path) as h5:
            group = h5[where]
            times = _Rows(group["time"], n)
            first = 0 if start_s is None else bisect.bisect_left(times, start_s)
            last = n if stop_s is None else bisect.bisect_left(times, stop_s)
            return {name: read_rows(group[name], first, last, self.path) for name in group}

    def raw(
        self,
        repetition: int,
        log: str = "pressure",
        *,
        start_s: float | None = None,
        stop_s: float | None = None,
    ) -> xr.Dataset:
        """One repetition's NXlog (``pressure``, ``pump``, ``length`` or ``force``) as a
        Dataset on its own ``time`` axis (s, the run's clock), its fields under their
        NeXus names (``value`` is the logged quantity: kPa, mL, mm or N), each with its
        ``units``; only the samples in [``start_s``, ``stop_s``) are read."""
        import xarray as xr

        columns = self._read_log(repetition, log, start_s, stop_s)
        where = f"/entry/repetitions/{repetition_name(repetition)}/{log}"
        time_s = columns.pop("time")
        variables = {}
        for name, values in columns.items():
            units = LOG_FIELDS[log].get(name, ("", ""))[1]
            if values.dtype.kind == "S":
                values = values.astype(str)
            attrs = {"units": units, "nexus_path": f"{where}/{name}"}
            if name == "value":
                attrs["long_name"] = LOG_DESCRIPTION[log]
            variables[name] = ("time", values, attrs)
        return xr.Dataset(
            variables,
            coords={"time": ("time", time_s, {"units": "s", "nexus_path": f"{where}/time"})},
            attrs={"nexus_path": where, "repetition": repetition, "log": log},
        )

    def raw_table(
        self,
        repetition: int,
        log: str = "pressure",
        *,
        start_s: float | None = None,
        stop_s: float | None = None,
    ) -> pd.DataFrame:
        """One repetition's log as a DataFrame with the columns of
        ``labrig export --csv`` (``time_s``, ``pressure_kpa``, ...); the pressure log
        also gets ``volume_ml``, the supplied volume aligned as the analysis aligns it."""
        import pandas as pd

        from labrig.analysis.curves import last_reading, pump_path, volume_at
        from labrig.analysis.export import RAW_COLUMNS

        columns = self._read_log(repetition, log, start_s, stop_s)
        table = {"time_s": columns["time"]}
        named = RAW_COLUMNS.get(log, [("value", f"{log}_{LOG_FIELDS[log]['value'][1].lower()}")])
        for field, name in named:
            if field in columns:
                values = columns[field]
                table[name] = values.astype(str) if values.dtype.kind == "S" else values
        if log == "pressure":
            pump = self._read_log(repetition, "pump", None, None)
            before = None
            if repetition > 1 and (repetition - 1, "pump") in self._rows:
                previous = self._read_log(repetition - 1, "pump", None, None)
                before = last_reading(previous["time"], previous["value"])
            path = pump_path(pump["time"], pump["value"], before)
            table["volume_ml"] = volume_at(columns["time"], *path)
        return pd.DataFrame(table)

    # --- the analysis -------------------------------------------------------------
    @cached_property
    def analysis(self) -> AnalysisResult:
        """The analysis the commands show: the one stored in the file, or (a file
        without one: live, killed, analysed never) one computed now, in memory."""
        from labrig.analysis.analyse import analyse
        from labrig.analysis.results import read_analysis
        from labrig.analysis.runfile import load_run

        if not self.writer_open:
            with open_run_file(self.path) as h5:
                stored = read_analysis(self.path, h5)
            if stored is not None:
                return stored
        record = load_run(self.path, open_readonly)
        return analyse(self.path, record=record)

    @property
    def analysis_stored(self) -> bool:
        """Whether the file holds an analysis (the runner stores one after each run)."""
        with open_run_file(self.path) as h5:
            return "entry/analysis" in h5

    @cached_property
    def curves(self) -> xr.Dataset:
        """The repetitions' curves on the analysis's volume grid, their mean and spread
        and the model's: dimensions ``phase`` (inflate, deflate), ``repetition`` and
        ``volume_ml`` (mL); pressure in kPa, length in mm. Names follow
        ``/entry/analysis`` (``pressure_kpa`` per repetition, ``mean_pressure_kpa``,
        ``std_pressure_kpa``, ``model_pressure_kpa``, and the same for length)."""
        import xarray as xr

        from labrig.analysis.curves import PHASES

        result = self.analysis
        grid = result.grid_ml
        reps = result.repetitions
        variables: dict[str, tuple] = {}
        where = "/entry/analysis"
        quantities = (("pressure_kpa", "kPa", "p_kpa"), ("length_mm", "mm", "l_mm"))
        for quantity, units, attr in quantities:
            if all(getattr(r, attr) is not None for r in reps) and reps:
                data = np.array([[getattr(r, attr)[p] for p in PHASES] for r in reps])
                path = f"{where}/repetitions/rep_NN/{{phase}}_{quantity}"
                variables[quantity] = (
                    ("repetition", "phase", "volume_ml"),
                    data,
                    {"units": units, "nexus_path": path},
                )
            means = result.mean_p if quantity == "pressure_kpa" else result.mean_l
            if means is not None:
                std = quantity.replace("_", "_std_")
                for name, values, nexus in (
                    (f"mean_{quantity}", [means[p].mean for p in PHASES], quantity),
                    (f"std_{quantity}", [means[p].std for p in PHASES], std),
                ):
                    variables[name] = (
                        ("phase", "volume_ml"),
                        np.array(values),
                        {"units": units, "nexus_path": f"{where}/mean/{{phase}}_{nexus}"},
                    )
            if result.comparison is not None:
                model = (
                    result.comparison.model_p_kpa
                    if quantity == "pressure_kpa"
                    else result.comparison.model_l_mm
                )
                variables[f"model_{quantity}"] = (
                    ("phase", "volume_ml"),
                    np.array([model[p] for p in PHASES]),
                    {"units": units, "nexus_path": f"{where}/model/{{phase}}_{quantity}"},
                )
        return xr.Dataset(
            variables,
            coords={
                "volume_ml": ("volume_ml", grid, {"units": "mL", "long_name": "supplied volume"}),
                "phase": ("phase", list(PHASES.values())),
                "repetition": ("repetition", [r.index for r in reps]),
                "used_in_mean": ("repetition", [r.used_in_mean for r in reps]),
            },
            attrs={"title": result.title, "averaged": list(result.averaged)},
        )

    def curves_table(self, phase: str = "inflate") -> pd.DataFrame:
        """One phase's curves on the volume grid, as ``curves_<phase>.csv`` of
        ``labrig export --csv``: ``volume_ml``, each repetition's pressure and length,
        ``mean_*``, ``std_*``, ``model_*``, and beside the mean and the model their
        vocabulary names (``pressure_measured_kpa``, ``pressure_model_kpa``, ...)."""
        import pandas as pd

        from labrig.analysis.curves import PHASES
        from labrig.analysis.export import curve_columns

        phases = {name: key for key, name in PHASES.items()}
        if phase not in phases:
            raise InputError(f"phase {phase!r}: one of {', '.join(phases)}")
        return beside(pd.DataFrame(curve_columns(self.analysis, phases[phase])), ALIASES["curves"])

    @property
    def transitions(self) -> pd.DataFrame:
        """Every transition measured in every repetition (``transitions.csv``):
        repetition, direction ("inflate" or "deflate"; the file's +1/-1 as
        ``direction_sign``), t_s (and time_s), v_ml, v_start_ml, v_end_ml, dp_kpa,
        dl_mm, by_pressure, by_length."""
        import pandas as pd

        from labrig.analysis.export import transition_columns

        table = pd.DataFrame(transition_columns(self.analysis))
        return beside(with_direction_names(table), ALIASES["transitions"])

    @property
    def agreed_transitions(self) -> pd.DataFrame:
        """The transitions the averaged repetitions agree on (``/entry/analysis/
        agreed_transitions``): direction (and direction_sign), v_ml and its spread
        v_std_ml, dp_kpa, dl_mm, seen of."""
        import pandas as pd

        from labrig.analysis.transitions import AgreedTransition

        names = [f.name for f in fields(AgreedTransition)]
        rows = [[getattr(t, n) for n in names] for t in self.analysis.transitions]
        return with_direction_names(pd.DataFrame(rows, columns=names))

    def _comparison(self):
        """The analysis's comparison with the model; InputError saying why there is none."""
        result = self.analysis
        if result.comparison is None:
            raise InputError(
                f"{self.path}: no comparison with the model ({'; '.join(result.notes)})"
            )
        return result.comparison

    @cached_property
    def comparison_document(self) -> dict[str, Any]:
        """What ``labrig compare RUN --json`` prints: ``rmse`` (kPa, mm),
        ``transitions`` (the model's path's events, each beside the measured one),
        ``paper_transitions`` (the same counted as the paper counts them),
        ``unpredicted``, ``energy`` (the cycle's stored and dissipated energy, mJ,
        measured and model) and, for step and blocked-force runs, ``steps`` and ``force``
        (those read the finished file: a file still open by its writer has none).
        ``InputError`` when the run has no comparison with the model."""
        from labrig.analysis.report import comparison_json

        result = self.analysis
        self._comparison()  # InputError saying why there is none
        document = comparison_json(result)
        if self.writer_open:
            return document
        from labrig.analysis.experiments import experiment_fields

        return experiment_fields(self.path, document)

    @property
    def comparison(self) -> pd.DataFrame:
        """Each predicted transition beside the measured one paired with it, the rows of
        ``labrig compare --json``'s ``transitions`` (phase, type, alpha, beta, v_ml,
        v_meas_ml, dp_kpa, dp_meas_kpa, dl_mm, dl_meas_mm; NaN where nothing was seen)
        and their energies: the model's ``energy_before_model_mj``,
        ``energy_after_model_mj`` and ``dE_model``, and for an inflation transition the
        one-cycle ``cycle_energy_before_*_mj``, ``cycle_energy_returned_*_mj`` and
        ``cycle_dE_*`` of the measurement and of the model (see "Energy" above); beside
        the JSON's names, the vocabulary's: direction, v_model_ml, v_measured_ml,
        dp_model_kpa, dp_measured_kpa, dl_model_mm, dl_measured_mm."""
        import pandas as pd

        return beside(pd.DataFrame(self.comparison_document["transitions"]), ALIASES["comparison"])

    @property
    def paper_comparison(self) -> pd.DataFrame:
        """``comparison`` with the model's transitions counted as the paper counts them
        (the events at one supplied volume are one): ``labrig compare --json``'s
        ``paper_transitions``."""
        import pandas as pd

        return beside(
            pd.DataFrame(self.comparison_document["paper_transitions"]), ALIASES["comparison"]
        )

    @property
    def rmse(self) -> pd.Series:
        """RMSE of the mean against the model per phase and quantity (kPa, mm)."""
        import pandas as pd

        return pd.Series(self.comparison_document["rmse"], name="rmse", dtype=float)

    @property
    def model_path(self) -> pd.DataFrame:
        """The model's path the run is compared with: volume_ml, pressure_kpa, length_mm
        (with the specimen's fittings, as the markers measure it), direction ("inflate"
        or "deflate") and direction_sign (+1, -1); a snap is two rows at one volume."""
        import pandas as pd

        prediction = self._comparison().prediction
        return with_direction_names(
            pd.DataFrame(
                {
                    "volume_ml": prediction.v_ml,
                    "pressure_kpa": prediction.p_kpa,
                    "length_mm": prediction.l_mm,
                    "direction": prediction.direction,
                }
            )
        )

    # --- video ----------------------------------------------------------------------
    def frame_at(self, t_s: float) -> np.ndarray:
        """The video frame nearest in time to ``t_s`` (s, the run's clock), RGB uint8."""
        from labrig.analysis.frame_strip import read_frames, video_index

        video = video_index(self.path)
        index = video.frame_at(t_s)
        return _rgb(read_frames(video, [index])[index])

    def transition_frames(self) -> list[TransitionFrame]:
        """For each measured transition during the video, the frame just before it
        starts and just after it ends (what ``labrig frames --at-transitions`` shows)."""
        from labrig.analysis.frame_strip import read_frames, transition_tiles, video_index
        from labrig.analysis.runfile import load_run

        video = video_index(self.path)
        tiles = transition_tiles(load_run(self.path, open_readonly), self.analysis, video)
        images = read_frames(video, sorted({t.index for t in tiles}))
        return [
            TransitionFrame(t.label, t.repetition, t.t_s, t.index, _rgb(images[t.index]))
            for t in tiles
        ]

    # --- pictures -------------------------------------------------------------------
    def plot(self, ax: Axes | Sequence[Axes] | None = None) -> Axes | list[Axes]:
        """Draw what ``labrig plot`` draws (mean p-v and l-v with their spread, each
        repetition faint, the model dashed, transitions marked) on ``ax``: one Axes
        (the p-v panel), a sequence of Axes (one per panel), or None (a new figure).
        Returns the Axes drawn on."""
        from labrig.analysis.plot import draw_run, run_panels

        result = self.analysis
        axes, shown = panel_axes(ax, run_panels(result), vertical=True, sharex=True)
        draw_run(axes, result)
        return shown


def _complete_rows(group) -> int:
    """Rows every field of a log holds (a live writer appends field by field)."""
    return min((group[name].shape[0] for name in group), default=0)


def _rgb(image: np.ndarray) -> np.ndarray:
    """OpenCV's BGR frame as RGB (what matplotlib's imshow expects)."""
    return np.ascontiguousarray(image[..., ::-1]) if image.ndim == 3 else image
