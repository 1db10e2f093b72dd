"""numpy's stable argsort, unique, searchsorted, interp, max, arange and array_equal, and a
row's assignment, as the small loops the solver needs of them, one source for both modes
(``labrig.model.actuator.jit``).

Why not numpy's own: compiled, each is numba's general implementation (sorts for every
dtype, kind and layout, a searchsorted that takes its side as a string, an interp with
its scalar and complex forms), typed and lowered for each type it is called with; numba's
library functions were a quarter of the typing and lowering of a cold compile of the
solver. The solver sorts at most a few hundred numbers at a time, mostly in the sorted
runs they come in (a segment's profile pressures), which a natural merge sort merges in
a few passes.

The same bits as numpy's, on NaN-free input: a stable order is unique; ``sorted_unique``
keeps the first of equal values in sorted order, where numpy keeps whichever its unstable
sort puts first (only 0.0 and -0.0 can tell them apart); ``interp`` is numpy's arithmetic
(numpy/_core/src/multiarray/compiled_base.c, ``arr_interp``), and its search finds the
only index numpy's can find in increasing sample points; ``largest`` keeps the first of
equal values (only 0.0 and -0.0 can tell). tests/model/actuator/
test_array_loops.py holds each to numpy's on generated input, in both modes.
"""

from __future__ import annotations

import math

import numpy as np

from labrig.model.actuator.jit import INTERNAL, INTERNAL_LEAF, njit


@njit(**INTERNAL)
def stable_order(keys):
    """``np.argsort(keys, kind="stable")``: a natural merge sort, which merges the
    non-decreasing runs the keys come in, taking the left one's key on a tie."""
    n = len(keys)
    order = np.empty(n, dtype=np.int64)
    starts = np.empty(n + 1, dtype=np.int64)
    runs = 0
    for i in range(n):
        order[i] = i
        if i == 0 or keys[i] < keys[i - 1]:
            starts[runs] = i
            runs += 1
    starts[runs] = n
    spare = np.empty(n, dtype=np.int64)
    while runs > 1:
        merged = 0
        for r in range(0, runs, 2):
            lo, mid, hi = starts[r], starts[r + 1], starts[min(r + 2, runs)]
            left, right = lo, mid
            for k in range(lo, hi):
                if right >= hi or (left < mid and keys[order[left]] <= keys[order[right]]):
                    spare[k] = order[left]
                    left += 1
                else:
                    spare[k] = order[right]
                    right += 1
            starts[merged] = lo
            merged += 1
        starts[merged] = n
        runs = merged
        order, spare = spare, order
    return order


@njit(**INTERNAL)
def sorted_unique(values):
    """``np.unique(values)`` of a 1-D float64 array: sorted, each value once."""
    order = stable_order(values)
    out = np.empty(len(values))
    m = 0
    for i in range(len(order)):
        x = values[order[i]]
        if m == 0 or x != out[m - 1]:
            out[m] = x
            m += 1
    return out[:m]


@njit(**INTERNAL_LEAF)
def copy_into(target, source):
    """``target[:] = source`` of 1-D arrays, element by element: numba's assignment
    checks the shapes with a message it formats at run time, and that formatting
    (``str`` of an int, string concatenation) cost more to compile than the rest of the
    function it was in."""
    if len(target) != len(source):
        raise ValueError("copy_into: arrays of different lengths")
    for i in range(len(source)):
        target[i] = source[i]


@njit(**INTERNAL_LEAF)
def count_at_or_below(xs, x):
    """``np.searchsorted(xs, x, side="right")`` of increasing ``xs``: by bisection."""
    lo, hi = 0, len(xs)
    while lo < hi:
        mid = (lo + hi) >> 1
        if x >= xs[mid]:
            lo = mid + 1
        else:
            hi = mid
    return lo


@njit(**INTERNAL)
def interp(x, xp, fp):
    """``np.interp(x, xp, fp)`` of 1-D float64 arrays, ``xp`` increasing (numpy's
    precondition; ties allowed): fp[0] below xp[0], fp[-1] above xp[-1]."""
    count = len(xp)
    if count == 0:
        raise ValueError("array of sample points is empty")
    out = np.empty(len(x))
    for i in range(len(x)):
        x_i = x[i]
        if count == 1:
            out[i] = fp[0]
            continue
        if math.isnan(x_i):
            out[i] = x_i
            continue
        j = count_at_or_below(xp, x_i) - 1  # the last sample point at or below x_i
        if j == -1:
            out[i] = fp[0]
        elif j == count - 1 or xp[j] == x_i:
            out[i] = fp[j]
        else:
            slope = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j])
            y = slope * (x_i - xp[j]) + fp[j]
            if math.isnan(y):  # numpy: a nan from one end, try the other
                y = slope * (x_i - xp[j + 1]) + fp[j + 1]
                if math.isnan(y) and fp[j] == fp[j + 1]:
                    y = fp[j]
            out[i] = y
    return out


@njit(**INTERNAL_LEAF)
def largest(values):
    """``np.max(values)`` of a 1-D array: the first of equal largest values."""
    if len(values) == 0:
        raise ValueError("largest: an empty array has no largest value")
    top = values[0]
    for i in range(1, len(values)):
        if values[i] > top:
            top = values[i]
    return top


@njit(**INTERNAL)
def arange(n):
    """``np.arange(n)``: 0 to n - 1, int64."""
    out = np.empty(n, dtype=np.int64)
    for i in range(n):
        out[i] = i
    return out


@njit(**INTERNAL_LEAF)
def differs(a, b):
    """``not np.array_equal(a, b)`` of 1-D arrays: another length or another element."""
    if len(a) != len(b):
        return True
    i = 0
    while i < len(a) and a[i] == b[i]:
        i += 1
    return i < len(a)
