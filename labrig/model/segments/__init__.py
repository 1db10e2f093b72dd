"""Segment sources, each reduced to a ``SegmentCurve``: the analytical braided tube, the
Gent membrane, measured tables (CSV, shape fit) and the library that finds them by name.

The bottom layer of the model: nothing here imports the actuator solvers or scans.
"""

from labrig.exports import lazy_exports

__getattr__, __dir__ = lazy_exports(
    "labrig.model.segments",
    {
        "braided": ["BraidedSegment"],
        "curve": ["SegmentCurve"],
        "gent": ["GENT_NAMES", "gent_membrane"],
        "catalog": [
            "LIBRARY_NAMES",
            "analytical_segment",
            "find_measured",
            "is_measured_name",
            "library_geometry",
            "load_segment",
            "resolve_library_dir",
        ],
        "measured": ["curve_from_table", "load_csv", "write_csv"],
        "resolution": ["NOISE_PROMINENCE"],
    },
)
