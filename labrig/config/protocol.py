"""Protocols: the YAML files a technician runs, validated before anything moves.

A protocol is data, never code: it is read with ``yaml.safe_load`` and checked against a
strict schema (unknown keys are errors). Every error names the file, the key path and
the line, and says what is allowed, so a typo is fixed at the bench in seconds.

Steps are single-key mappings::

    steps:
      - zero_pressure: {}
      - repeat: {times: 5, steps: [{infuse: {rate_ml_min: 20, volume_ml: 45}},
                                   {hold: {seconds: 5}},
                                   {withdraw: {rate_ml_min: 20, volume_ml: 45}}]}

``volume_ml`` of ``infuse``/``withdraw`` is the volume that step moves. A repetition is
one pass through a ``repeat`` block (or one run of consecutive top-level actuation
steps); the analysis averages the last repetitions.

The step experiments (a fast volume step, the actuation time, the blocked force) add a
technician ``prompt`` (Enter to go on; ``connect`` says whether the specimen is then on
the pump or on a small reservoir) and a ``reservoir`` step that pushes a small volume
in quickly; the specimen's ``fluid`` (water or air), an optional ``air_reservoir_ml``
and a ``length: blocked`` (a load cell holds the actuator's ends) describe the set-up.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, Discriminator, Field, Tag, field_validator, model_validator

from labrig.config.yaml_schema import Line, Strict, Text, parse_yaml_model
from labrig.user_files import MAX_CONFIG_BYTES, read_text_file

STEP_KINDS = ("zero_pressure", "infuse", "withdraw", "hold", "prompt", "reservoir", "repeat")


# a name becomes part of the run file's name (at most 255 bytes on most file systems)
MAX_NAME_CHARS = 200
MAX_PATH_CHARS = 1000
MAX_TEXT_CHARS = 10_000

# Bounds a rig can honour, so that a protocol that validates can start, be recorded,
# read back and analysed (each is checked again against the rig by the dry run).
# The PHD ULTRA's rates over the syringes a rig file accepts (0.1 to 50 mm inner
# diameter: 1.6e-9 to 423 mL/min); the dry run checks the rig's own syringe.
MIN_RATE_ML_MIN = 1e-9
MAX_RATE_ML_MIN = 500.0
# the largest syringe a PHD ULTRA holds (pump.syringe.volume_ml)
MAX_VOLUME_ML = 140.0
# a hold of a week at most: a longer one is no step of a run a person watches
MAX_HOLD_S = 7 * 24 * 3600.0
# The pressure is read every 0.2 s and a signal with no sample for 0.5 s
# (signal_timeout_s) is a dead device: 10 Hz gives every read two samples.
MIN_PRESSURE_RATE_HZ = 10.0
# A camera's first frame must come within 3 s of its start and the markers-lost
# interlock allows 10 s: below 1 frame per second a healthy camera faults the run.
MIN_CAMERA_FPS = 1.0
# The run's pressure samples (duration x rate): nine tenths of what a reader reads
# whole (labrig.recording.run_reader.MAX_DATASET_VALUES, 250 million), the tenth left
# for what a run adds to its plan (waiting for the first readings, a pump's start).
MAX_PRESSURE_SAMPLES = 225_000_000
# The run file lays out every repetition before the first sample: 1000 take about
# 13 s on a busy 2-core machine (10,000: two minutes).
MAX_REPETITIONS = 1000


NO_MODEL = "none"


class Specimen(Strict):
    segments: list[Annotated[Line, Field(max_length=MAX_PATH_CHARS)]] = Field(
        min_length=1,
        description="Segments in the actuator: library names (B46-T20), measured segments "
        "or CSV paths; with model: none, the lab's own labels (LAB-S37)",
    )
    model: Literal["segments", "none"] = Field(
        "segments",
        description="segments: the model is built from the segments' names (each must "
        "name one); none: the specimen has no model yet, its segments are labels "
        "(no predicted peak, no comparison)",
    )
    fittings_length_mm: float = Field(
        0.0, ge=0, description="Length added by couplings between the markers, in mm"
    )
    fluid: Literal["water", "air"] = Field(
        "water", description="The working fluid in the specimen and the lines"
    )
    air_reservoir_ml: float = Field(
        0.0,
        ge=0,
        le=500,
        description="A rigid air volume on the specimen's inlet (mL); stores energy that "
        "speeds a snap up (air only)",
    )
    length: Literal["free", "blocked"] = Field(
        "free",
        description="free: the actuator elongates; blocked: its ends are held at their "
        "unpressurised distance and a load cell reads the reaction force",
    )

    @property
    def has_model(self) -> bool:
        """Whether the model is built from the segments (``model: segments``)."""
        return self.model != NO_MODEL

    @model_validator(mode="after")
    def _reservoir_holds_air(self) -> Specimen:
        if self.air_reservoir_ml > 0 and self.fluid != "air":
            raise ValueError(
                f"air_reservoir_ml: {self.air_reservoir_ml:g} needs fluid: air "
                f"(the specimen's fluid is {self.fluid})"
            )
        return self


class Limits(Strict):
    max_pressure_kpa: float = Field(
        gt=0, le=100, description="Interlock: stop the pump above this pressure (kPa)"
    )
    max_volume_ml: float = Field(
        gt=0,
        le=MAX_VOLUME_ML,
        description="Interlock: stop the pump above this volume in the specimen (mL)",
    )


class Acquisition(Strict):
    pressure_rate_hz: float = Field(
        1000.0,
        ge=MIN_PRESSURE_RATE_HZ,
        le=48000,
        description="DAQ sample rate; the USB-6009 allows 48 kS/s in total",
    )
    camera_fps: float = Field(
        0.0, ge=0, le=60, description="Camera frames per second, 1 to 60; 0 means no camera"
    )
    video: bool = Field(
        False, description="Record the camera's frames to RUN.avi beside the run file"
    )

    @field_validator("camera_fps")
    @classmethod
    def _camera_fast_enough(cls, fps: float) -> float:
        if 0 < fps < MIN_CAMERA_FPS:
            raise ValueError(
                f"{fps:g} frames per second is too few: a camera's first frame must come "
                f"within 3 s of its start; 0 (no camera) or {MIN_CAMERA_FPS:g} to 60"
            )
        return fps

    @model_validator(mode="after")
    def _video_needs_camera(self) -> Acquisition:
        """`video: true` needs a camera (`camera_fps` above 0)."""
        if self.video and self.camera_fps == 0:
            raise ValueError("video: true needs a camera (camera_fps > 0)")
        return self


class Analysis(Strict):
    average_last: int = Field(4, ge=1, description="Average this many final repetitions")
    compare_model: bool = Field(True, description="Compare the measurement with the model")


class ZeroPressureParams(Strict):
    duration_s: float = Field(
        2.0, gt=0, le=60, description="Averaging time at atmospheric pressure"
    )


class FlowParams(Strict):
    rate_ml_min: float = Field(
        ge=MIN_RATE_ML_MIN,
        le=MAX_RATE_ML_MIN,
        description="Flow rate in mL/min (the dry run checks the rig's syringe)",
    )
    volume_ml: float = Field(gt=0, le=MAX_VOLUME_ML, description="Volume this step moves, in mL")


class HoldParams(Strict):
    seconds: float = Field(
        ge=0, le=MAX_HOLD_S, description="Time to hold at constant volume (a week at most)"
    )


class PromptParams(Strict):
    message: Text = Field(
        min_length=1,
        max_length=MAX_TEXT_CHARS,
        description="What the technician does, then Enter",
    )
    connect: Literal["pump", "reservoir"] | None = Field(
        None,
        description="What the specimen is connected to once the technician is done "
        "(the simulated rig switches its plumbing accordingly); omit for no change",
    )


class ReservoirParams(Strict):
    volume_ml: float = Field(
        gt=0, le=5, description="Volume pushed in from the small reservoir, in mL"
    )
    duration_s: float = Field(
        0.1, gt=0, le=10, description="How long the push takes (a quick push: 0.1 s)"
    )


class ZeroPressureStep(Strict):
    zero_pressure: ZeroPressureParams


class InfuseStep(Strict):
    infuse: FlowParams


class WithdrawStep(Strict):
    withdraw: FlowParams


class HoldStep(Strict):
    hold: HoldParams


class PromptStep(Strict):
    prompt: PromptParams


class ReservoirStep(Strict):
    reservoir: ReservoirParams


def _step_kind(value: Any) -> str | None:
    if isinstance(value, dict) and len(value) == 1:
        key = next(iter(value))
        return key if key in STEP_KINDS else None
    if isinstance(value, BaseModel):
        return next(iter(type(value).model_fields))
    return None


Step = Annotated[
    Annotated[ZeroPressureStep, Tag("zero_pressure")]
    | Annotated[InfuseStep, Tag("infuse")]
    | Annotated[WithdrawStep, Tag("withdraw")]
    | Annotated[HoldStep, Tag("hold")]
    | Annotated[PromptStep, Tag("prompt")]
    | Annotated[ReservoirStep, Tag("reservoir")]
    | Annotated["RepeatStep", Tag("repeat")],
    Discriminator(
        _step_kind,
        custom_error_type="step_kind",
        custom_error_message=("a step is a mapping with exactly one key: " + ", ".join(STEP_KINDS)),
    ),
]


class RepeatParams(Strict):
    times: int = Field(ge=1, le=1000, description="How many repetitions")
    steps: list[Step] = Field(
        min_length=1, description="The steps of one repetition (no repeat inside a repeat)"
    )

    @model_validator(mode="after")
    def _no_nesting(self) -> RepeatParams:
        """A repeat holds no other repeat."""
        if any(isinstance(step, RepeatStep) for step in self.steps):
            raise ValueError("a repeat cannot contain another repeat")
        return self


class RepeatStep(Strict):
    repeat: RepeatParams


class Protocol(Strict):
    """A validated protocol (the schema behind ``labrig protocol schema``)."""

    name: Line = Field(
        min_length=1,
        max_length=MAX_NAME_CHARS,
        description="Title of the run; it names the run file",
    )
    description: Text = Field(
        "", max_length=MAX_TEXT_CHARS, description="Free text, stored with the run"
    )
    specimen: Specimen = Field(description="What is inflated")
    rig: Line = Field(
        "sim",
        max_length=MAX_PATH_CHARS,
        description="'sim' or the path of a rig YAML file, relative to the protocol",
    )
    limits: Limits = Field(description="The interlocks' ceilings")
    acquisition: Acquisition = Field(Acquisition(), description="What is recorded, how often")
    steps: list[Step] = Field(min_length=1, description="What the pump does, in order")
    analysis: Analysis = Field(Analysis(), description="What the analysis after the run does")

    @model_validator(mode="after")
    def _recordable(self) -> Protocol:
        """The run's repetitions and its pressure samples (duration x
        `pressure_rate_hz`) fit in a run file that can be read back and analysed."""
        summary = plan(self)
        if summary.repetitions > MAX_REPETITIONS:
            raise ValueError(
                f"the steps make {summary.repetitions} repetitions, more than "
                f"{MAX_REPETITIONS}: the run file lays out each before the first sample"
            )
        rate_hz = self.acquisition.pressure_rate_hz
        samples = summary.duration_s * rate_hz
        if samples > MAX_PRESSURE_SAMPLES:
            raise ValueError(
                f"the run takes {summary.duration_s / 3600:.4g} h at "
                f"acquisition.pressure_rate_hz {rate_hz:g}: {samples:.3g} pressure samples, "
                f"more than the {MAX_PRESSURE_SAMPLES:,} a run file is read back with; at "
                f"{rate_hz:g} Hz a run lasts at most {MAX_PRESSURE_SAMPLES / rate_hz / 3600:.4g} h"
            )
        return self

    @model_validator(mode="after")
    def _comparison_needs_a_model(self) -> Protocol:
        """`analysis.compare_model: true` written out contradicts `specimen.model:
        none` (left out, the comparison is simply not made)."""
        if (
            self.specimen.model == NO_MODEL
            and self.analysis.compare_model
            and "compare_model" in self.analysis.model_fields_set
        ):
            raise ValueError(
                "analysis.compare_model: true asks for a comparison with the model, but "
                "specimen.model: none says the specimen has none; drop one of them"
            )
        return self

    @model_validator(mode="after")
    def _flows_from_what_is_connected(self) -> Protocol:
        """Pump steps need the pump connected, reservoir steps the reservoir: a step
        from the other source would move nothing, or fluid the run does not count."""
        connected = "pump"
        for where, step in iter_steps(self.steps):
            if isinstance(step, PromptStep) and step.prompt.connect is not None:
                connected = step.prompt.connect
            elif isinstance(step, InfuseStep | WithdrawStep) and connected != "pump":
                raise ValueError(
                    f"{where}: the pump is disconnected here (a prompt connected the "
                    "reservoir); add a prompt with connect: pump before this step"
                )
            elif isinstance(step, ReservoirStep) and connected != "reservoir":
                raise ValueError(
                    f"{where}: a reservoir step needs the reservoir connected: add a "
                    "prompt with connect: reservoir before it"
                )
        return self

    @model_validator(mode="after")
    def _volumes_within_limits(self) -> Protocol:
        """At no step does the volume in the specimen exceed `limits.max_volume_ml` or
        fall below zero (more withdrawn than infused)."""
        for where, volume_ml in self._net_volumes():
            if volume_ml > self.limits.max_volume_ml + 1e-9:
                raise ValueError(
                    f"{where} brings the specimen to {volume_ml:g} mL, above "
                    f"limits.max_volume_ml = {self.limits.max_volume_ml:g} mL"
                )
            if volume_ml < -1e-9:
                raise ValueError(
                    f"{where} withdraws more than was infused (net {volume_ml:g} mL): "
                    "the pump would pull air or collapse the specimen"
                )
        return self

    def _net_volumes(self) -> Iterator[tuple[str, float]]:
        volume_ml = 0.0
        for location, step in iter_steps(self.steps):
            if isinstance(step, InfuseStep):
                volume_ml += step.infuse.volume_ml
            elif isinstance(step, WithdrawStep):
                volume_ml -= step.withdraw.volume_ml
            elif isinstance(step, ReservoirStep):
                volume_ml += step.reservoir.volume_ml
            else:
                continue
            yield location, volume_ml


def iter_steps(steps: list, prefix: str = "steps") -> Iterator[tuple[str, BaseModel]]:
    """Every leaf step in execution order with its key path, repeats unrolled."""
    for location, step, _ in iter_plan(steps, prefix):
        yield location, step


def iter_plan(steps: list, prefix: str = "steps") -> Iterator[tuple[str, BaseModel, int]]:
    """Every leaf step with its key path and its repetition (1-based; 0 for none).

    A repetition is one pass through a ``repeat`` block, or one run of consecutive
    top-level actuation steps; ``zero_pressure`` belongs to no repetition.
    """
    repetition = 0
    in_loose_run = False
    for index, step in enumerate(steps):
        location = f"{prefix}[{index}]"
        if isinstance(step, RepeatStep):
            in_loose_run = False
            for rep in range(step.repeat.times):
                repetition += 1
                for inner_index, inner in enumerate(step.repeat.steps):
                    inner_location = f"{location}.repeat(#{rep + 1}).steps[{inner_index}]"
                    yield inner_location, inner, repetition
        elif isinstance(step, ZeroPressureStep):
            in_loose_run = False
            yield location, step, 0
        else:
            if not in_loose_run:
                repetition += 1
                in_loose_run = True
            yield location, step, repetition


@dataclass(frozen=True)
class Plan:
    """What a protocol will do, computed before anything moves."""

    duration_s: float
    infused_ml: float
    withdrawn_ml: float
    max_volume_ml: float
    repetitions: int
    # technician prompts take as long as the technician does: not in duration_s
    prompts: int = 0


def plan(protocol: Protocol) -> Plan:
    duration_s = infused_ml = withdrawn_ml = volume_ml = max_volume_ml = 0.0
    repetitions = prompts = 0
    for _, step, repetition in iter_plan(protocol.steps):
        repetitions = max(repetitions, repetition)
        if isinstance(step, ZeroPressureStep):
            duration_s += step.zero_pressure.duration_s
        elif isinstance(step, HoldStep):
            duration_s += step.hold.seconds
        elif isinstance(step, InfuseStep):
            duration_s += 60.0 * step.infuse.volume_ml / step.infuse.rate_ml_min
            infused_ml += step.infuse.volume_ml
            volume_ml += step.infuse.volume_ml
        elif isinstance(step, WithdrawStep):
            duration_s += 60.0 * step.withdraw.volume_ml / step.withdraw.rate_ml_min
            withdrawn_ml += step.withdraw.volume_ml
            volume_ml -= step.withdraw.volume_ml
        elif isinstance(step, ReservoirStep):
            duration_s += step.reservoir.duration_s
            volume_ml += step.reservoir.volume_ml
        elif isinstance(step, PromptStep):
            prompts += 1
        max_volume_ml = max(max_volume_ml, volume_ml)
    return Plan(duration_s, infused_ml, withdrawn_ml, max_volume_ml, repetitions, prompts)


@dataclass(frozen=True)
class LoadedProtocol:
    """A validated protocol with the text it came from (stored verbatim in the run file)."""

    path: Path
    text: str
    protocol: Protocol


def load_protocol(path: str | Path) -> LoadedProtocol:
    """Read and validate a protocol file; raise InputError naming file, key and line."""
    path = Path(path)
    text = read_text_file(path, what="protocol file", max_bytes=MAX_CONFIG_BYTES)
    return LoadedProtocol(path, text, parse_protocol(text, str(path)))


def parse_protocol(text: str, filename: str = "<protocol>") -> Protocol:
    return parse_yaml_model(text, filename, Protocol, what="a protocol", hide=STEP_KINDS)


def protocol_json_schema() -> str:
    """JSON Schema of the protocol format, for editors (YAML language servers)."""
    schema = Protocol.model_json_schema()
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    schema["title"] = "labrig protocol"
    return json.dumps(schema, indent=2)


RepeatParams.model_rebuild()
RepeatStep.model_rebuild()
Protocol.model_rebuild()
