"""One live view from start to end: the state, the model in the background, the server.

``labrig run --live`` and ``labrig watch`` both open one, feed its ``state`` (the first
from the runner, the second from the file), ``finish`` it with the run's status and
``close`` it, which keeps the page up a little longer so that a browser sees the end.
"""

from __future__ import annotations

import time

from labrig.config.protocol import Protocol, plan
from labrig.live.model import BackgroundPrediction
from labrig.live.server import LiveServer
from labrig.live.state import LiveState, RunInfo


def run_info(protocol: Protocol, title: str | None = None) -> RunInfo:
    the_plan = plan(protocol)
    return RunInfo(
        title=title or protocol.name,
        repetitions=max(1, the_plan.repetitions),
        duration_s=the_plan.duration_s,
        max_volume_ml=the_plan.max_volume_ml,
        max_pressure_kpa=protocol.limits.max_pressure_kpa,
        segments=tuple(protocol.specimen.segments),
    )


class LiveView:
    """The live page of one run, served on 127.0.0.1:``port`` (0: any free port)."""

    def __init__(self, protocol: Protocol, port: int = 0, title: str | None = None) -> None:
        self.state = LiveState(run_info(protocol, title))
        self.model = BackgroundPrediction(protocol)
        self.server = LiveServer(self.state, self.model, port)

    @property
    def url(self) -> str:
        return self.server.url

    def start(self) -> LiveView:
        self.state.start()
        self.model.start()
        self.server.start()
        return self

    def finish(self, status: str, reason: str = "") -> None:
        self.state.finish(status, reason)

    def close(self, hold_s: float = 0.0) -> None:
        """Serve ``hold_s`` more seconds (host time; inf: until Ctrl-C), then stop."""
        deadline = time.monotonic() + hold_s
        try:
            while (left := deadline - time.monotonic()) > 0:
                time.sleep(min(1.0, left))
        except KeyboardInterrupt:
            pass
        finally:
            self.server.close()
            self.state.close()
