"""The rig check on the simulated rig, and the faults it can be shown with.

The simulated rig is built as for a run (``labrig.rig.assembly.build_rig``); the check then
reaches its devices as it reaches real ones: the pump by opening the emulator's
pseudo-terminal with the real driver, the DAQ through a simulated nidaqmx task behind
the real driver, the camera's rendered frames through the real tracker.

``FAULTS`` are what a technician meets at the bench, each made the way it happens:
a pump that does not answer (the emulator drops every reply), a rig file with the
wrong pump address, a DAQ that is not there (the rig file names a device the simulated
DAQ is not), a marker fallen off (not drawn), a sensor whose offset is out of tolerance.
"""

from __future__ import annotations

from labrig.config.protocol import parse_protocol
from labrig.config.rig_file import PumpConfig, RigConfig, SimConfig
from labrig.rig.assembly import build_rig
from labrig.rig.check import DeviceCheck, check_camera, check_pressure, check_pump

# the emulator's thread shares the host with everything else: a starved host only
# costs wall time here, so its replies are awaited as long as the rig file's default
# (but not the runs' 10 s: the no-reply fault waits this eight times). The search for a pump
# at another address has its own timeout: a test of the faults, where no reply is the
# point, shortens the first and keeps the second (the answer it needs may come late).
SIM_REPLY_TIMEOUT_S = 2.0
SIM_SEARCH_TIMEOUT_S = 2.0
FAULTS = {
    "no-reply": "the pump sends no reply (cable, power)",
    "wrong-address": "the rig file names pump address 3; the pump is at 0",
    "daq-missing": "the rig file names DAQ Dev2; only Dev1 is connected",
    "marker-hidden": "the second marker is covered",
    "sensor-offset": "the pressure sensor reads 4 kPa at atmospheric pressure",
}
# a protocol only to build the simulated rig: its specimen and its camera
_CHECK_PROTOCOL = """\
name: rig check
specimen: {segments: [SI-B48-T30, SI-B50-T20], fittings_length_mm: 10}
rig: sim
limits: {max_pressure_kpa: 95, max_volume_ml: 45}
acquisition: {pressure_rate_hz: 1000, camera_fps: 2}
steps:
  - hold: {seconds: 1}
"""


def simulated_config(bench: RigConfig | None) -> RigConfig:
    """The simulated rig, keeping a rig file's pump address, syringe and DAQ wiring."""
    if bench is None:
        return RigConfig(pump=PumpConfig(port="emulator"), sim=SimConfig())
    return RigConfig(
        pump=bench.pump.model_copy(update={"port": "emulator"}),
        pressure=bench.pressure,
        sim=bench.sim or SimConfig(),
    )


def check_sim_rig(config: RigConfig, fault: str | None = None) -> list[DeviceCheck]:
    """Check the simulated rig of ``config`` (its ``sim`` section set), with one of
    ``FAULTS`` injected if given."""
    from labrig.sim.daq import SimAnalogMultiChannelReader, SimDaqTask

    if fault is not None and fault not in FAULTS:
        raise ValueError(f"unknown fault {fault!r}")
    if fault == "sensor-offset":
        config = config.model_copy(
            update={"sim": config.sim.model_copy(update={"offset_error_kpa": 4.0})}
        )
    protocol = parse_protocol(_CHECK_PROTOCOL, "<rig check>")
    rig = build_rig(protocol, config)
    try:
        sim, wired = rig.simulation, config.pressure
        rig.pump.close()  # the check opens the pump's port itself, as on the bench
        pump = config.pump
        if fault == "no-reply":
            sim.emulator.drop_next_replies(1_000_000)
        elif fault == "wrong-address":
            pump = pump.model_copy(update={"address": 3 if pump.address != 3 else 4})
        elif fault == "marker-hidden":
            sim.camera.hide_marker(1)
        named = wired
        if fault == "daq-missing":
            named = wired.model_copy(
                update={
                    "channel": _on_device(wired.channel, "Dev2"),
                    "supply_channel": wired.supply_channel
                    and _on_device(wired.supply_channel, "Dev2"),
                }
            )

        def new_task() -> SimDaqTask:
            return SimDaqTask(
                rig.clock,
                sim.plant.pressure_kpa_at,
                supply_v=wired.supply_v,
                noise_kpa=config.sim.noise_kpa,
                offset_error_kpa=config.sim.offset_error_kpa,
                seed=config.sim.seed,
                device=wired.channel.strip("/").split("/")[0],
                output_channel=wired.channel,
                supply_channel=wired.supply_channel,
            )

        return [
            check_pump(
                pump,
                rig.clock,
                port=sim.emulator.port,
                timeout_s=SIM_REPLY_TIMEOUT_S,
                search_timeout_s=SIM_SEARCH_TIMEOUT_S,
            ),
            check_pressure(
                named,
                rig.clock,
                task_factory=new_task,
                reader_factory=SimAnalogMultiChannelReader,
            ),
            check_camera(rig.length, None, "simulated camera"),
        ]
    finally:
        rig.close()


def _on_device(channel: str, device: str) -> str:
    return f"{device}/{channel.strip('/').split('/', 1)[1]}"
