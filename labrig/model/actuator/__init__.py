"""Actuators of n segments under volume control: equilibria and their stability, the
quasi-static path, the post-snap flow, transitions (the path's events, and the paper's
counting of them), and the compiled kernels they share.

Built on ``labrig.model.segments`` alone; the reference solvers and scans stand above it.
"""

from labrig.exports import lazy_exports

__getattr__, __dir__ = lazy_exports(
    "labrig.model.actuator",
    {
        "equilibria": ["Actuator"],
        "path": ["DEFLATE", "INFLATE", "Path", "SampledPath", "quasi_static_path", "sample_path"],
        "transitions": ["Transition"],
        "paper_counting": [
            "PaperTransition",
            "SAME_VOLUME_ML",
            "group_paper_transitions",
            "paper_transitions",
        ],
        "descent": ["FlowError"],
        "prediction": ["predicted_inflation", "predicted_peak_pressure_kpa"],
    },
)
