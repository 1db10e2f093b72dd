"""What a user writes: protocols and rig files (YAML), each checked against a strict schema
with errors that name the file, the key and what is allowed.
"""

from labrig.exports import lazy_exports

__getattr__, __dir__ = lazy_exports(
    "labrig.config",
    {
        "yaml_schema": ["Strict", "parse_yaml_model"],
        "protocol": [
            "HoldStep",
            "InfuseStep",
            "LoadedProtocol",
            "Protocol",
            "WithdrawStep",
            "ZeroPressureStep",
            "iter_plan",
            "load_protocol",
            "parse_protocol",
            "plan",
            "protocol_json_schema",
        ],
        "rig_file": [
            "CameraConfig",
            "PressureConfig",
            "PumpConfig",
            "RigConfig",
            "SimConfig",
            "load_rig_config",
            "rig_config_text",
            "sim_rig_config",
        ],
    },
)
