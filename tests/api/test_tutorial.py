"""The tutorial notebook runs top to bottom on this install, and is committed with its
outputs (so GitHub shows them); ``python tests/support/tutorial.py`` stores them."""

import pytest
from support.tutorial import NOTEBOOK, execute


@pytest.mark.slow
def test_the_tutorial_runs_top_to_bottom(tmp_path):
    notebook = execute(tmp_path)  # CellExecutionError names the failing cell
    outputs = [o for cell in notebook.cells if cell.cell_type == "code" for o in cell.outputs]
    assert not [o for o in outputs if o.output_type == "error"]
    text = "\n".join(o.get("data", {}).get("text/plain", "") for o in outputs)
    assert "<labrig.Run seed1.h5: 'quick demo pair', complete, 2 repetitions>" in text
    assert sorted(p.name for p in (tmp_path / "runs").iterdir()) == [
        "seed1.h5",
        "seed2.h5",
        "seed3.h5",
    ]
    # the campaign's table: three runs, each with the model's snap beside the measured one
    assert text.count("runs/seed") >= 3 and "snap1_v_error_ml" in text


def test_the_committed_tutorial_holds_its_outputs():
    import nbformat

    notebook = nbformat.read(NOTEBOOK, as_version=4)
    nbformat.validate(notebook)
    code = [cell for cell in notebook.cells if cell.cell_type == "code"]
    assert [cell.execution_count for cell in code] == list(range(1, len(code) + 1))
    shown = [cell for cell in code if cell.outputs]
    assert len(shown) >= len(code) - 2  # the imports and the helper print nothing
    assert not [o for c in code for o in c.outputs if o.output_type == "error"]
    images = [o for c in code for o in c.outputs if "image/png" in o.get("data", {})]
    assert len(images) >= 3
