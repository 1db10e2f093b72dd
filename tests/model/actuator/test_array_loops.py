"""The solver's loops for numpy's stable argsort, unique, searchsorted, interp, max, arange
and array_equal (``labrig.model.actuator.array_loops``) give numpy's results bit for bit,
on generated input with ties, single elements, sorted and reversed runs and points outside
the samples: as the plain Python they are written in and, in a compiling process,
compiled."""

import types

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from labrig.model.actuator import array_loops, jit

# NaN-free, and with few distinct values so that ties are common
_FEW = st.sampled_from([-2.5, -1.0, 0.0, 1e-300, 0.5, 1.0, 3.0, 1e300])
_ANY = st.floats(allow_nan=False, allow_infinity=False, width=64)
_VALUES = st.lists(st.one_of(_FEW, _ANY), max_size=60)


def _arranged(values: list[float], arrangement: str) -> np.ndarray:
    a = np.array(values, dtype=np.float64)
    if arrangement == "sorted":
        return np.sort(a)
    if arrangement == "reversed":
        return np.sort(a)[::-1].copy()
    if arrangement == "runs":  # a few sorted runs one after another, as fold_screen's
        return np.concatenate([np.sort(part) for part in np.array_split(a, 3)])
    return a


_ARRANGEMENTS = st.sampled_from(["as drawn", "sorted", "reversed", "runs"])


# the fixture's names for the loops
_LOOPS = {
    "order": "stable_order",
    "unique": "sorted_unique",
    "interp": "interp",
    "count": "count_at_or_below",
    "copy": "copy_into",
    "largest": "largest",
    "arange": "arange",
    "differs": "differs",
}


def _compiled():
    """The loops compiled, called through compiled code as the solver calls them (they
    are internal: Python cannot call them directly)."""
    import numba

    def through_compiled(loop):
        return numba.njit(lambda *args: loop(*args))

    return {key: through_compiled(getattr(array_loops, name)) for key, name in _LOOPS.items()}


def _plain():
    """The loops as the plain Python they are written in. In a compiling process their
    globals name the compiled (internal) loops, so each plain function is rebuilt with
    the plain functions in their place."""

    def plain(function):
        function = getattr(function, "py_func", function)
        names = {
            name: getattr(value, "py_func", value) for name, value in function.__globals__.items()
        }
        return types.FunctionType(function.__code__, names, function.__name__)

    return {key: plain(getattr(array_loops, name)) for key, name in _LOOPS.items()}


@pytest.fixture(scope="module", params=["python"] + (["compiled"] if jit.COMPILED else []))
def loops(request):
    return _compiled() if request.param == "compiled" else _plain()


def _same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


@settings(max_examples=300, deadline=None)
@given(values=_VALUES, arrangement=_ARRANGEMENTS)
def test_stable_order_is_numpys_stable_argsort(loops, values, arrangement):
    keys = _arranged(values, arrangement)
    assert _same_bits(loops["order"](keys), np.argsort(keys, kind="stable"))


@settings(max_examples=200, deadline=None)
@given(values=st.lists(st.integers(0, 4), max_size=250))
def test_stable_order_of_integer_keys(loops, values):
    """Integer keys, with many ties."""
    keys = np.array(values, dtype=np.int64)
    assert _same_bits(loops["order"](keys), np.argsort(keys, kind="mergesort"))


@settings(max_examples=300, deadline=None)
@given(values=_VALUES, arrangement=_ARRANGEMENTS)
def test_sorted_unique_is_numpys_unique(loops, values, arrangement):
    values = _arranged(values, arrangement)
    got, expected = loops["unique"](values), np.unique(values)
    np.testing.assert_array_equal(got, expected)
    if not np.any(values == 0.0):  # 0.0 and -0.0 tie, and numpy's sort is not stable
        assert _same_bits(got, expected)


@settings(max_examples=300, deadline=None)
@given(values=_VALUES, points=st.lists(st.one_of(_FEW, _ANY), max_size=10))
def test_count_at_or_below_is_numpys_searchsorted_right(loops, values, points):
    xs = np.sort(np.array(values, dtype=np.float64))
    for x in [*points, *xs[:3]]:
        assert loops["count"](xs, x) == np.searchsorted(xs, x, side="right")


@settings(max_examples=300, deadline=None)
@given(
    samples=st.lists(st.tuples(st.one_of(_FEW, _ANY), _ANY), min_size=1, max_size=40),
    points=st.lists(st.one_of(_FEW, _ANY), max_size=40),
    unique_xp=st.booleans(),
)
def test_interp_is_numpys_interp(loops, samples, points, unique_xp):
    """Sample points increasing (with ties unless ``unique_xp``), points inside, on,
    between and outside them; one sample point alone."""
    xp = np.sort(np.array([s[0] for s in samples]))
    fp = np.array([s[1] for s in samples])
    if unique_xp:
        xp, first = np.unique(xp, return_index=True)
        fp = fp[first]
    x = np.concatenate([np.array(points), xp, xp[:1] - 1.0, xp[-1:] + 1.0])
    with np.errstate(all="ignore"):
        expected = np.interp(x, xp, fp)
        got = loops["interp"](x, xp, fp)
    assert _same_bits(got, expected)


def test_interp_of_ordinary_samples_between_and_beyond(loops):
    xp = np.array([0.0, 1.0, 2.0, 2.0, 5.0])
    fp = np.array([1.0, 3.0, -1.0, 4.0, 10.0])
    x = np.array([-7.0, 0.0, 0.25, 1.5, 2.0, 3.5, 5.0, 6.0])
    got = loops["interp"](x, xp, fp)
    # by hand: clamped outside, linear inside, the last of tied sample points at a tie
    assert got.tolist() == [1.0, 1.0, 1.5, 1.0, 4.0, 7.0, 10.0, 10.0]
    assert _same_bits(got, np.interp(x, xp, fp))


def test_interp_without_sample_points_is_numpys_error(loops):
    with pytest.raises(ValueError, match="empty"):
        np.interp(np.array([1.0]), np.array([]), np.array([]))
    with pytest.raises(ValueError, match="empty"):
        loops["interp"](np.array([1.0]), np.empty(0), np.empty(0))


def test_sorted_unique_and_order_of_nothing_and_of_one(loops):
    assert loops["unique"](np.empty(0)).shape == (0,)
    assert loops["order"](np.empty(0)).tolist() == []
    assert loops["unique"](np.array([2.5])).tolist() == [2.5]
    assert loops["order"](np.array([2.5])).tolist() == [0]


def test_copy_into_a_row_writes_through_and_refuses_another_length(loops):
    table = np.zeros((3, 4))
    loops["copy"](table[1], np.array([1.5, -2.0, 0.0, 7.0]))
    assert table.tolist() == [[0.0] * 4, [1.5, -2.0, 0.0, 7.0], [0.0] * 4]
    with pytest.raises(ValueError, match="different lengths"):
        loops["copy"](table[2], np.ones(3))
    assert table[2].tolist() == [0.0] * 4


@settings(max_examples=300, deadline=None)
@given(values=st.lists(st.one_of(_FEW, _ANY), min_size=1, max_size=60), arrangement=_ARRANGEMENTS)
def test_largest_is_numpys_max(loops, values, arrangement):
    values = _arranged(values, arrangement)
    got, expected = loops["largest"](values), np.max(values)
    assert got == expected
    if expected != 0.0:  # 0.0 and -0.0 tie: the loop keeps the first, numpy either
        assert _same_bits(np.float64(got), expected)


def test_largest_of_a_tables_row_prefix_and_of_nothing(loops):
    table = np.array([[1.0, 7.5, -3.0, 7.5, np.inf], [0.0, 0.0, 0.0, 0.0, 0.0]])
    assert loops["largest"](table[0, :4]) == 7.5  # the padding past it not read
    with pytest.raises(ValueError, match="empty"):
        loops["largest"](np.empty(0))


@settings(max_examples=100, deadline=None)
@given(n=st.integers(0, 300))
def test_arange_is_numpys_arange(loops, n):
    assert _same_bits(loops["arange"](n), np.arange(n, dtype=np.int64))


@settings(max_examples=300, deadline=None)
@given(
    a=st.lists(st.integers(-1, 3), max_size=8),
    b=st.lists(st.integers(-1, 3), max_size=8),
    same=st.booleans(),
)
def test_differs_is_not_numpys_array_equal(loops, a, b, same):
    """Branch rows of the lengths an actuator has: often equal (``same``), else of another
    length or content."""
    first = np.array(a, dtype=np.int64)
    second = first.copy() if same else np.array(b, dtype=np.int64)
    assert loops["differs"](first, second) == (not np.array_equal(first, second))
    assert loops["differs"](second, first) == (not np.array_equal(first, second))
