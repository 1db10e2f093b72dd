"""The simulated rig: devices that behave like the real ones at their interface.

The pump emulator answers the PHD Ultra protocol on a pseudo-terminal, the DAQ simulator
implements the part of the nidaqmx Task API the driver uses, and the camera simulator
renders frames; all of them are driven by a plant built on the stability model.
"""

from labrig.exports import lazy_exports

__getattr__, __dir__ = lazy_exports(
    "labrig.sim",
    {
        "plant": ["Plant"],
        "pump": ["PumpEmulator"],
        "daq": ["SimAnalogMultiChannelReader", "SimDaqTask"],
        "camera": ["SimCamera"],
    },
)
