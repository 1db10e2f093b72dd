"""Why the 5 quintuples that fail in the n = 5 scan of the library fail (and a
sextuple that fails alike in n = 6).

In each, one segment is just past its peak (falling, k < 0) and its 1/k term is nearly
cancelled by the others' (Eq. 10: sum 1/k comes within ~1e-4 of zero along a stretch
of otherwise stable states). Four of the five do it with two segments of the same braid
length, which peak at exactly the same pressure (docs/reference/segments.md), one either side of
it; the fifth with SI-B46-T26 against three rising B48 segments. There sum 1/k crosses
zero twice, 1e-7 to 9e-5 kPa apart: a fold pair. Inflating, the state is lost at the
first fold and the same branches are stable again past the second, the volume regained
within 1e-9 mL. So a state to snap to exists: the same branches, just past the second
fold; the snap would move ~1e-10 mL. The path solver's flow from the fold cannot
resolve a basin that shallow: it stalls within rounding of the fold (every start
distance it tries, 1e-4 to 0.1 mL, ends back on the fold's own stretch, which the
solver rejects); for the first quintuple starts from 0.5 mL on cross into a farther
basin (the two B40 segments swap sides of their peak), which is not where the
quasi-static path goes. The solver raises FlowError and the scan records the actuator as failed
with that reason.

Whether the flow stalls there is decided in the last bits of the host's arithmetic (a
basin 1e-9 mL deep against rounding of ~1e-11 mL): on another processor (seen on an AMD
EPYC host) the same code finds a state and snaps at the fold, by ~1e-11 mL onto the same
branches or into a farther basin. So the solver's part is checked as what holds on any
host: it stops at this fold, either giving up there (FlowError naming the fold) or
snapping there.

The fold pair is shown with a method that shares no code with the path solver: every
segment's curve inverted on its branch at each pressure of a fine grid
(``SegmentCurve.volumes_at_pressure``, the Fig. S5 equilibria).
"""

import re

import numpy as np
import pytest

from labrig.model.actuator.descent import FlowError
from labrig.model.actuator.equilibria import Actuator
from labrig.model.actuator.path import quasi_static_path
from labrig.model.segments.catalog import SI_PREFIX, analytical_segment

# (segments, each one's branch on the stretch that folds, a pressure near the fold, the
# half-width of the pressure window that holds the pair):
# the failures of `labrig model scan --n 5`, and one of n = 6 met by
# tests/benchmarks/bench_scan_plan.py's sample
# (the SI's segments: the library those scans ran on)
_FOLDS = [
    (("B40-T20", "B40-T24", "B40-T26", "B42-T20", "B44-T20"), (2, 0, 1, 2, 2), 38.182135, 2e-5),
    (("B40-T22", "B46-T28", "B48-T28", "B50-T20", "B50-T30"), (2, 2, 2, 0, 1), 40.455383, 2e-5),
    (("B44-T28", "B48-T22", "B48-T26", "B50-T24", "B50-T26"), (2, 2, 2, 0, 1), 40.429914, 2e-5),
    (("B44-T30", "B46-T20", "B46-T28", "B50-T20", "B50-T30"), (2, 2, 2, 0, 1), 40.455383, 2e-5),
    (("B46-T20", "B46-T26", "B48-T24", "B48-T28", "B48-T30"), (2, 1, 0, 0, 0), 39.237506, 2e-3),
    (
        ("B40-T30", "B42-T22", "B46-T22", "B48-T28", "B50-T20", "B50-T30"),
        (0, 2, 2, 2, 0, 1),
        40.455383,
        2e-5,
    ),
]
FOLD_PAIRS = [(tuple(SI_PREFIX + n for n in names), *rest) for names, *rest in _FOLDS]


def _along(actuator, branches, p_kpa):
    """v(p) and sum 1/k(p) on one branch of each segment, at every pressure p_kpa."""
    v = np.zeros_like(p_kpa)
    inverse_sum = np.zeros_like(p_kpa)
    for segment, branch in zip(actuator.segments, branches, strict=True):
        v_i, k_i = segment.volumes_at_pressure(p_kpa)
        v += v_i[:, branch]
        inverse_sum += 1.0 / k_i[:, branch]
    return v, inverse_sum


@pytest.mark.parametrize(("names", "branches", "p_near_kpa", "window_kpa"), FOLD_PAIRS)
def test_a_failing_actuator_folds_on_a_pair_of_folds_below_the_flows_resolution(
    names, branches, p_near_kpa, window_kpa
):
    actuator = Actuator([analytical_segment(n) for n in names])
    p = p_near_kpa + np.linspace(-window_kpa, window_kpa, 4001)
    v, inverse_sum = _along(actuator, branches, p)
    assert np.all(np.isfinite(v)), "every segment is on that branch over the whole window"
    # stable (sum 1/k < 0) on both sides, lost in between: exactly two folds
    assert inverse_sum[0] < 0 and inverse_sum[-1] < 0
    folds = np.nonzero(np.diff(np.sign(inverse_sum)))[0]
    assert len(folds) == 2
    lower, upper = folds
    # one segment past its peak, whose 1/k the others cancel
    slopes = [
        float(segment.volumes_at_pressure(p[upper : upper + 1])[1][0, branch])
        for segment, branch in zip(actuator.segments, branches, strict=True)
    ]
    assert sum(1 for k in slopes if k < 0) == 1
    # inflation runs to lower pressure here (sum 1/k < 0): the state is lost at the upper
    # fold, a maximum of v(p), and regained on the same branches past the lower one
    assert p[upper] - p[lower] < 1e-4
    depth_ml = v[upper] - v[lower]
    assert 0 < depth_ml < 1e-9
    assert v[0] > v[upper]  # further on, the same branches hold more volume: stable again
    # and that fold is where the path solver gives up, or (on other hosts) snaps
    try:
        path = quasi_static_path(actuator)
    except FlowError as failed:
        assert "no state to snap to from the fold" in str(failed)
        # the one-line PathError quotes the flow's own message, with the fold's volume
        v_failed_ml = float(re.search(r"fold at v = ([0-9.]+) mL", str(failed)).group(1))
        assert v[upper] == pytest.approx(v_failed_ml, abs=1e-4)
    else:
        snaps_ml = [e.pre.v_ml for e in path.events if e.kind == "snap"]
        assert any(abs(v_ml - v[upper]) < 1e-4 for v_ml in snaps_ml), (v[upper], snaps_ml)
