"""The simulated rig: the real drivers connected to the emulators — the PHD Ultra
emulator on a pseudo-terminal, SimDaqTask behind the nidaqmx Task factory, SimCamera
behind the capture — all fed by one plant on one simulated clock.

The plant is the specimen's truth: the rig file's ``sim.specimen`` (its segments and
its real-world behaviour, ``labrig.sim.specimen``), which need not be the protocol's
specimen, the model the run is compared with; by default it is the protocol's segments,
exactly."""

from __future__ import annotations

import math
from contextlib import ExitStack
from dataclasses import dataclass

from labrig.config.protocol import Protocol
from labrig.config.rig_file import (
    CameraConfig,
    LoadCellConfig,
    RigConfig,
    SimConfig,
    SimSpecimen,
    rig_config_text,
)
from labrig.errors import InputError
from labrig.rig.connect import needs_technician, pressure_driver, set_up_pump
from labrig.rig.devices import Rig
from labrig.rig.serial_link_folder import new_link_folder

# The simulated camera's sensor (px) when the rig file has no camera section: a small
# monochrome camera, so a simulated run's video (every frame rendered whole and encoded)
# costs a fraction of a 1280x720 colour one; tracking reads only the markers' windows
# at any size.
SIM_CAMERA_SIZE = (640, 360)
# How long the simulated rig's pump driver looks for a lost port (host seconds; 10 s on
# the bench): the emulator's re-enumerations take at most a second.
SIM_RECONNECT_S = 2.0


def build_simulated_rig(protocol: Protocol, config: RigConfig, before_connect=None) -> Rig:
    """The simulated rig; ``before_connect(emulator)`` leaves the emulated pump in a
    state of its own before the driver connects (running, in a method: tests, soak)."""
    from labrig.drivers.camera import CameraLength, FrameSource
    from labrig.drivers.ni_daq import NiDaqPressure
    from labrig.drivers.phd_ultra import PhdUltra
    from labrig.model.segments.catalog import load_segment
    from labrig.sim.camera import SimCamera
    from labrig.sim.daq import SimAnalogMultiChannelReader, SimDaqTask
    from labrig.sim.plant import Plant
    from labrig.sim.pump import PumpEmulator
    from labrig.sim.specimen import LeakyVolume, SpecimenBehaviour, scaled_curve
    from labrig.time.virtual import VirtualClock

    sim = config.sim
    truth = specimen_truth(protocol, sim)
    segments = [scaled_curve(load_segment(spec), truth.stiffness_factor) for spec in truth.segments]
    # the truth as run goes into the run file with the rest of the rig's configuration
    config = config.model_copy(update={"sim": sim.model_copy(update={"specimen": truth})})
    clock = VirtualClock(speed=sim.speed)
    syringe = config.pump.syringe
    plant_box: list[Plant] = []
    # the pump is opened by a stable link, like udev's /dev/serial/by-id/... one, which
    # follows it when it re-enumerates as another pseudo-terminal
    link_dir = new_link_folder()
    emulator = PumpEmulator(
        clock,
        by_id=link_dir / "usb-Harvard_Apparatus_PHD_ULTRA_SIM-if00",
        address=config.pump.address,
        diameter_mm=syringe.diameter_mm,
        syringe_ml=syringe.volume_ml,
        load_pressure_kpa=lambda t: float(plant_box[0].pressure_kpa_at(t)),
        seed=sim.seed,
    )
    volume_ml_at = emulator.net_volume_ml
    if truth.leak_fraction > 0:
        volume_ml_at = LeakyVolume(volume_ml_at, truth.leak_fraction)
    behaviour = None
    if truth.hysteresis_kpa or truth.first_cycle_factor != 1 or truth.burst_at_ml is not None:
        behaviour = SpecimenBehaviour(
            emulator.net_volume_ml,
            hysteresis_kpa=truth.hysteresis_kpa,
            first_cycle_factor=truth.first_cycle_factor,
            burst_at_ml=truth.burst_at_ml,
        )
    if needs_dynamic_plant(protocol) or truth.air_ml > 0:
        plant = _dynamic_plant(segments, volume_ml_at, clock, protocol, config, behaviour)
    else:
        plant = Plant(
            segments,
            volume_ml_at,
            t0_s=clock.now(),
            resistance_kpa_s_per_ml=sim.resistance_kpa_s_per_ml,
            fittings_length_mm=protocol.specimen.fittings_length_mm,
            seed=sim.seed,
            behaviour=behaviour,
        )
    plant_box.append(plant)
    with ExitStack() as stack:
        stack.callback(link_dir.rmdir)
        emulator.start()
        stack.callback(emulator.close)
        if before_connect is not None:
            before_connect(emulator)
        pump = PhdUltra.open(
            emulator.port,
            address=config.pump.address,
            clock=clock,
            timeout_s=sim.reply_timeout_s,
        )
        stack.callback(pump.close)
        # the emulator re-enumerates within a second of host time when told to
        pump.reconnect_s = SIM_RECONNECT_S
        set_up_pump(pump, config.pump, protocol)
        p = config.pressure
        daq_tasks: list[SimDaqTask] = []

        if protocol.specimen.length == "blocked" and config.force is None:
            # the simulated rig has the load cell a blocked protocol needs
            config = config.model_copy(update={"force": LoadCellConfig()})
        other_signals = {}
        if protocol.specimen.length == "blocked":
            from labrig.sim.load_cell import LoadCellSignal

            other_signals[config.force.channel] = LoadCellSignal(
                plant.force_n_at,
                n_per_v=config.force.n_per_v,
                offset_v=config.force.offset_v,
                seed=sim.seed + 1000,
            )

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
                other_signals=other_signals,
                pull_up_kohm=p.pull_up_kohm,
            )
            daq_tasks.append(task)
            return task

        factories = {"task_factory": new_task, "reader_factory": SimAnalogMultiChannelReader}
        pressure = pressure_driver(NiDaqPressure, clock, config, protocol, factories)
        length = camera = capture = None
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
            capture = SlowStartingCapture(camera, clock)
            frames = FrameSource.live(
                capture, clock, "simulated camera", warmup_frames=wanted.warmup_frames
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
    simulation = SimulatedParts(plant, emulator, camera, daq_tasks, capture, SimDisk(clock))
    rig = Rig(clock, pump, pressure, length, rig_config_text(config), closer.close, simulation)
    if needs_technician(protocol):
        from labrig.sim.technician import SimTechnician

        rig.technician = SimTechnician(clock, plant, sim.answer_s)
    return rig


def needs_dynamic_plant(protocol: Protocol) -> bool:
    """The step experiments' plant: for a technician's steps, air or a blocked length;
    the quasi-static plant otherwise (the same path, far cheaper)."""
    specimen = protocol.specimen
    return needs_technician(protocol) or specimen.fluid != "water" or specimen.length != "free"


def specimen_truth(protocol: Protocol, sim: SimConfig) -> SimSpecimen:
    """The simulated specimen: the rig file's ``sim.specimen`` with its segments given
    (the protocol's by default). InputError, in one line, for a protocol whose segments
    no library holds, or that has no model, and a rig file that does not say what the
    specimen really is."""
    from labrig.model.segments.catalog import load_segment

    truth = sim.specimen or SimSpecimen()
    if truth.segments is not None:
        return truth
    if not protocol.specimen.has_model:
        raise InputError(
            "the simulated rig cannot know what the specimen is: specimen.model: none makes "
            "its segments labels; give the rig file's sim.specimen.segments, the segments "
            "the simulated specimen really is (library names or CSV paths)"
        )
    for spec in protocol.specimen.segments:
        try:
            load_segment(spec)
        except InputError:
            raise InputError(
                f"the simulated rig cannot know what segment {spec!r} is (no library holds "
                "it): give the rig file's sim.specimen.segments, the segments the simulated "
                "specimen really is (library names or CSV paths)"
            ) from None
    return truth.model_copy(update={"segments": list(protocol.specimen.segments)})


def _dynamic_plant(
    segments, volume_ml_at, clock, protocol: Protocol, config: RigConfig, behaviour=None
):
    from labrig.sim.dynamic_plant import FLUIDS, DynamicPlant, Plumbing

    sim, specimen = config.sim, protocol.specimen
    plumbing = Plumbing(
        fluid=FLUIDS[specimen.fluid],
        bore_mm=sim.coupling_bore_mm,
        coupling_length_mm=sim.coupling_length_mm,
        dead_volume_ml=sim.dead_volume_ml,
        air_reservoir_ml=specimen.air_reservoir_ml,
        syringe_ml=config.pump.syringe.volume_ml,
        trapped_air_ml=sim.specimen.air_ml if sim.specimen else 0.0,
    )
    return DynamicPlant(
        segments,
        volume_ml_at,
        plumbing=plumbing,
        t0_s=clock.now(),
        fittings_length_mm=specimen.fittings_length_mm,
        blocked=specimen.length == "blocked",
        behaviour=behaviour,
    )


@dataclass(frozen=True)
class SimulatedParts:
    """What stands behind the drivers of a simulated rig (the truth, for tests)."""

    plant: object
    emulator: object
    camera: object | None
    daq_tasks: list  # every SimDaqTask made so far; the last one is acquiring
    capture: SlowStartingCapture | None = None  # the camera as the driver sees it
    disk: SimDisk | None = None  # a run file's disk, when the run writes through it


class SimDisk:
    """A disk whose writes can be made to take rig time (a USB stick, a network share,
    a virus scanner): ``write`` is a runner's data tap, called with every append to the
    run file, and sleeps ``write_s`` on the clock in the thread that writes."""

    def __init__(self, clock) -> None:
        self.clock = clock
        self.write_s = 0.0

    def write(self, *appended) -> None:
        if self.write_s > 0:
            self.clock.sleep(self.write_s)


class SlowStartingCapture:
    """The simulated camera as a UVC webcam starts: its first frame comes
    ``first_frame_s`` of rig time after the first grab (0.3-1 s is common; 0 unless a
    test or the soak sets it, so the simulated rig's data stay as they were). Every
    other call goes to the camera."""

    def __init__(self, camera, clock) -> None:
        self.camera = camera
        self.clock = clock
        self.first_frame_s = 0.0
        self._started = False

    def read(self):
        if not self._started:
            self._started = True
            self.clock.sleep(self.first_frame_s)
        return self.camera.read()

    def __getattr__(self, name: str):
        return getattr(self.camera, name)


def _fitting_scale_mm_per_px(segments, protocol: Protocol, width_px: int) -> float:
    """A scale at which the longest specimen fills at most 80 % of the frame's width."""
    longest_mm = sum(float(s.l_mm.max()) for s in segments)
    longest_mm += protocol.specimen.fittings_length_mm
    return max(0.02, math.ceil(longest_mm / (0.8 * width_px) * 1000) / 1000)
