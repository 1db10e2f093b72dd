"""The model against the paper: its statements, checked (``checker``), and the fit that
calibrates the library on a named subset of them (``fit``).

A package above the model, the simulator and the analysis: it reads all three (Movie
S7 is a run of the simulated plumbing) and none of them reads it."""
