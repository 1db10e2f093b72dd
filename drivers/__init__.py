"""Drivers for the real instruments of the rig.

Each driver speaks one instrument's language in physical units and takes its transport
(a serial port or URL, a nidaqmx Task factory, a capture object) as a parameter: that is
where the simulators of ``labrig.sim`` plug in, with no change to the driver's code.
"""

from labrig.exports import lazy_exports

__getattr__, __dir__ = lazy_exports(
    "labrig.drivers",
    {
        "camera": ["CameraLength", "CameraSettings", "FrameSource"],
        "ni_daq": ["NiDaqPressure"],
        "phd_ultra": ["PhdUltra"],
        "phd_ultra_errors": ["PumpPortError", "PumpProtocolError", "PumpTimeout"],
    },
)
