"""Rig assembly: the one place that knows which devices a run uses.

Either rig gives the runner the same drivers: on the bench they talk to the instruments
the rig file names; in simulation (``labrig.rig.simulated``) they are connected to the
emulators. Only configuration differs between the bench and CI.
"""

from __future__ import annotations

from contextlib import ExitStack

from labrig.config.protocol import Protocol
from labrig.config.rig_file import RigConfig, rig_config_text
from labrig.errors import InputError
from labrig.rig.connect import needs_technician, pressure_driver, set_up_pump
from labrig.rig.devices import Rig
from labrig.rig.simulated import build_simulated_rig
from labrig.time.clock import RealClock


def build_rig(protocol: Protocol, config: RigConfig) -> Rig:
    """Connect the drivers of ``config``; the caller runs and the Rig closes them."""
    if config.sim is not None:
        return build_simulated_rig(protocol, config)
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
        pressure = pressure_driver(NiDaqPressure, clock, config, protocol, None)
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
    rig = Rig(clock, pump, pressure, length, rig_config_text(config), closer.close)
    if needs_technician(protocol):
        from labrig.run.technician import ConsoleTechnician

        rig.technician = ConsoleTechnician(clock)
    return rig
