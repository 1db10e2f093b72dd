"""The API's solver choice: the model's own switch, set by the API's calls (one actuator
each: plain Python), whatever a notebook imported first; checked in fresh processes with
an empty numba cache, as on a fresh install."""

import os
import shutil
import subprocess
import sys

import h5py
import pytest

from labrig.api import solver_mode
from labrig.model.actuator import jit

# what a probe prints after its calls: numba imported?, the mode, LABRIG_JIT left as found
REPORT = (
    "from labrig.model.actuator import jit\n"
    "print('numba' in sys.modules, jit.COMPILED, os.environ.get('LABRIG_JIT'))\n"
)


def _fresh_process(probe: str, cache) -> list[str]:
    """What ``probe`` prints, run by a new interpreter with no mode chosen and numba's
    cache in the new folder ``cache``, which must hold no file after (nothing compiled:
    numba makes a folder per module as it decorates, its files as it compiles)."""
    env = {k: v for k, v in os.environ.items() if k != "LABRIG_JIT"}
    env["NUMBA_CACHE_DIR"] = str(cache)
    out = subprocess.run(
        [sys.executable, "-c", "import os, sys\n" + probe + REPORT],
        capture_output=True,
        text=True,
        env=env,
        check=True,
    ).stdout
    compiled = [p for p in cache.rglob("*") if p.is_file()]
    assert not compiled, compiled
    return out.split()


def test_the_api_names_the_switch_the_model_reads():
    assert (solver_mode.MODE_VARIABLE, solver_mode.PYTHON) == (jit.MODE_VARIABLE, jit.PYTHON)


def test_importing_the_api_imports_neither_the_model_nor_the_analysis(tmp_path):
    probe = (
        "import labrig\n"
        "import labrig.api.run, labrig.api.campaign, labrig.api.model, labrig.api.scan\n"
        "assert labrig.open_run and labrig.open_runs and labrig.actuator and labrig.open_scan\n"
        "loaded = [m for m in sys.modules if m.startswith(('labrig.model', 'numba'))]\n"
        "loaded += [m for m in ('labrig.analysis.compare', 'labrig.analysis.analyse')"
        " if m in sys.modules]\n"
        "print(len(loaded), *loaded)\n"
    )
    out = _fresh_process(probe, tmp_path / "numba")
    assert out[:1] == ["0"], out
    assert "jit" not in " ".join(out)


def test_a_notebook_solves_one_actuator_as_plain_python_and_leaves_the_environment(tmp_path):
    probe = "import labrig\nlabrig.actuator('B48-T30', 'B50-T20').path()\n"
    assert _fresh_process(probe, tmp_path / "numba") == ["False", "False", "None"]


@pytest.mark.parametrize("stored", [True, False], ids=["stored", "analysed-now"])
def test_a_runs_comparison_compiles_nothing(quick_run, tmp_path, stored):
    """A run whose analysis is stored reads it; one without (live, killed, never
    analysed) is analysed and compared with the model now: either way as plain Python."""
    run = tmp_path / "run.h5"
    shutil.copyfile(quick_run, run)
    if not stored:
        with h5py.File(run, "a") as h5:
            del h5["entry/analysis"]
    probe = f"import labrig\nassert len(labrig.open_run({str(run)!r}).comparison)\n"
    assert _fresh_process(probe, tmp_path / "numba") == ["False", "False", "None"]


def test_a_model_imported_first_keeps_its_mode(tmp_path):
    """The API does not switch a process whose model is loaded already (a script that
    imported the solver compiled keeps it compiled: the modes never mix)."""
    probe = (
        "from labrig.model.actuator import path\n"
        "import labrig\nlabrig.actuator('B48-T30', 'B50-T20').segments\n"
    )
    assert _fresh_process(probe, tmp_path / "numba") == ["True", "True", "None"]


def test_the_analysis_function_keeps_its_name_beside_its_module():
    """``labrig.analysis.analyse`` is the function, also once its module was imported."""
    probe = (
        "import labrig.analysis.analyse\n"
        "from labrig.analysis import analyse\n"
        "assert analyse is sys.modules['labrig.analysis.analyse'].analyse, analyse\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "LABRIG_JIT"}
    subprocess.run([sys.executable, "-c", "import sys\n" + probe], env=env, check=True)
