"""labrig: acquisition and control for soft-actuator inflation experiments.

The package holds the core (model, run, recording, rig, config, analysis, CLI, time);
real device drivers live in ``labrig.drivers`` and the simulated rig in ``labrig.sim``.
"""

__version__ = "0.1.0"
