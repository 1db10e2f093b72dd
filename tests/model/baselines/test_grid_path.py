"""The pressure-grid path (the benchmark's Fig. S5 baseline) against the continuation:
the same transitions, snap volumes that converge with the grid, crossings that lag by
the square root of the spacing."""

import numpy as np
import pytest
from support.actuator_curves import cubic_segment

from labrig.model.actuator.equilibria import Actuator
from labrig.model.actuator.path import quasi_static_path
from labrig.model.actuator.transitions import transitions
from labrig.model.baselines.grid_path import grid_path
from labrig.model.segments.catalog import analytical_segment

NAMED = [
    ("SI-B48-T30", "SI-B50-T20"),
    ("SI-B46-T20", "SI-B46-T22"),
    ("SI-B44-T30", "SI-B48-T26"),
    ("SI-B40-T28", "SI-B44-T30", "SI-B50-T24"),
]


@pytest.mark.parametrize("names", NAMED, ids=" + ".join)
def test_a_fine_grid_finds_the_continuations_transitions(names):
    actuator = Actuator([analytical_segment(n) for n in names])
    fast = transitions(quasi_static_path(actuator))
    v_end = fast[-1].v_ml + 1.0
    grid = grid_path(actuator, v_end, n_points=4000)
    assert [(t.alpha, t.beta, t.stable) for t in grid] == [
        (t.alpha, t.beta, t.stable) for t in fast
    ]
    for g, f in zip(grid, fast, strict=True):
        assert g.v_ml <= f.v_ml + 1e-9  # the last grid point before it
        if not f.stable:
            assert f.v_ml - g.v_ml < 0.05  # 4000 points: 0.025 kPa
            d_e = actuator.energy_mj(g.v_i_post_ml) / actuator.energy_mj(g.v_i_pre_ml) - 1
            assert d_e == pytest.approx(f.dE, abs=3e-4)
            np.testing.assert_allclose(g.v_i_post_ml, f.post.v_i_ml, atol=0.1)
        else:
            assert f.v_ml - g.v_ml < 1.0  # a peak: v ~ sqrt(p_peak - p)


def test_snap_volumes_converge_with_the_grid():
    actuator = Actuator([cubic_segment("A", 4.0, 10.0, 30.0), cubic_segment("B", 5.0, 13.0, 33.0)])
    fast = [t for t in transitions(quasi_static_path(actuator)) if not t.stable]
    errors = []
    for n_points in (250, 1000, 4000):
        snaps = [t for t in grid_path(actuator, 40.0, n_points=n_points) if not t.stable]
        assert len(snaps) == len(fast) == 1
        errors.append(fast[0].v_ml - snaps[0].v_ml)
    assert 0 <= errors[2] < errors[1] < errors[0] < 0.2
