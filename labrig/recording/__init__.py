"""What a run leaves behind: its HDF5 file (the layout, the writer, the reader, the repair
of a killed run's file) and its video.
"""

from labrig.exports import lazy_exports

__getattr__, __dir__ = lazy_exports(
    "labrig.recording",
    {
        "run_layout": ["LOG_FIELDS", "REASON_SIZE", "repetition_name"],
        "run_writer": ["RunWriter"],
        "run_reader": ["LogSeries", "decode", "open_run", "read_log", "repetition_statuses"],
        "repair": ["clear_write_flag"],
        "video": ["VideoRecorder"],
    },
)
