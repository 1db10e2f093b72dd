"""Segment sources, each reduced to a ``SegmentCurve``: the analytical braided tube, the
Gent membrane, measured tables (CSV, shape fit) and the library that finds them by name.

The bottom layer of the model: nothing here imports the actuator solvers or scans.
"""
