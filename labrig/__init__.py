"""labrig: acquisition and control for soft-actuator inflation experiments.

The package holds the core (model, run, recording, rig, config, analysis, CLI, time);
real device drivers live in ``labrig.drivers`` and the simulated rig in ``labrig.sim``.

For a notebook, runs, campaigns, the model and scans as pandas and xarray objects
(docs/reference/python-api.md)::

    import labrig
    run = labrig.open_run("runs/demo.h5")      # run.curves, run.comparison, run.plot()
    table = labrig.open_runs("runs/")          # one row a run, as `labrig runs runs/`
    path = labrig.actuator("B48-T30", "B50-T20").path()   # path.transitions

The names are imported on first use, so ``labrig --help`` does not load pandas.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from labrig._version import __version__

# public name -> the module that defines it
_API = {
    "open_run": "labrig.api.run",
    "Run": "labrig.api.run",
    "RunOpenWarning": "labrig.api.run",
    "TransitionFrame": "labrig.api.run",
    "open_runs": "labrig.api.campaign",
    "segment": "labrig.api.model",
    "Segment": "labrig.api.model",
    "actuator": "labrig.api.model",
    "Actuator": "labrig.api.model",
    "ActuatorPath": "labrig.api.model",
    "open_scan": "labrig.api.scan",
    "Scan": "labrig.api.scan",
    "InputError": "labrig.errors",
}
__all__ = ["__version__", *_API]

if TYPE_CHECKING:  # for type checkers and editors; at run time __getattr__ imports
    from labrig.api.campaign import open_runs as open_runs
    from labrig.api.model import Actuator as Actuator
    from labrig.api.model import ActuatorPath as ActuatorPath
    from labrig.api.model import Segment as Segment
    from labrig.api.model import actuator as actuator
    from labrig.api.model import segment as segment
    from labrig.api.run import Run as Run
    from labrig.api.run import RunOpenWarning as RunOpenWarning
    from labrig.api.run import TransitionFrame as TransitionFrame
    from labrig.api.run import open_run as open_run
    from labrig.api.scan import Scan as Scan
    from labrig.api.scan import open_scan as open_scan
    from labrig.errors import InputError as InputError


def __getattr__(name: str):
    if name in _API:
        return getattr(importlib.import_module(_API[name]), name)
    raise AttributeError(f"module 'labrig' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), *_API])
