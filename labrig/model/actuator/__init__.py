"""Actuators of n segments under volume control: equilibria and their stability, the
quasi-static path, the post-snap flow, transitions, and the compiled kernels they share.

Built on ``labrig.model.segments`` alone; the reference solvers and scans stand above it.
"""
