"""Shared helpers for the tests that drive the whole simulated rig: the real drivers
talking to the pty pump emulator, SimDaqTask and SimCamera, all fed by one plant."""

import textwrap
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from labrig.protocol import load_protocol
from labrig.rig import build_rig, sim_rig_config
from labrig.runner import Rig, Runner, RunResult

SHORT = textwrap.dedent(
    """\
    name: short fault test
    specimen: {{segments: [B46-T20, B46-T22], fittings_length_mm: 10}}
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


def run_sim(tmp_path, text, *, inject=None, speed=100.0) -> Outcome:
    """Run protocol ``text`` on a fresh simulated rig; ``inject(rig)`` runs in a thread."""
    protocol_path = tmp_path / "protocol.yaml"
    protocol_path.write_text(text)
    loaded = load_protocol(protocol_path)
    rig = build_rig(loaded.protocol, sim_rig_config(speed))
    if inject is not None:
        threading.Thread(target=inject, args=(rig,), daemon=True).start()
    result = Runner(loaded, rig, tmp_path / "run.h5").run()
    return Outcome(result, rig, rig.clock.now())


def when_volume_exceeds(rig, volume_ml, timeout_s=30.0) -> bool:
    """Block (host time) until the specimen holds ``volume_ml``."""
    deadline = time.monotonic() + timeout_s
    emulator = rig.simulation.emulator
    while time.monotonic() < deadline:
        if emulator.net_volume_ml(rig.clock.now()) > volume_ml:
            return True
        time.sleep(0.002)
    return False


def short_protocol(max_pressure_kpa=95, camera_fps=2) -> str:
    return SHORT.format(max_pressure_kpa=max_pressure_kpa, camera_fps=camera_fps)
