"""labrig.arrays: the shared row medians against numpy's nanmedian, and runs of true
values against a plain loop."""

import warnings

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from labrig.arrays import nanmedian_rows, runs_of_true


@settings(max_examples=200, deadline=None)
@given(
    st.integers(1, 40),
    st.integers(1, 25),
    st.floats(0.0, 1.0),
    st.sampled_from([np.float64, np.float32]),
    st.integers(0, 2**32 - 1),
)
def test_row_medians_are_numpys_nanmedian(n, span, nan_fraction, dtype, seed):
    """Against ``np.nanmedian`` of the rows (in float64, as the tracker's float32 rings
    take it) with NaN anywhere, all-NaN rows, repeated values and infinities: equal to
    the bit."""
    rng = np.random.default_rng(seed)
    values = rng.choice([-2.0, 0.0, 1.5, 3.0, np.inf, -np.inf], (n, span))
    values = np.where(rng.random((n, span)) < 0.8, rng.normal(size=(n, span)), values)
    values[rng.random((n, span)) < nan_fraction] = np.nan
    values = values.astype(dtype)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN rows
        expected = np.nanmedian(values.astype(np.float64), axis=1)
    np.testing.assert_array_equal(nanmedian_rows(values), expected)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.booleans(), max_size=40))
def test_runs_of_true_are_the_loops_runs(flags):
    runs, start = [], None
    for i, flag in enumerate([*flags, False]):
        if flag and start is None:
            start = i
        elif not flag and start is not None:
            runs.append((start, i - 1))
            start = None
    assert runs_of_true(np.array(flags, dtype=bool)) == runs
