"""The analysis of a run as data, and its place in the run file (``/entry/analysis``).

``AnalysisResult`` is everything the review commands show: the per-repetition curves on
the common volume grid with their key figures and transitions, the mean and spread of
the averaged repetitions, the transitions they agree on, and the comparison with the
model. ``write_analysis`` stores it in the run file, replacing any earlier analysis, and
makes the averaged pressure-volume curve the file's NeXus default plot (``/entry/data``,
the model as auxiliary signal); ``read_analysis`` reads it back. Tables are stored
NeXus-style, one 1-D dataset per column with a ``units`` attribute, so that any HDF5
tool reads them; docs/reference/run-file.md describes the layout.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from labrig._version import __version__
from labrig.analysis.compare import (
    Comparison,
    PredictedTransition,
    Prediction,
    TransitionMatch,
    follows_model,
    match_transitions,
    paper_counted,
)
from labrig.analysis.curves import PHASES, MeanCurve
from labrig.analysis.transitions import AgreedTransition, DetectionSettings, MeasuredTransition
from labrig.errors import InputError
from labrig.recording.file_check import vouch_for
from labrig.recording.run_layout import repetition_name
from labrig.recording.unwritable import abandon, room_to_write

LAYOUT_VERSION = 1
UNITS = {"_ml": "mL", "_kpa": "kPa", "_mm": "mm", "_s": "s", "_ml_s": "mL/s"}
STRINGS = h5py.string_dtype()


@dataclass(frozen=True)
class AnalysisSettings:
    """What the analysis was asked to do (the protocol's ``analysis`` section plus the
    grid, the gap limit, the matching tolerance and the detector's settings)."""

    average_last: int = 4
    compare_model: bool = True
    grid_step_ml: float = 0.05
    max_gap_ml: float = 1.0
    match_ml: float = 2.0
    detection: DetectionSettings = field(default_factory=DetectionSettings)


@dataclass(frozen=True)
class RepetitionAnalysis:
    """One repetition: status, key figures, curves on the grid, transitions.

    ``p_kpa`` and ``l_mm`` map a phase (+1 inflation, -1 deflation) to its curve on the
    grid; ``l_mm`` is None without a camera; figures that cannot be had are NaN.
    """

    index: int
    status: str
    reason: str
    used_in_mean: bool
    duration_s: float
    n_pressure: int
    n_out_of_range: int
    v_max_ml: float
    p_max_kpa: float
    l_min_mm: float
    l_max_mm: float
    p_kpa: dict[int, np.ndarray]
    l_mm: dict[int, np.ndarray] | None
    transitions: tuple[MeasuredTransition, ...]

    @property
    def name(self) -> str:
        return repetition_name(self.index)


@dataclass(frozen=True)
class AnalysisResult:
    source: Path
    title: str
    run_status: str
    created: str
    labrig_version: str
    settings: AnalysisSettings
    grid_ml: np.ndarray
    repetitions: tuple[RepetitionAnalysis, ...]
    averaged: tuple[int, ...]
    mean_p: dict[int, MeanCurve] | None
    mean_l: dict[int, MeanCurve] | None
    transitions: tuple[AgreedTransition, ...]
    comparison: Comparison | None
    notes: tuple[str, ...]

    @property
    def with_length(self) -> bool:
        return self.mean_l is not None or any(r.l_mm is not None for r in self.repetitions)

    def on_the_models_curve(self, measured) -> bool:
        """Whether the model's own path makes a measured transition (a steep stable
        stretch, ``compare.follows_model``); False without a comparison."""
        if self.comparison is None or self.mean_p is None:
            return False
        mean_p = {phase: curve.mean for phase, curve in self.mean_p.items()}
        return follows_model(self.comparison, self.grid_ml, mean_p, measured)

    @property
    def steep_stretches(self) -> list[AgreedTransition]:
        """The averaged transitions no predicted snap explains but the model's path makes."""
        if self.comparison is None:
            return []
        return [
            m.measured
            for m in self.comparison.matches
            if m.predicted is None and self.on_the_models_curve(m.measured)
        ]


def now_iso() -> str:
    return dt.datetime.now(dt.UTC).isoformat(timespec="seconds")


# --- writing ------------------------------------------------------------------------
def _units_of(name: str) -> str:
    for suffix in sorted(UNITS, key=len, reverse=True):
        if name.endswith(suffix):
            return UNITS[suffix]
    return ""


def _dataset(group: h5py.Group, name: str, data, units: str | None = None) -> h5py.Dataset:
    if isinstance(data, str):
        return group.create_dataset(name, data=data, dtype=STRINGS)
    if isinstance(data, list | tuple) and (not data or isinstance(data[0], str)):
        return group.create_dataset(name, data=np.array(data, dtype=object), dtype=STRINGS)
    dataset = group.create_dataset(name, data=data)
    units = _units_of(name) if units is None else units
    if units:
        dataset.attrs["units"] = units
    return dataset


def _table(parent: h5py.Group, name: str, cls, rows) -> h5py.Group:
    """A table of dataclass rows as one column dataset per field."""
    group = parent.create_group(name)
    group.attrs["NX_class"] = "NXcollection"
    for f in dataclasses.fields(cls):
        values = [getattr(row, f.name) for row in rows]
        kind = {"int": np.int64, "float": np.float64, "bool": np.bool_}.get(str(f.type))
        if kind is None:
            raise TypeError(f"cannot store {cls.__name__}.{f.name} of type {f.type}")
        _dataset(group, f.name, np.array(values, dtype=kind))
    return group


def _curves(group: h5py.Group, prefix_quantity: str, curves: dict[int, np.ndarray]) -> None:
    for phase, name in PHASES.items():
        _dataset(group, f"{name}_{prefix_quantity}", curves[phase])


def _settings(group: h5py.Group, settings: AnalysisSettings) -> None:
    for f in dataclasses.fields(settings):
        if f.name != "detection":
            _dataset(group, f.name, getattr(settings, f.name))
    detection = group.create_group("detection")
    for f in dataclasses.fields(settings.detection):
        _dataset(detection, f.name, getattr(settings.detection, f.name))


# what an analysis may take in the file, asked of the disk before it is written: it is
# a few hundred kB, and a write cut short in HDF5's metadata spoils the whole file
ANALYSIS_ROOM_BYTES = 8_000_000


def write_analysis(path: Path, result: AnalysisResult) -> None:
    """Store ``result`` in the run file at ``path``, replacing any earlier analysis and
    default plot. The file must be closed by its writer (``labrig recover`` otherwise)."""
    room_to_write(path, ANALYSIS_ROOM_BYTES, "the analysis")
    try:
        run = h5py.File(path, "r+")
    except OSError as exc:
        raise InputError(
            f"{path}: cannot be opened for writing the analysis ({exc}); if a killed run "
            f"left it flagged open, `labrig recover {path}` clears that"
        ) from None
    try:
        if "entry" not in run:
            run.close()
            raise InputError(f"{path}: not a labrig run file: missing /entry")
        entry = run["entry"]
        for name in ("analysis", "data"):
            if name in entry:
                del entry[name]
        _write(entry, result)
        run.close()
    except (OSError, RuntimeError) as exc:  # the disk filled meanwhile
        abandon(run.id)
        raise InputError(
            f"{path}: the analysis could not be stored (the file could not be written: "
            f"{type(exc).__name__})"
        ) from None
    vouch_for(path)  # read before, written here: no reader needs to walk it again


def _write(entry: h5py.Group, result: AnalysisResult) -> None:
    group = entry.create_group("analysis")
    group.attrs.update(
        NX_class="NXprocess",
        program="labrig",
        version=result.labrig_version,
        date=result.created,
        layout_version=LAYOUT_VERSION,
    )
    _dataset(group, "notes", list(result.notes))
    parameters = group.create_group("parameters")
    parameters.attrs["NX_class"] = "NXparameters"
    _settings(parameters, result.settings)
    _dataset(group, "volume_ml", result.grid_ml)

    reps = group.create_group("repetitions")
    reps.attrs["NX_class"] = "NXcollection"
    for name in (
        "index",
        "used_in_mean",
        "duration_s",
        "n_pressure",
        "n_out_of_range",
        "v_max_ml",
        "p_max_kpa",
        "l_min_mm",
        "l_max_mm",
    ):
        _dataset(reps, name, np.array([getattr(r, name) for r in result.repetitions]))
    _dataset(reps, "status", [r.status for r in result.repetitions])
    _dataset(reps, "reason", [r.reason for r in result.repetitions])
    for rep in result.repetitions:
        curves = reps.create_group(repetition_name(rep.index))
        curves.attrs["NX_class"] = "NXcollection"
        _curves(curves, "pressure_kpa", rep.p_kpa)
        if rep.l_mm is not None:
            _curves(curves, "length_mm", rep.l_mm)
    measured = [t for rep in result.repetitions for t in rep.transitions]
    _table(group, "transitions", MeasuredTransition, measured)

    mean = group.create_group("mean")
    mean.attrs["NX_class"] = "NXcollection"
    _dataset(mean, "repetitions", np.array(result.averaged, dtype=np.int64))
    for quantity, curves in (("pressure_kpa", result.mean_p), ("length_mm", result.mean_l)):
        if curves is None:
            continue
        _curves(mean, quantity, {phase: curves[phase].mean for phase in PHASES})
        _curves(mean, quantity.replace("_", "_std_"), {p: curves[p].std for p in PHASES})
    _table(group, "agreed_transitions", AgreedTransition, result.transitions)

    if result.comparison is not None:
        _write_model(group, result.comparison, result.transitions)
    _write_default_plot(entry, group, result)


def _write_model(group: h5py.Group, comparison: Comparison, agreed) -> None:
    model = group.create_group("model")
    model.attrs["NX_class"] = "NXcollection"
    prediction = comparison.prediction
    _dataset(model, "segments", list(prediction.segments))
    _dataset(model, "sources", list(prediction.sources))
    path = model.create_group("path")
    path.attrs["NX_class"] = "NXcollection"
    _dataset(path, "volume_ml", prediction.v_ml)
    _dataset(path, "pressure_kpa", prediction.p_kpa)
    _dataset(path, "length_mm", prediction.l_mm)
    _dataset(path, "direction", prediction.direction)
    _curves(model, "pressure_kpa", comparison.model_p_kpa)
    _curves(model, "length_mm", comparison.model_l_mm)
    rmse = model.create_group("rmse")
    rmse.attrs["NX_class"] = "NXcollection"
    for phase, name in PHASES.items():
        _dataset(rmse, f"{name}_pressure_kpa", comparison.rmse_p_kpa[phase])
        _dataset(rmse, f"{name}_length_mm", comparison.rmse_l_mm[phase])
    _table(model, "transitions", PredictedTransition, prediction.transitions)
    matches = model.create_group("matches")
    matches.attrs["NX_class"] = "NXcollection"
    matches.attrs["match_ml"] = comparison.match_ml
    predicted_index = [
        -1 if m.predicted is None else prediction.transitions.index(m.predicted)
        for m in comparison.matches
    ]
    measured_index = [
        -1 if m.measured is None else agreed.index(m.measured) for m in comparison.matches
    ]
    _dataset(matches, "direction", np.array([m.direction for m in comparison.matches], np.int64))
    _dataset(matches, "predicted", np.array(predicted_index, dtype=np.int64))
    _dataset(matches, "measured", np.array(measured_index, dtype=np.int64))


def _write_default_plot(entry: h5py.Group, analysis: h5py.Group, result: AnalysisResult) -> None:
    """/entry/data: the mean inflation p-v with its spread, the model as auxiliary signal
    (hard links into /entry/analysis, so nothing is stored twice)."""
    if result.mean_p is None:
        return
    data = entry.create_group("data")
    signals = []
    data["volume_ml"] = analysis["volume_ml"]
    data["pressure_kpa"] = analysis["mean/inflate_pressure_kpa"]
    data["pressure_kpa_errors"] = analysis["mean/inflate_pressure_std_kpa"]
    if "model" in analysis:
        data["model_pressure_kpa"] = analysis["model/inflate_pressure_kpa"]
        signals.append("model_pressure_kpa")
    data.attrs.update(NX_class="NXdata", signal="pressure_kpa", axes=["volume_ml"])
    if signals:
        data.attrs["auxiliary_signals"] = signals
    data.attrs["title"] = f"{result.title}: mean of repetitions {list(result.averaged)}"


# --- reading ------------------------------------------------------------------------
def _value(dataset: h5py.Dataset):
    value = dataset[()]
    if isinstance(value, bytes):
        return value.decode()
    if isinstance(value, np.ndarray) and value.dtype.kind in "OS":
        return [v.decode() if isinstance(v, bytes) else str(v) for v in value]
    return value.item() if isinstance(value, np.generic) else value


def _read_table(group: h5py.Group, cls) -> list:
    """The rows of ``cls`` stored by ``_table``; a field with a default may be missing
    (a file written before the field was kept) and takes its default."""
    columns = {f.name: group[f.name][()] for f in dataclasses.fields(cls) if f.name in group}
    count = len(next(iter(columns.values()))) if columns else 0
    return [
        cls(**{name: values[k].item() for name, values in columns.items()}) for k in range(count)
    ]


def _read_curves(group: h5py.Group, quantity: str) -> dict[int, np.ndarray] | None:
    names = {phase: f"{name}_{quantity}" for phase, name in PHASES.items()}
    if not all(name in group for name in names.values()):
        return None
    return {phase: group[name][()] for phase, name in names.items()}


def _read_settings(group: h5py.Group) -> AnalysisSettings:
    stored = group["detection"]
    detection_fields = {f.name for f in dataclasses.fields(DetectionSettings)}
    detection = DetectionSettings(
        **{name: _value(stored[name]) for name in stored if name in detection_fields}
    )
    known = {f.name for f in dataclasses.fields(AnalysisSettings)} - {"detection"}
    values = {name: _value(group[name]) for name in group if name in known}
    return AnalysisSettings(**values, detection=detection)


def read_analysis(path: Path, run: h5py.File) -> AnalysisResult | None:
    """The analysis stored in an open run file, or None if it has none."""
    if "entry/analysis" not in run:
        return None
    group = run["entry/analysis"]
    try:
        return _read(path, run["entry"], group)
    except (KeyError, ValueError, TypeError, OSError) as exc:
        raise InputError(
            f"{path}: the stored analysis (/entry/analysis) is damaged or from another "
            f"version ({exc}); re-run it with `labrig compare {path} --store`"
        ) from None


def _read(path: Path, entry: h5py.Group, group: h5py.Group) -> AnalysisResult:
    settings = _read_settings(group["parameters"])
    reps = group["repetitions"]
    measured = _read_table(group["transitions"], MeasuredTransition)
    statuses, reasons = _value(reps["status"]), _value(reps["reason"])
    repetitions = []
    for k, index in enumerate(reps["index"][()]):
        index = int(index)
        curves = reps[repetition_name(index)]
        repetitions.append(
            RepetitionAnalysis(
                index=index,
                status=statuses[k],
                reason=reasons[k],
                used_in_mean=bool(reps["used_in_mean"][k]),
                duration_s=float(reps["duration_s"][k]),
                n_pressure=int(reps["n_pressure"][k]),
                n_out_of_range=int(reps["n_out_of_range"][k]),
                v_max_ml=float(reps["v_max_ml"][k]),
                p_max_kpa=float(reps["p_max_kpa"][k]),
                l_min_mm=float(reps["l_min_mm"][k]),
                l_max_mm=float(reps["l_max_mm"][k]),
                p_kpa=_read_curves(curves, "pressure_kpa"),
                l_mm=_read_curves(curves, "length_mm"),
                transitions=tuple(t for t in measured if t.repetition == index),
            )
        )
    mean = group["mean"]

    def mean_curves(quantity: str) -> dict[int, MeanCurve] | None:
        means = _read_curves(mean, quantity)
        spreads = _read_curves(mean, quantity.replace("_", "_std_"))
        if means is None or spreads is None:
            return None
        return {phase: MeanCurve(means[phase], spreads[phase]) for phase in PHASES}

    agreed = tuple(_read_table(group["agreed_transitions"], AgreedTransition))
    return AnalysisResult(
        source=path,
        title=_value(entry["title"]) if "title" in entry else "",
        run_status=_value(entry["status"]) if "status" in entry else "unknown",
        created=str(group.attrs.get("date", "")),
        labrig_version=str(group.attrs.get("version", "")),
        settings=settings,
        grid_ml=group["volume_ml"][()],
        repetitions=tuple(repetitions),
        averaged=tuple(int(i) for i in mean["repetitions"][()]),
        mean_p=mean_curves("pressure_kpa"),
        mean_l=mean_curves("length_mm"),
        transitions=agreed,
        comparison=_read_model(group["model"], agreed) if "model" in group else None,
        notes=tuple(_value(group["notes"])),
    )


def _read_model(model: h5py.Group, agreed: tuple[AgreedTransition, ...]) -> Comparison:
    path = model["path"]
    predicted = tuple(_read_table(model["transitions"], PredictedTransition))
    prediction = Prediction(
        segments=tuple(_value(model["segments"])),
        sources=tuple(_value(model["sources"])),
        v_ml=path["volume_ml"][()],
        p_kpa=path["pressure_kpa"][()],
        l_mm=path["length_mm"][()],
        direction=path["direction"][()],
        transitions=predicted,
    )
    rmse = model["rmse"]
    matches = model["matches"]
    rows = tuple(
        TransitionMatch(
            int(direction),
            predicted[i] if i >= 0 else None,
            agreed[j] if j >= 0 else None,
        )
        for direction, i, j in zip(
            matches["direction"][()], matches["predicted"][()], matches["measured"][()], strict=True
        )
    )
    return Comparison(
        prediction=prediction,
        model_p_kpa=_read_curves(model, "pressure_kpa"),
        model_l_mm=_read_curves(model, "length_mm"),
        rmse_p_kpa={p: float(rmse[f"{n}_pressure_kpa"][()]) for p, n in PHASES.items()},
        rmse_l_mm={p: float(rmse[f"{n}_length_mm"][()]) for p, n in PHASES.items()},
        matches=rows,
        match_ml=float(matches.attrs["match_ml"]),
        paper_matches=match_transitions(
            paper_counted(predicted), agreed, float(matches.attrs["match_ml"])
        ),
    )


def stamp() -> tuple[str, str]:
    """(creation time, labrig version) recorded with an analysis."""
    return now_iso(), __version__
