"""The rig: the device contracts the runner drives, the assembly of the real or the
simulated devices a rig file names, and the checks of a rig before a run.
"""

from labrig.exports import lazy_exports

__getattr__, __dir__ = lazy_exports(
    "labrig.rig",
    {
        "devices": [
            "LengthSample",
            "LengthSource",
            "PressureBlock",
            "PressureSource",
            "Pump",
            "PumpState",
            "PumpStatus",
            "Rig",
        ],
        "assembly": ["build_rig"],
        "simulated": ["SimulatedParts"],
        "check": ["check_rig", "report"],
        "check_sim": ["check_sim_rig", "simulated_config"],
    },
)
