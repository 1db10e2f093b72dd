"""The compiled path of a whole actuator (``labrig.model.actuator.compiled_path``) gives
the reference's rows bit for bit (``path.py`` + ``transitions.py``, the second method
here), on chunks of the library and on generated curves; where it gives up, a scan
takes the reference's rows or error; its ``fsum`` is ``math.fsum``."""

import math
import struct

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from support.scan_helpers import small_library
from support.stress_curves import STRESS, TWIN, knot_curve, shapes

from labrig.model.actuator import compiled_path
from labrig.model.scan import scan
from labrig.model.scan.scan import ScanLibrary, combinations_between, run_chunk
from labrig.model.segments.catalog import LIBRARY_NAMES, analytical_segment


def _bits(rows):
    """An actuator's rows (int and float arrays) as bytes: floats by their IEEE
    patterns (-0.0 != 0.0)."""
    ints, floats = rows
    assert ints.dtype == np.int64 and floats.dtype == np.float64
    assert ints.shape == (len(floats), 4) and floats.shape == (len(ints), 5)
    return ints.tobytes() + b"|" + floats.tobytes()


def _reference(library, combo, deflate):
    try:
        return scan.reference_rows(library, combo, deflate), None
    except Exception as exc:
        return None, exc


def assert_same_as_reference(library, combo, deflate):
    """The compiled rows equal the reference's; returns False where the compiled path
    gave up (the reference then decides, and may fail itself)."""
    expected, error = _reference(library, combo, deflate)
    try:
        got = scan._CompiledRows(library).compiled(combo, deflate)
    except Exception:
        return False
    assert error is None, f"the reference fails ({error}) where the compiled path does not"
    assert _bits(got) == _bits(expected), combo
    return True


# (n, first rank, last rank + 1) of the 8-segment library, as in test_jit
CHUNKS = [(2, 0, 28), (3, 0, 56), (4, 0, 70)]


@pytest.mark.slow
@pytest.mark.parametrize(("n", "start", "stop"), CHUNKS)
def test_library_chunks_are_compiled_whole_and_give_the_same_bits(n, start, stop):
    library = small_library()
    rows = 0
    for combo in combinations_between(start, stop, len(library.curves), n):
        for deflate in (False, True):
            assert assert_same_as_reference(library, combo, deflate), combo  # none left
        rows += len(scan._CompiledRows(library).compiled(combo, True)[0])
    assert rows >= 4 * (stop - start)  # snaps and stable transitions both ways


@pytest.mark.slow
def test_quintuples_and_sextuples_of_the_full_library():
    library = ScanLibrary("analytical", tuple(analytical_segment(n) for n in LIBRARY_NAMES))
    rng = np.random.default_rng(13)
    for n in (5, 6):
        for _ in range(12):
            combo = tuple(sorted(int(i) for i in rng.choice(len(LIBRARY_NAMES), n, replace=False)))
            assert assert_same_as_reference(library, combo, deflate=True), combo


@STRESS
@given(st.lists(shapes(), min_size=2, max_size=4), st.booleans())
def test_generated_curves_give_the_same_bits_or_the_reference_decides(knots, deflate):
    """Plateaus, near-flat dips, two peaks: what the compiled path solves is the
    reference's result; what it leaves, the scan gives to the reference."""
    curves = tuple(knot_curve(f"S{i}", *k) for i, k in enumerate(knots))
    _assert_compiled_or_reference(ScanLibrary("generated", curves), deflate)


@pytest.mark.parametrize(
    "knots",
    [
        [TWIN, TWIN],  # identical segments whose fold mirrors itself
        [([0, 1, 2, 5], [0, 40, 39.999999, 300])] * 3,  # three with a common peak and valley
        [([0, 1, 3, 6], [0, 2, 2, 300]), ([0, 1, 2, 5], [0, 2, 1.999999, 300])],  # plateau
    ],
)
def test_degenerate_actuators_give_the_same_bits(knots):
    curves = tuple(knot_curve(f"S{i}", *k) for i, k in enumerate(knots))
    _assert_compiled_or_reference(ScanLibrary("degenerate", curves), True)


def _assert_compiled_or_reference(library, deflate):
    """The compiled rows are the reference's; where it gives up, the scan's rows (or
    error) are the reference's."""
    combo = tuple(range(len(library.curves)))
    if assert_same_as_reference(library, combo, deflate):
        return
    expected, error = _reference(library, combo, deflate)
    solve = scan._rows_function(library)
    if error is None:
        assert _bits(solve(combo, deflate)) == _bits(expected)
    else:
        with pytest.raises(type(error)):
            solve(combo, deflate)


def test_a_scan_gives_what_the_compiled_path_leaves_to_the_reference(monkeypatch):
    """An actuator the compiled path gives up on is solved by the reference: the chunk's
    rows are the reference's, and an actuator that fails there is recorded as failed."""
    library = small_library()
    chunk = scan.Chunk(0, 0, 12, 3, deflate=True)
    expected = run_chunk(library, chunk)

    def give_up(*args):
        raise compiled_path.Unported("left to the reference")

    scan._ROWS.clear()
    monkeypatch.setattr(compiled_path, "trace_transitions", give_up)
    try:
        fallback = run_chunk(library, chunk)
    finally:
        scan._ROWS.clear()
    np.testing.assert_array_equal(fallback.actuator, expected.actuator)
    for name in scan.TRANSITION_FIELDS:
        assert fallback.columns[name].tobytes() == expected.columns[name].tobytes(), name


@pytest.fixture(scope="module")
def fsum_compiled():
    """``fsum`` compiled for calls from Python (its first call compiles it, or loads it
    from numba's cache), before hypothesis times each call."""
    compiled_path.fsum(np.zeros(1))


@given(
    st.lists(
        st.one_of(
            st.floats(allow_nan=False, allow_infinity=False),
            st.sampled_from([0.0, -0.0, 1e308, -1e308, 5e-324, 1.0, 1e-16, -1e-16]),
        ),
        max_size=12,
    )
)
def test_fsum_is_math_fsum(fsum_compiled, values):
    array = np.array(values, dtype=float)
    try:
        expected = math.fsum(values)
    except OverflowError:
        with pytest.raises(OverflowError):
            compiled_path.fsum(array)
        return
    assert struct.pack("<d", compiled_path.fsum(array)) == struct.pack("<d", expected)


@pytest.mark.parametrize(
    ("values", "expected"),
    [
        ([math.inf, 1.0], math.inf),
        ([-math.inf, 2.0, -math.inf], -math.inf),
        ([math.nan, 1.0], None),
    ],
)
def test_fsum_of_infinities_and_nan(values, expected):
    got = compiled_path.fsum(np.array(values))
    assert math.isnan(got) if expected is None else got == expected
    with pytest.raises(ValueError):
        compiled_path.fsum(np.array([math.inf, -math.inf]))
