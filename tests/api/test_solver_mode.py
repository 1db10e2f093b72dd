"""The API's solver choice speaks the model's own switch."""

import os
import subprocess
import sys

from labrig.api import solver_mode
from labrig.model.actuator import jit


def test_the_api_names_the_switch_the_model_reads():
    assert (solver_mode.MODE_VARIABLE, solver_mode.PYTHON) == (jit.MODE_VARIABLE, jit.PYTHON)


def test_a_notebook_solves_one_actuator_as_plain_python_and_leaves_the_environment():
    probe = (
        "import os, labrig\n"
        "labrig.actuator('B48-T30', 'B50-T20').path()\n"
        "from labrig.model.actuator import jit\n"
        "print(jit.COMPILED, os.environ.get('LABRIG_JIT'))"
    )
    env = {k: v for k, v in os.environ.items() if k != "LABRIG_JIT"}
    out = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, env=env, check=True
    ).stdout
    assert out.split() == ["False", "None"]
