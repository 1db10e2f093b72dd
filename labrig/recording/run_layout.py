"""The run file's layout, shared by the writer and every reader: the NXlog fields
with their dtypes and units, the fixed sizes of status strings, and group names."""

# 48 kS/s, the USB-6009's fastest, for 87 minutes: more is no run of this rig, and
# 2e9 values (16 GB) would be asked of memory before anything could say so
MAX_DATASET_VALUES = 250_000_000

STATUS_SIZE = 16
REASON_SIZE = 512
TIME_SIZE = 32
CHUNK = 4096

# name -> (dtype, units) of the fields of each NXlog; "value" is the logged quantity.
LOG_FIELDS: dict[str, dict[str, tuple[str, str]]] = {
    "pressure": {
        "time": ("f8", "s"),
        "value": ("f8", "kPa"),
        "out_of_range": ("?", ""),
    },
    "pump": {
        "time": ("f8", "s"),
        "value": ("f8", "mL"),
        "infused": ("f8", "mL"),
        "withdrawn": ("f8", "mL"),
        "state": (f"S{STATUS_SIZE}", ""),
    },
    "length": {
        "time": ("f8", "s"),
        "value": ("f8", "mm"),
        "x1": ("f8", "px"),
        "y1": ("f8", "px"),
        "x2": ("f8", "px"),
        "y2": ("f8", "px"),
        "ok": ("?", ""),
    },
    "force": {
        "time": ("f8", "s"),
        "value": ("f8", "N"),
    },
}
LOG_DESCRIPTION = {
    "pressure": "specimen pressure (gauge, zeroed)",
    "pump": "net volume supplied by the pump (infused - withdrawn)",
    "length": "specimen length between the two markers",
    "force": "reaction force of the blocked actuator on the load cell (compression positive)",
}
# What the technician and the reservoir did, in order (entry/events): a prompt, the
# connection it made, a reservoir push and its volume.
EVENT_FIELDS = {
    "time": ("f8", "s"),
    "kind": (f"S{STATUS_SIZE}", ""),
    "volume": ("f8", "mL"),
    "message": (f"S{REASON_SIZE}", ""),
}
# The run's video (labrig.recording.video): frame i of the file was taken at time[i].
VIDEO_FIELDS = {"time": ("f8", "s"), "repetition": ("i4", "")}
# The camera's frame rate (entry/camera, with a camera), scalars in Hz: auto exposure
# can lower the real rate below the nominal one while the camera still reports that.
CAMERA_FIELDS = {
    "nominal_fps": "the protocol's acquisition.camera_fps",
    "measured_fps": "the rate the frames really came at over the run, set at its end "
    "(NaN: fewer than two frames)",
}

# /entry/specimen_model: the protocol's specimen.model as run (absent in older files)
SPECIMEN_MODEL_DESCRIPTION = (
    "the protocol's specimen.model: 'segments' (the model is built from the specimen's "
    "segments) or 'none' (the specimen had no model; its segments are labels)"
)

RUN_STATUSES = ("running", "complete", "aborted", "faulted")
REPETITION_STATUSES = ("pending", "running", "complete", "aborted", "faulted")


def repetition_name(index: int) -> str:
    """Group name of repetition ``index`` (1-based): rep_01, rep_02, ..."""
    return f"rep_{index:02d}"
