"""Scans of every actuator of n segments from a library: running them in chunks, the
scan file (HDF5), and its summaries and rankings."""
