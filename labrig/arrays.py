"""Two small array operations shared by the analysis, the marker tracker and the video
encoder: the runs of true values in a mask, and the median of each row of an array with
gaps. Plain numpy, no other import, so that any process can take them cheaply (the
video's encoder process does not import the analysis)."""

from __future__ import annotations

import numpy as np


def runs_of_true(mask) -> list[tuple[int, int]]:
    """(first, last) indices of the runs of True in ``mask``."""
    edges = np.diff(np.concatenate([[0], np.asarray(mask).astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1, strict=True))


def nanmedian_rows(values: np.ndarray) -> np.ndarray:
    """``np.nanmedian(values, axis=1)`` of a 2-d array, in float64, from one sort of the
    rows: each row's middle value, or the mean of its middle two, NaN sorted last; NaN
    for an all-NaN row. numpy's own takes masked arrays for rows this short, ~10x slower
    (the analysis's side windows, the tracker's background rings)."""
    ordered = np.sort(values, axis=1)
    count = values.shape[1] - np.isnan(values).sum(axis=1)
    rows = np.arange(len(ordered))
    lower = ordered[rows, np.maximum((count - 1) // 2, 0)].astype(np.float64)
    upper = ordered[rows, count // 2].astype(np.float64)
    return 0.5 * (lower + upper)
