"""Drivers for the real instruments of the rig.

Each driver speaks one instrument's language in physical units and takes its transport
(a serial port or URL, a nidaqmx Task factory, a capture object) as a parameter: that is
where the simulators of ``labrig.sim`` plug in, with no change to the driver's code.
"""
