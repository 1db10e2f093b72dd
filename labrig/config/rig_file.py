"""The rig file: which devices a run uses, as YAML, checked against a schema.

A rig YAML names the real devices (serial port, DAQ channel, camera, calibration); the
word ``sim`` (in the protocol, or ``--sim``) gives the simulated rig instead. The schema
is all that differs between the bench and CI: ``labrig.rig`` connects the drivers it
names.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Literal

import yaml
from pydantic import Field, model_validator

from labrig.config.protocol import MAX_PATH_CHARS, LoadedProtocol
from labrig.config.yaml_schema import IndexOrLine, Line, Strict, parse_yaml_model
from labrig.errors import InputError
from labrig.user_files import MAX_CONFIG_BYTES, read_text_file

# The pull-up that makes a cut sensor wire read out of band (docs/reference/interlocks.md
# derives it: 4.7 kOhm against the USB-6009's 144 kOhm input holds an open input at
# 4.89 V, above the MPX5100's 4.813 V most).
DEFAULT_PULL_UP_KOHM = 4.7
# the largest that still holds an open input above the band's 4.8125 V: 7.9 kOhm
MAX_PULL_UP_KOHM = 7.5
# A 50 mL Hamilton 1000-series gastight syringe (the paper's), inner diameter in mm.
DEFAULT_SYRINGE_DIAMETER_MM = 27.6
DEFAULT_SYRINGE_VOLUME_ML = 50.0
# The PHD ULTRA's rated linear force at 100 % force: 75 lbf (catalogue, unverified).
PHD_ULTRA_RATED_FORCE_N = 75 * 4.4482216


class SyringeConfig(Strict):
    diameter_mm: float = Field(
        DEFAULT_SYRINGE_DIAMETER_MM,
        gt=0.1,
        le=50.0,
        description="Inner diameter from the syringe's data sheet: volumes scale with its square",
    )
    volume_ml: float = Field(DEFAULT_SYRINGE_VOLUME_ML, gt=0, le=140, description="Capacity")


class PumpConfig(Strict):
    port: Line = Field(description="Serial device (/dev/ttyACM0, COM3) or pyserial URL")
    address: int = Field(0, ge=0, le=99, description="The address set on the pump")
    baud: Literal[9600, 19200, 38400, 57600, 115200] = Field(
        115200, description="RS-232 only (USB ignores it): the pump's own setting"
    )
    syringe: SyringeConfig = Field(SyringeConfig(), description="The syringe in the pump")
    address_form: Literal["auto", "none", "colon", "digits"] = Field(
        "auto",
        description="How the address precedes a command: none (cmd), colon (N:cmd), digits "
        "(0Ncmd); auto tries the manual's form first and keeps the one answered",
    )
    reply_timeout_s: float = Field(
        2.0, gt=0, le=30, description="How long the pump may take to answer one command"
    )
    force_limit_pct: int = Field(
        100,
        ge=1,
        le=100,
        description="The pump's force limit, % of its rated force: it stalls above "
        "this share of rated_force_n over the plunger area (the hardware pressure backstop)",
    )
    rated_force_n: float = Field(
        PHD_ULTRA_RATED_FORCE_N, gt=0, description="The pump's linear force at 100 %"
    )
    infuse_only: bool = Field(False, description="An infuse-only pump model (no withdraw)")


class PressureConfig(Strict):
    channel: Line = Field("Dev1/ai0", description="DAQ channel of the sensor's output")
    terminal: Literal["RSE", "DIFF"] = Field(
        "RSE", description="Single-ended (ai0-ai7) or differential (ai0-ai3)"
    )
    min_v: float = Field(-10.0, description="Input range asked of DAQmx (RSE: always +-10 V)")
    max_v: float = Field(10.0, description="Input range asked of DAQmx (RSE: always +-10 V)")
    supply_channel: Line | None = Field(
        None, description="Channel measuring the sensor supply (the MPX5100 is ratiometric)"
    )
    supply_v: float = Field(5.0, gt=0, description="Assumed supply when none is measured")
    pull_up_kohm: float | None = Field(
        DEFAULT_PULL_UP_KOHM,
        ge=1,
        le=MAX_PULL_UP_KOHM,
        description="The resistor from the sensor's output to its 5 V supply at the DAQ's "
        "input, so a cut output wire reads above the sensor's band and faults the run as a "
        "wire fault (above 7.5 kOhm it would read inside the band); null for a rig wired "
        "without it (a cut wire then reads about 27 kPa, in range, and only the zeroing "
        "sees it)",
    )


class LoadCellConfig(Strict):
    """A load cell's bridge amplifier on another input of the pressure's USB-6009."""

    channel: Line = Field("Dev1/ai2", description="The amplifier's output")
    n_per_v: float = Field(10.0, gt=0, description="Calibration: newtons per volt")
    offset_v: float = Field(0.0, description="Calibration: the output at no load (V)")
    capacity_n: float = Field(100.0, gt=0, description="The cell's rated force")


class CameraConfig(Strict):
    source: IndexOrLine = Field(0, description="Camera index, /dev/video* path or video file")
    mm_per_px: float | None = Field(
        None, gt=0, description="Scale in the specimen's plane at this width and height"
    )
    reference_distance_mm: float | None = Field(
        None, gt=0, description="Or: the markers' distance in the first frame, for the scale"
    )
    # set on the camera and read back; a camera that cannot do them is refused
    width: int | None = Field(
        1280, gt=0, le=8192, description="Frame width (px); V4L2 opens at 640"
    )
    height: int | None = Field(
        720, gt=0, le=8192, description="Frame height (px); V4L2 opens at 480"
    )
    fps: float | None = Field(
        None, ge=1, le=240, description="Streaming rate; default the protocol's camera_fps"
    )
    exposure: float | None = Field(
        None, description="Manual exposure in the backend's units (V4L2: 100 us); default auto"
    )
    focus: float | None = Field(
        None, ge=0, description="Manual focus in the backend's units; default the camera's own"
    )
    warmup_frames: int = Field(
        5, ge=0, le=300, description="Frames dropped at start while the auto exposure settles"
    )
    fourcc: Line | None = Field(
        "MJPG",
        min_length=4,
        max_length=4,
        description="Pixel format asked for first and read back (MJPG: 1280x720 at 30 fps "
        "over USB 2.0; YUYV gives ~10 fps there); null leaves the camera's own",
    )

    def settings(self, protocol_fps: float | None):
        """What the driver sets on the camera (the rate: this file's, else the
        protocol's camera_fps; None leaves the camera's own)."""
        from labrig.drivers.camera import CameraSettings

        return CameraSettings(
            width=self.width,
            height=self.height,
            fps=self.fps or protocol_fps,
            exposure=self.exposure,
            focus=self.focus,
            fourcc=self.fourcc,
        )

    @model_validator(mode="after")
    def _one_scale(self) -> CameraConfig:
        """Exactly one of `mm_per_px` and `reference_distance_mm` gives the scale."""
        if (self.mm_per_px is None) == (self.reference_distance_mm is None):
            raise ValueError("give exactly one of mm_per_px and reference_distance_mm")
        return self


# The simulated pump's reply deadline in host seconds, by default. The emulator answers
# at once in virtual time; this only bounds how long a starved host thread may take to
# do it (and how long a pump that went silent costs in wall time: the soak shortens it).
SIM_REPLY_TIMEOUT_S = 10.0


class SimSpecimen(Strict):
    """The simulated specimen's truth: what it is made of and how it behaves, which need
    not be what the protocol's specimen (its model) says. Every behaviour is off by
    default."""

    segments: list[Annotated[Line, Field(max_length=MAX_PATH_CHARS)]] | None = Field(
        None,
        min_length=1,
        description="Its segments as a protocol's specimen.segments names them (library "
        "names of any library, measured segments, CSV paths); default: the protocol's",
    )
    stiffness_factor: float = Field(
        1.0, ge=0.1, le=10, description="Pressure scaled at equal volume (2: twice as stiff)"
    )
    hysteresis_kpa: float = Field(
        0.0,
        ge=0,
        le=50,
        description="Deflation reads this much below inflation (at most half the pressure), "
        "reached over the first 0.5 mL withdrawn",
    )
    first_cycle_factor: float = Field(
        1.0,
        ge=1,
        le=3,
        description="A fresh latex tube is this much stiffer on its first inflation (the "
        "Mullins effect): at volumes below the most it has held it is softer again",
    )
    air_ml: float = Field(
        0.0, ge=0, le=100, description="Air trapped in a water line (mL at atmosphere)"
    )
    leak_fraction: float = Field(
        0.0,
        ge=0,
        le=0.9,
        description="The share of the pump's infused flow lost at the specimen (a weeping "
        "fitting): it never comes back",
    )
    burst_at_ml: float | None = Field(
        None,
        gt=0,
        le=1000,
        description="The specimen opens to the air once the pump has supplied this volume: "
        "the pressure falls to 0 and stays there",
    )


class SimConfig(Strict):
    speed: float | None = Field(
        None,
        ge=0.5,
        le=1e6,
        description="Wall-clock pacing of the virtual timeline (1: real time); default: as "
        "fast as the host computes it. The recorded data are the same either way.",
    )
    seed: int = Field(0, ge=0, description="Seeds every random part of the simulation")
    resistance_kpa_s_per_ml: float = Field(
        0.1,
        ge=1e-3,
        le=1e3,
        description="Flow resistance between segments (sets the snap time; below 1e-3 the "
        "plant's time steps get too small to finish)",
    )
    noise_kpa: float = Field(0.05, ge=0, description="Pressure sensor white noise")
    offset_error_kpa: float = Field(0.8, description="Sensor zero offset (removed by zeroing)")
    mm_per_px: float | None = Field(
        None, gt=0, description="Rendered camera scale; default fits the specimen"
    )
    reply_timeout_s: float = Field(
        SIM_REPLY_TIMEOUT_S,
        gt=0,
        le=60,
        description="Host seconds the simulated pump's replies are awaited (virtual time "
        "stands still meanwhile)",
    )
    # the plumbing of the step experiments' plant (labrig.sim.dynamic_plant); the bore
    # is fitted so that the paper's water step (Movie S7) takes 1.4 s
    coupling_bore_mm: float = Field(
        0.76, ge=0.1, le=5, description="Bore of each segment's coupling (sets the snap time)"
    )
    coupling_length_mm: float = Field(20.0, ge=1, le=1000, description="Length of each coupling")
    dead_volume_ml: float = Field(
        2.0, ge=0.01, le=100, description="Fluid in the lines and the tee"
    )
    answer_s: float = Field(
        2.0,
        ge=0,
        le=30,
        description="How long the technician takes a prompt (the simulation computes the "
        "plant all that time: half a minute at most)",
    )
    specimen: SimSpecimen | None = Field(
        None,
        description="The specimen's truth and behaviour; default: exactly the protocol's "
        "segments, which then are their own model",
    )


class RigConfig(Strict):
    """The devices of a rig; ``sim`` present means the simulated rig."""

    pump: PumpConfig = Field(description="The syringe pump (PHD ULTRA) and its syringe")
    pressure: PressureConfig = Field(
        PressureConfig(), description="The DAQ channels of the MPX5100 pressure sensor"
    )
    camera: CameraConfig | None = Field(None, description="The camera; none: no length")
    force: LoadCellConfig | None = Field(
        None, description="The load cell of a blocked-force test; none: no force"
    )
    sim: SimConfig | None = Field(None, description="Present only on the simulated rig")
    signal_timeout_s: float = Field(
        0.5,
        ge=0.2,
        le=5,
        description="A pressure signal with no sample this long, or a camera "
        "with no frame this long or three frame periods, is a dead device: the run faults",
    )


def sim_rig_config(speed: float | None = None, seed: int = 0) -> RigConfig:
    return RigConfig(pump=PumpConfig(port="emulator"), sim=SimConfig(speed=speed, seed=seed))


def load_rig_config(
    loaded: LoadedProtocol,
    *,
    force_sim: bool = False,
    speed: float | None = None,
    seed: int | None = None,
) -> RigConfig:
    """The rig a protocol runs on: ``sim``, or a rig YAML relative to the protocol."""
    spec = loaded.protocol.rig
    if force_sim or spec == "sim":
        config = sim_rig_config(speed, seed or 0)
        if spec not in ("sim", "") and force_sim:
            # a real rig file run with --sim keeps nothing of the hardware but the syringe
            syringe = _rig_file(loaded).pump.syringe
            config = config.model_copy(
                update={"pump": PumpConfig(port="emulator", syringe=syringe)}
            )
        return config
    for flag, value in (("--speed", speed), ("--seed", seed)):
        if value is not None:
            raise InputError(f"{flag} applies to the simulated rig only (use --sim)")
    return _rig_file(loaded)


def _rig_file(loaded: LoadedProtocol) -> RigConfig:
    path = Path(loaded.protocol.rig)
    if not path.is_absolute():
        path = loaded.path.parent / path
    text = read_rig_text(path, f"{loaded.path}: rig: ")
    return parse_yaml_model(text, str(path), RigConfig, what="a rig configuration")


def read_rig_text(path: Path, context: str = "") -> str:
    """The text of a rig file (a regular file only); InputError after ``context``."""
    try:
        return read_text_file(path, what="rig file", max_bytes=MAX_CONFIG_BYTES)
    except InputError as exc:
        raise InputError(f"{context}cannot read rig file {exc}") from None


def rig_config_text(config: RigConfig) -> str:
    return yaml.safe_dump(config.model_dump(mode="json"), sort_keys=False)
