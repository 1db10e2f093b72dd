"""Rig configuration and assembly: the one place that knows which devices a run uses.

A rig YAML names the real devices (serial port, DAQ channel, camera, calibration); the
word ``sim`` (in the protocol, or ``--sim``) gives the simulated rig instead. Either way
the runner gets the same drivers: in simulation they are connected to the emulators —
the PHD Ultra emulator on a pseudo-terminal, SimDaqTask behind the nidaqmx Task
factory, SimCamera behind the capture — all fed by one plant on one simulated clock.
Only configuration differs between the bench and CI.
"""

from __future__ import annotations

import math
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import yaml
from pydantic import Field, model_validator

from labrig.clock import RealClock
from labrig.errors import DeviceError, InputError
from labrig.protocol import LoadedProtocol, Protocol, plan
from labrig.runner import Rig
from labrig.yamlmodel import Strict, parse_yaml_model

# A 50 mL Hamilton 1000-series gastight syringe (the paper's), inner diameter in mm.
DEFAULT_SYRINGE_DIAMETER_MM = 27.6
DEFAULT_SYRINGE_VOLUME_ML = 50.0
# The PHD ULTRA's rated linear force at 100 % force: 75 lbf (catalogue, unverified).
PHD_ULTRA_RATED_FORCE_N = 75 * 4.4482216
# The simulated pump's reply deadline in host seconds. The emulator answers at once in
# virtual time; this only bounds how long a starved host thread may take to do it.
SIM_REPLY_TIMEOUT_S = 10.0
# The simulated camera's sensor (px) when the rig file has no camera section: a small
# monochrome camera, so a simulated run's video (every frame rendered whole and encoded)
# costs a fraction of a 1280x720 colour one; tracking reads only the markers' windows
# at any size.
SIM_CAMERA_SIZE = (640, 360)


class SyringeConfig(Strict):
    diameter_mm: float = Field(DEFAULT_SYRINGE_DIAMETER_MM, gt=0.1, le=50.0)
    volume_ml: float = Field(DEFAULT_SYRINGE_VOLUME_ML, gt=0, le=140)


class PumpConfig(Strict):
    port: str = Field(description="Serial device (/dev/ttyACM0, COM3) or pyserial URL")
    address: int = Field(0, ge=0, le=99)
    baud: Literal[9600, 19200, 38400, 57600, 115200] = 115200
    syringe: SyringeConfig = SyringeConfig()
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
    channel: str = "Dev1/ai0"
    terminal: Literal["RSE", "DIFF"] = "RSE"
    min_v: float = -10.0
    max_v: float = 10.0
    supply_channel: str | None = Field(
        None, description="Channel measuring the sensor supply (the MPX5100 is ratiometric)"
    )
    supply_v: float = Field(5.0, gt=0, description="Assumed supply when none is measured")


class CameraConfig(Strict):
    source: int | str = Field(0, description="Camera index, /dev/video* path or video file")
    mm_per_px: float | None = Field(None, gt=0)
    reference_distance_mm: float | None = Field(None, gt=0)
    # set on the camera and read back; a camera that cannot do them is refused
    width: int | None = Field(1280, gt=0, description="Frame width (px); V4L2 opens at 640")
    height: int | None = Field(720, gt=0, description="Frame height (px); V4L2 opens at 480")
    fps: float | None = Field(
        None, gt=0, le=240, description="Streaming rate; default the protocol's camera_fps"
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
        )

    @model_validator(mode="after")
    def _one_scale(self) -> CameraConfig:
        if (self.mm_per_px is None) == (self.reference_distance_mm is None):
            raise ValueError("give exactly one of mm_per_px and reference_distance_mm")
        return self


class SimConfig(Strict):
    speed: float | None = Field(
        None,
        gt=0,
        description="Wall-clock pacing of the virtual timeline (1: real time); default: as "
        "fast as the host computes it. The recorded data are the same either way.",
    )
    seed: int = Field(0, ge=0, description="Seeds every random part of the simulation")
    resistance_kpa_s_per_ml: float = Field(
        0.1, gt=0, description="Flow resistance between segments (sets the snap time)"
    )
    noise_kpa: float = Field(0.05, ge=0, description="Pressure sensor white noise")
    offset_error_kpa: float = Field(0.8, description="Sensor zero offset (removed by zeroing)")
    mm_per_px: float | None = Field(
        None, gt=0, description="Rendered camera scale; default fits the specimen"
    )


class RigConfig(Strict):
    """The devices of a rig; ``sim`` present means the simulated rig."""

    pump: PumpConfig
    pressure: PressureConfig = PressureConfig()
    camera: CameraConfig | None = None
    sim: SimConfig | None = None


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
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise InputError(f"{loaded.path}: rig: cannot read rig file {path} ({exc})") from None
    return parse_yaml_model(text, str(path), RigConfig, what="a rig configuration")


def rig_config_text(config: RigConfig) -> str:
    return yaml.safe_dump(config.model_dump(mode="json"), sort_keys=False)


def build_rig(protocol: Protocol, config: RigConfig) -> Rig:
    """Connect the drivers of ``config``; the caller runs and the Rig closes them."""
    if config.sim is not None:
        return _build_sim_rig(protocol, config)
    return _build_real_rig(protocol, config)


def _build_real_rig(protocol: Protocol, config: RigConfig) -> Rig:
    from labrig.drivers.camera import CameraLength, FrameSource
    from labrig.drivers.ni_daq import NiDaqPressure
    from labrig.drivers.phd_ultra import PhdUltra

    clock = RealClock()
    with ExitStack() as stack:
        pump = PhdUltra.open(
            config.pump.port,
            baudrate=config.pump.baud,
            address=config.pump.address,
            address_form=config.pump.address_form,
            clock=clock,
            timeout_s=config.pump.reply_timeout_s,
        )
        stack.callback(pump.close)
        set_up_pump(pump, config.pump, protocol)
        pressure = _pressure_driver(NiDaqPressure, clock, config, protocol, None)
        length = None
        if protocol.acquisition.camera_fps > 0:
            if config.camera is None:
                raise InputError("the protocol asks for camera frames but the rig has no camera")
            camera = config.camera
            frames = FrameSource.open(
                camera.source, clock, camera.settings(protocol.acquisition.camera_fps)
            )
            frames.warmup_frames = camera.warmup_frames
            stack.callback(frames.close)
            length = CameraLength(
                frames,
                mm_per_px=config.camera.mm_per_px,
                reference_distance_mm=config.camera.reference_distance_mm,
            )
            stack.callback(length.close_tracker)
        closer = stack.pop_all()
    return Rig(clock, pump, pressure, length, rig_config_text(config), closer.close)


def set_up_pump(pump, config: PumpConfig, protocol: Protocol) -> None:
    """What a connected pump needs before a run: it can do what the protocol asks, the
    syringe, and the force limit (the hardware backstop, read back)."""
    if not pump.can_withdraw and plan(protocol).withdrawn_ml > 0:
        raise DeviceError(
            f"the pump on {config.port} is infuse-only (it refused 'wvolume') but the "
            "protocol withdraws: use a pump that withdraws, or a protocol without withdraw steps"
        )
    pump.configure_syringe(config.syringe.diameter_mm, config.syringe.volume_ml)
    pump.set_force_limit(config.force_limit_pct)


def _pressure_driver(driver_class, clock, config: RigConfig, protocol: Protocol, factories):
    kwargs = {} if factories is None else factories
    p = config.pressure
    return driver_class(
        clock,
        p.channel,
        terminal=p.terminal,
        min_v=p.min_v,
        max_v=p.max_v,
        supply_channel=p.supply_channel,
        supply_v=p.supply_v,
        rate_hz=protocol.acquisition.pressure_rate_hz,
        **kwargs,
    )


def _build_sim_rig(protocol: Protocol, config: RigConfig) -> Rig:
    from labrig.drivers.camera import CameraLength, FrameSource
    from labrig.drivers.ni_daq import NiDaqPressure
    from labrig.drivers.phd_ultra import PhdUltra
    from labrig.model.segments.library import load_segment
    from labrig.sim.camera import SimCamera
    from labrig.sim.daq import SimAnalogMultiChannelReader, SimDaqTask
    from labrig.sim.plant import Plant
    from labrig.sim.pump import PumpEmulator
    from labrig.virtual_clock import VirtualClock

    sim = config.sim
    segments = [load_segment(spec) for spec in protocol.specimen.segments]
    clock = VirtualClock(speed=sim.speed)
    syringe = config.pump.syringe
    plant_box: list[Plant] = []
    emulator = PumpEmulator(
        clock,
        address=config.pump.address,
        diameter_mm=syringe.diameter_mm,
        syringe_ml=syringe.volume_ml,
        load_pressure_kpa=lambda t: float(plant_box[0].pressure_kpa_at(t)),
        seed=sim.seed,
    )
    plant = Plant(
        segments,
        emulator.net_volume_ml,
        t0_s=clock.now(),
        resistance_kpa_s_per_ml=sim.resistance_kpa_s_per_ml,
        fittings_length_mm=protocol.specimen.fittings_length_mm,
        seed=sim.seed,
    )
    plant_box.append(plant)
    with ExitStack() as stack:
        emulator.start()
        stack.callback(emulator.close)
        pump = PhdUltra.open(
            emulator.port,
            address=config.pump.address,
            clock=clock,
            timeout_s=SIM_REPLY_TIMEOUT_S,
        )
        stack.callback(pump.close)
        set_up_pump(pump, config.pump, protocol)
        p = config.pressure
        daq_tasks: list[SimDaqTask] = []

        def new_task() -> SimDaqTask:
            task = SimDaqTask(
                clock,
                plant.pressure_kpa_at,
                supply_v=p.supply_v,
                noise_kpa=sim.noise_kpa,
                offset_error_kpa=sim.offset_error_kpa,
                seed=sim.seed + len(daq_tasks),
                output_channel=p.channel,
                supply_channel=p.supply_channel,
            )
            daq_tasks.append(task)
            return task

        factories = {"task_factory": new_task, "reader_factory": SimAnalogMultiChannelReader}
        pressure = _pressure_driver(NiDaqPressure, clock, config, protocol, factories)
        length = camera = None
        if protocol.acquisition.camera_fps > 0:
            size = SIM_CAMERA_SIZE
            if config.camera is not None and config.camera.width and config.camera.height:
                size = (config.camera.width, config.camera.height)  # the sensor asked for
            mm_per_px = sim.mm_per_px or _fitting_scale_mm_per_px(segments, protocol, size[0])
            camera = SimCamera(
                clock,
                plant.length_mm_at,
                mm_per_px=mm_per_px,
                size=size,
                seed=sim.seed,
                # a grey sensor: a third of the pixels to render, track and encode
                monochrome=True,
            )
            # the camera is set up through the driver as on the bench: from the rig's
            # camera section if it has one (its scale too), else at the sensor's size
            wanted = config.camera or CameraConfig(
                mm_per_px=mm_per_px, width=size[0], height=size[1]
            )
            frames = FrameSource.live(
                camera, clock, "simulated camera", warmup_frames=wanted.warmup_frames
            )
            frames.configure(wanted.settings(protocol.acquisition.camera_fps))
            stack.callback(frames.close)
            length = CameraLength(
                frames,
                mm_per_px=wanted.mm_per_px,
                reference_distance_mm=wanted.reference_distance_mm,
            )
            stack.callback(length.close_tracker)
        closer = stack.pop_all()
    simulation = SimulatedParts(plant, emulator, camera, daq_tasks)
    return Rig(clock, pump, pressure, length, rig_config_text(config), closer.close, simulation)


@dataclass(frozen=True)
class SimulatedParts:
    """What stands behind the drivers of a simulated rig (the truth, for tests)."""

    plant: object
    emulator: object
    camera: object | None
    daq_tasks: list  # every SimDaqTask made so far; the last one is acquiring


def _fitting_scale_mm_per_px(segments, protocol: Protocol, width_px: int) -> float:
    """A scale at which the longest specimen fills at most 80 % of the frame's width."""
    longest_mm = sum(float(s.l_mm.max()) for s in segments)
    longest_mm += protocol.specimen.fittings_length_mm
    return max(0.02, math.ceil(longest_mm / (0.8 * width_px) * 1000) / 1000)
