"""The stability model of interconnected fluidic segments (Overvelde et al. 2016).

Every segment source (analytical braided tube, Gent sphere, measured table) produces a
``SegmentCurve``: a shape-preserving tabulated p(v), l(v). Actuators of n segments share
one pressure under total-volume control; their equilibria, stability, inflation and
deflation paths and transitions are computed from the curves alone.
"""
