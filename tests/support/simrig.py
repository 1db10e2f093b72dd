"""Shared helpers for the tests that drive the whole simulated rig: the real drivers
talking to the pty pump emulator, SimDaqTask and SimCamera, all fed by one plant."""

import textwrap
from dataclasses import dataclass
from pathlib import Path

from labrig.config.protocol import load_protocol
from labrig.config.rig_file import sim_rig_config
from labrig.rig.assembly import build_rig
from labrig.rig.devices import Rig
from labrig.run.runner import Runner, RunResult

DEMO = Path(__file__).parents[2] / "protocols" / "demo.yaml"

SHORT = textwrap.dedent(
    """\
    name: short fault test
    specimen: {{segments: [SI-B46-T20, SI-B46-T22], fittings_length_mm: 10}}
    rig: sim
    limits: {{max_pressure_kpa: {max_pressure_kpa}, max_volume_ml: 40}}
    acquisition: {{pressure_rate_hz: 1000, camera_fps: {camera_fps}}}
    steps:
      - zero_pressure: {{duration_s: 1}}
      - repeat:
          times: 2
          steps:
            - infuse: {{rate_ml_min: 60, volume_ml: 20}}
            - hold: {{seconds: 2}}
            - withdraw: {{rate_ml_min: 60, volume_ml: 20}}
    """
)


@dataclass
class Outcome:
    result: RunResult
    rig: Rig
    end_s: float

    @property
    def path(self) -> Path:
        return self.result.path

    def pump_is_stopped(self) -> bool:
        """The emulated plunger does not move after the run ended."""
        emulator = self.rig.simulation.emulator
        return emulator.net_volume_ml(self.end_s) == emulator.net_volume_ml(self.end_s + 30.0)


def run_sim(
    tmp_path,
    text,
    *,
    inject=None,
    speed=None,
    seed=0,
    name="run.h5",
    config=None,
    prepare=None,
    tap=None,
) -> Outcome:
    """Run protocol ``text`` on a fresh simulated rig; ``inject(rig)`` runs in a thread
    that takes part in the rig's time, so it acts at a definite rig time and holds time
    still while it acts. ``config``: a simulated rig configuration of the test's own;
    ``prepare(rig)`` acts on the rig before the run; ``tap(rig)`` gives the run's data
    tap (it sees every append to the run file)."""
    protocol_path = tmp_path / "protocol.yaml"
    protocol_path.write_text(text)
    loaded = load_protocol(protocol_path)
    rig = build_rig(loaded.protocol, config or sim_rig_config(speed, seed))
    if prepare is not None:
        prepare(rig)
    # the main thread takes part in time before the injector starts: alone, a waiting
    # injector would see everyone waiting and let time run to its timeout
    with rig.clock.participate():
        if inject is not None:
            rig.clock.start_thread(lambda: inject(rig), "inject")
        data_tap = tap(rig) if tap is not None else None
        result = Runner(loaded, rig, tmp_path / name, data_tap=data_tap).run()
    return Outcome(result, rig, rig.clock.now())


def when_volume_exceeds(rig, volume_ml, timeout_s=3600.0) -> bool:
    """Wait (rig time) until the specimen holds ``volume_ml``."""
    emulator = rig.simulation.emulator
    return rig.clock.wait_for(
        lambda: emulator.net_volume_ml(rig.clock.now()) > volume_ml, timeout_s=timeout_s
    )


def short_protocol(max_pressure_kpa=95, camera_fps=2) -> str:
    return SHORT.format(max_pressure_kpa=max_pressure_kpa, camera_fps=camera_fps)
