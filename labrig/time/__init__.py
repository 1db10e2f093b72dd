"""Time for the rig: the ``Clock`` every device and the runner share, the real one, and a
virtual one on which the simulated rig runs as fast as the host computes it.
"""

from labrig.exports import lazy_exports

__getattr__, __dir__ = lazy_exports(
    "labrig.time",
    {
        "clock": ["Clock", "ClockThread", "RealClock", "ScaledClock"],
        "virtual": ["VirtualClock"],
    },
)
