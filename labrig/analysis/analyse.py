"""From a run file to its analysis: the steps in order, and the entry point the runner
calls after finalising a run.

``analyse`` computes (nothing is written); ``analyse_run`` computes and stores the
result in the run file (replacing any earlier analysis, so it can be re-run). The
settings come from the protocol stored in the file (``analysis: {average_last,
compare_model}``); the model's segments from its specimen, unless the caller names
others (``labrig compare --segments``); a specimen with no model (``specimen.model:
none``) is compared with nothing unless the caller names segments, and a note says so.
A model that cannot be built (a segment that is
not in the library, a path the solver cannot follow) does not stop the analysis of the
measurement: the comparison is left out and a note says why.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from labrig.analysis.compare import compare, predict
from labrig.analysis.curves import (
    DEFLATE,
    INFLATE,
    PHASES,
    last_reading,
    mean_curve,
    phase_curves,
    pump_path,
    repetitions_to_average,
    volume_grid,
)
from labrig.analysis.results import AnalysisResult, AnalysisSettings, RepetitionAnalysis, stamp
from labrig.analysis.runfile import Repetition, RunRecord, load_run
from labrig.analysis.transitions import agreed_transitions, detect_transitions
from labrig.errors import LabrigError

NO_MODEL_NOTE = (
    "no model to compare with: the specimen has no model (specimen.model: none); "
    "labrig compare RUN --segments SEG compares it with segments you name"
)


def settings_for(record: RunRecord) -> AnalysisSettings:
    analysis = record.protocol.analysis
    return AnalysisSettings(
        average_last=analysis.average_last,
        compare_model=analysis.compare_model and record.protocol.specimen.has_model,
    )


def _pressure(rep: Repetition) -> tuple[np.ndarray, np.ndarray, int]:
    """Pressure samples that are pressures (not flagged beyond the sensor's range)."""
    t, p = rep.pressure.time_s, np.asarray(rep.pressure.fields["value"], dtype=float)
    flagged = rep.pressure.fields.get("out_of_range")
    good = np.isfinite(p) if flagged is None else np.isfinite(p) & ~flagged.astype(bool)
    return t[good], p[good], int(len(p) - np.count_nonzero(good))


def _length(rep: Repetition) -> tuple[np.ndarray, np.ndarray] | None:
    """Length samples where both markers were found."""
    if rep.length is None:
        return None
    ok = rep.length.fields.get("ok")
    lv = np.asarray(rep.length.fields["value"], dtype=float)
    good = np.isfinite(lv) if ok is None else np.isfinite(lv) & ok.astype(bool)
    return rep.length.time_s[good], lv[good]


def _analyse_repetition(
    rep: Repetition,
    grid_ml: np.ndarray,
    settings: AnalysisSettings,
    used: bool,
    pump_before: tuple[float, float] | None,
) -> RepetitionAnalysis:
    pt, p, n_flagged = _pressure(rep)
    pump_t, pump_v = pump_path(rep.pump.time_s, rep.pump.fields["value"], pump_before)
    length = _length(rep)
    moving = len(pump_t) >= 2
    p_curves = (
        phase_curves(grid_ml, pt, p, pump_t, pump_v, settings.max_gap_ml)
        if moving
        else {phase: np.full(len(grid_ml), np.nan) for phase in PHASES}
    )
    l_curves = None
    if length is not None:
        l_curves = (
            phase_curves(grid_ml, *length, pump_t, pump_v, settings.max_gap_ml)
            if moving
            else {phase: np.full(len(grid_ml), np.nan) for phase in PHASES}
        )
    found = detect_transitions(
        rep.index, pt, p, pump_t, pump_v,
        *(length if length is not None else (None, None)),
        settings=settings.detection,
    )  # fmt: skip
    times = np.concatenate([pt, pump_t])
    inflation = p_curves[INFLATE]
    return RepetitionAnalysis(
        index=rep.index,
        status=rep.status,
        reason=rep.reason,
        used_in_mean=used,
        duration_s=float(np.ptp(times)) if len(times) else float("nan"),
        n_pressure=len(rep.pressure.time_s),
        n_out_of_range=n_flagged,
        v_max_ml=float(np.max(pump_v)) if len(pump_v) else float("nan"),
        # from the curve on the grid: the raw 1 kHz maximum would be the noise's
        p_max_kpa=float(np.nanmax(inflation)) if np.any(np.isfinite(inflation)) else np.nan,
        l_min_mm=float(np.min(length[1])) if length is not None and len(length[1]) else np.nan,
        l_max_mm=float(np.max(length[1])) if length is not None and len(length[1]) else np.nan,
        p_kpa=p_curves,
        l_mm=l_curves,
        transitions=tuple(found),
    )


def analyse(
    path: str | Path,
    *,
    segments: Sequence[str] | None = None,
    library_dir: Path | None = None,
    settings: AnalysisSettings | None = None,
    record: RunRecord | None = None,
) -> AnalysisResult:
    """The analysis of the run file at ``path`` (nothing is written)."""
    record = record or load_run(path)
    settings = settings or settings_for(record)
    notes: list[str] = []
    v_max = max(
        (float(np.max(rep.pump.fields["value"])) for rep in record.repetitions if len(rep.pump)),
        default=0.0,
    )
    grid_ml = volume_grid(v_max, settings.grid_step_ml)
    statuses = [rep.status for rep in record.repetitions]
    averaged = repetitions_to_average(statuses, settings.average_last)
    if len(averaged) < settings.average_last:
        complete = statuses.count("complete")
        notes.append(
            f"mean of {len(averaged)} repetition(s): only {complete} of {len(statuses)} "
            f"completed (the protocol asks for the last {settings.average_last})"
        )
    reps = []
    pump_before = None  # the previous repetition's last pump reading
    for rep in record.repetitions:
        reps.append(_analyse_repetition(rep, grid_ml, settings, rep.index in averaged, pump_before))
        pump_before = last_reading(rep.pump.time_s, rep.pump.fields["value"]) or pump_before
    reps = tuple(reps)
    chosen = [r for r in reps if r.index in averaged]
    mean_p = mean_l = None
    if chosen:
        mean_p = {phase: mean_curve([r.p_kpa[phase] for r in chosen]) for phase in PHASES}
        if all(r.l_mm is not None for r in chosen):
            mean_l = {phase: mean_curve([r.l_mm[phase] for r in chosen]) for phase in PHASES}
    agreed = tuple(
        agreed_transitions(
            [t for r in reps for t in r.transitions], averaged, settings.detection.cluster_ml
        )
    )
    comparison = None
    wanted = segments is not None or settings.compare_model
    if wanted and mean_p is not None:
        comparison, note = _comparison(
            record, segments, library_dir, grid_ml, mean_p, mean_l, agreed, settings, v_max
        )
        if note:
            notes.append(note)
    elif wanted:
        notes.append("no comparison with the model: no repetition completed")
    elif not record.protocol.specimen.has_model:
        notes.append(NO_MODEL_NOTE)
    created, version = stamp()
    return AnalysisResult(
        source=record.path,
        title=record.title,
        run_status=record.status,
        created=created,
        labrig_version=version,
        settings=settings,
        grid_ml=grid_ml,
        repetitions=reps,
        averaged=tuple(averaged),
        mean_p=mean_p,
        mean_l=mean_l,
        transitions=agreed,
        comparison=comparison,
        notes=tuple(notes),
    )


def _comparison(record, segments, library_dir, grid_ml, mean_p, mean_l, agreed, settings, v_max):
    from labrig.model.segments.catalog import load_segment

    names = list(segments) if segments is not None else list(record.protocol.specimen.segments)
    deflate = bool(np.any(np.isfinite(mean_p[DEFLATE].mean)))
    try:
        curves = [load_segment(name, library_dir=library_dir) for name in names]
        prediction = predict(curves, record.protocol.specimen.fittings_length_mm, v_max, deflate)
    except LabrigError as exc:
        if segments is not None:
            raise
        return None, f"no comparison with the model: {exc}"
    mean_l_curves = None if mean_l is None else {p: mean_l[p].mean for p in PHASES}
    mean_p_curves = {p: mean_p[p].mean for p in PHASES}
    result = compare(prediction, grid_ml, mean_p_curves, mean_l_curves, agreed, settings.match_ml)
    return result, None


def analyse_run(path: str | Path, **options) -> AnalysisResult:
    """Analyse the run file at ``path`` and store the result in it (``/entry/analysis``
    and the default plot ``/entry/data``), replacing any earlier analysis. What the
    runner calls after finalising a run; ``summary_text`` prints it."""
    from labrig.analysis.results import write_analysis

    result = analyse(path, **options)
    write_analysis(Path(path), result)
    return result
