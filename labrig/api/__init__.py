"""The researcher's Python API: runs, campaigns, the model and scans as pandas and
xarray objects, for a notebook.

Import it from ``labrig`` itself (``labrig.open_run``, ``labrig.open_runs``,
``labrig.segment``, ``labrig.actuator``, ``labrig.open_scan``); the modules of this
package are its implementation, not a second namespace. Every reader here is a thin
layer over what the commands use (the run file reader, the analysis, ``compare --json``,
``model path --json``, the scan file reader), so a field the commands gain appears here
without an edit here.
"""
