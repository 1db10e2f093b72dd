"""The simulated rig: devices that behave like the real ones at their interface.

The pump emulator answers the PHD Ultra protocol on a pseudo-terminal, the DAQ simulator
implements the part of the nidaqmx Task API the driver uses, and the camera simulator
renders frames; all of them are driven by a plant built on the stability model.
"""
