"""Scans of every actuator of n segments from a library: running them in chunks, the
scan file (HDF5), and its summaries and rankings."""

from labrig.exports import lazy_exports

__getattr__, __dir__ = lazy_exports(
    "labrig.model.scan",
    {
        "scan": ["ScanInterrupted", "load_library"],
        "run": ["run_scan"],
        "scan_file": ["read_scan"],
        "scan_summary": ["METRICS", "plot_fig4", "rank_designs", "summarise"],
    },
)
