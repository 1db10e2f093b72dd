"""The run plot's transition marks: snaps labelled with their jump, steep stretches of
the model's own curve marked apart and unlabelled."""

import pytest
from support.simulated_runs import simulate_run

from labrig.analysis import analyse
from labrig.analysis.plot import _mark_transitions


@pytest.fixture(scope="module")
def demo_pair(tmp_path_factory):
    """The demo's pair on the plant at the rig's default flow resistance: one large snap
    on inflation and steep stable stretches around it."""
    path = tmp_path_factory.mktemp("runs") / "demo_pair.h5"
    run = simulate_run(
        path, ("B48-T30", "B50-T20"), volume_ml=30.0, resistance_kpa_s_per_ml=0.1, seed=3
    )
    return analyse(run.path, segments=["B48-T30", "B50-T20"])


def test_only_the_snaps_get_a_label(demo_pair):
    result = demo_pair
    steep = result.steep_stretches
    snaps = [m.measured for m in result.comparison.matches if m.predicted and m.measured]
    assert steep and snaps
    assert not set(map(id, steep)) & set(map(id, snaps))
    from matplotlib.figure import Figure

    ax = Figure().add_subplot()
    _mark_transitions(ax, result, "p", result.grid_ml, result.mean_p)
    labelled = [text.get_text() for text in ax.texts]
    assert len(labelled) == len(result.transitions) - len(steep)
    for snap in snaps:
        assert any(f"at {snap.v_ml:.1f} mL" in text for text in labelled)
    _, names = ax.get_legend_handles_labels()
    assert names == ["steep stretches on the model's curve", "measured snaps"] or names == [
        "measured snaps",
        "steep stretches on the model's curve",
    ]


def test_without_a_model_every_transition_is_labelled(demo_pair):
    import dataclasses

    from matplotlib.figure import Figure

    result = dataclasses.replace(demo_pair, comparison=None)
    ax = Figure().add_subplot()
    _mark_transitions(ax, result, "p", result.grid_ml, result.mean_p)
    assert len(ax.texts) == len(result.transitions)
    assert ax.get_legend_handles_labels()[1] == ["measured transitions"]
