"""The solver's inner loops as plain Python (``LABRIG_JIT=python``) and compiled by numba
give the same results, bit for bit, on chunks of pairs, triples and quadruples with
deflation; and the console script runs the one-actuator commands without numba, and a
scan compiled only where that pays."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from support.scan_helpers import small_library

from labrig.model.actuator import jit
from labrig.model.scan.scan import TRANSITION_FIELDS, Chunk, run_chunk

# (n, first rank, last rank + 1) of the 8-segment library: every pair, the last 20
# triples and the last 12 quadruples, with deflation. They run every branch of the
# solver's loops (coverage.py's arcs in plain Python: 1,520) that the triples and
# quadruples from the start and the middle of their order ran too, which added none and
# took two thirds of this test's time in plain Python
CHUNKS = [(2, 0, 28), (3, 36, 56), (4, 58, 70)]

_IN_PYTHON = """
import sys
import numpy as np
sys.path.insert(0, {helpers!r})
from support.scan_helpers import small_library
from labrig.model.actuator import jit
from labrig.model.scan.scan import Chunk, run_chunk, TRANSITION_FIELDS
assert not jit.COMPILED
arrays = {{}}
for i, (n, start, stop) in enumerate({chunks!r}):
    r = run_chunk(small_library(), Chunk(i, start, stop, n, deflate=True))
    assert len(r.failed_actuator) == 0, r.failed_error
    arrays[f"{{i}}/actuator"] = r.actuator
    for name in TRANSITION_FIELDS:
        arrays[f"{{i}}/{{name}}"] = r.columns[name]
np.savez({out!r}, **arrays)
"""


@pytest.mark.slow
def test_python_and_compiled_loops_give_the_same_bits(tmp_path):
    assert jit.COMPILED  # this process compiles (LABRIG_JIT unset)
    out = tmp_path / "python.npz"
    helpers = str(Path(__file__).parents[2])
    code = _IN_PYTHON.format(helpers=helpers, chunks=CHUNKS, out=str(out))
    env = {**os.environ, jit.MODE_VARIABLE: jit.PYTHON}
    subprocess.run([sys.executable, "-c", code], env=env, check=True)
    plain = np.load(out)
    rows = 0
    for i, (n, start, stop) in enumerate(CHUNKS):
        compiled = run_chunk(small_library(), Chunk(i, start, stop, n, deflate=True))
        np.testing.assert_array_equal(plain[f"{i}/actuator"], compiled.actuator)
        for name in TRANSITION_FIELDS:
            # bit for bit: the float64 patterns, not a tolerance
            a, b = plain[f"{i}/{name}"], compiled.columns[name]
            assert a.dtype == b.dtype and a.tobytes() == b.tobytes(), (i, name)
        rows += len(compiled.actuator)
    assert rows > 500  # snaps and stable transitions of 60 actuators, both directions


_CHECK_IMPORTS = """
import sys
sys.argv = {argv!r}
from labrig.cli import main
try:
    main()
except SystemExit as exc:
    code = exc.code
mode = getattr(sys.modules.get("labrig.model.actuator.jit"), "COMPILED", None)
print("EXIT", code, "NUMBA", "numba" in sys.modules, "COMPILED", mode, file=sys.stderr)
"""


@pytest.mark.parametrize(
    ("argv", "numba", "compiled"),
    [
        (["labrig", "model", "path", "B48-T30", "B50-T20", "--json"], False, False),
        (["labrig", "run", "protocols/demo.yaml", "--dry-run"], False, False),
        # a scan reads numba's cache to choose (labrig.model.scan.plan): gent's three
        # pairs cost less in Python than loading the compiled code, the 630 pairs of the
        # analytical library more (this group's fixture compiled it)
        (
            ["labrig", "model", "scan", "--n", "2", "--library", "gent", "--out", "{out}"],
            True,
            False,
        ),
        (["labrig", "model", "scan", "--n", "2", "--out", "{out}"], True, True),
    ],
)
def test_the_console_script_compiles_only_for_many_actuators(tmp_path, argv, numba, compiled):
    argv = [a.format(out=tmp_path / "s.h5") for a in argv]
    env = {k: v for k, v in os.environ.items() if k != jit.MODE_VARIABLE}
    code = _CHECK_IMPORTS.format(argv=argv)
    repo = Path(__file__).parents[3]
    done = subprocess.run(
        [sys.executable, "-c", code], env=env, cwd=repo, capture_output=True, text=True
    )
    last = done.stderr.strip().splitlines()[-1]
    assert last == f"EXIT 0 NUMBA {numba} COMPILED {compiled}", done.stderr


_WARNINGS = """
import warnings
from labrig.model.scan.scan import Chunk, ScanLibrary, run_chunk
from labrig.model.segments.catalog import SI_NAMES, analytical_segment
library = ScanLibrary("si", tuple(analytical_segment(n) for n in SI_NAMES[::5]))
# the last five triples of the 8 segments: three of them meet the one warning that any
# triple of them meets (an invalid value in a scalar add, in curve_tables)
chunk = Chunk(0, 51, 56, 3)
with warnings.catch_warnings(record=True) as shown:
    run_chunk(library, chunk)
with warnings.catch_warnings(record=True) as raised:
    warnings.simplefilter("always")
    run_chunk(library, chunk)
print(len(shown), len({str(w.message) for w in raised if w.category is RuntimeWarning}))
"""


def test_plain_python_hides_numpys_warnings_of_expected_infinities():
    """numpy warns where the 1/k sums meet both signs of inf (the compiled code gives the
    same nan silently): a scan in plain Python shows the user none of it."""
    env = {**os.environ, jit.MODE_VARIABLE: jit.PYTHON}
    done = subprocess.run(
        [sys.executable, "-c", _WARNINGS], env=env, capture_output=True, text=True, check=True
    )
    shown, raised = map(int, done.stdout.split())
    assert raised > 0  # the triples meet them
    assert shown == 0
