"""What the scan tests share: a small library and a comparison of two scan files."""

import h5py
import numpy as np

from labrig.model.scan.scan import ScanLibrary
from labrig.model.segments.catalog import LIBRARY_NAMES, analytical_segment

# eight segments across the library: every braid length, a segment without a peak
# (B40-T30), near-flat dips and the deepest one
SMALL = LIBRARY_NAMES[::5]


def small_library():
    return ScanLibrary("test", tuple(analytical_segment(n) for n in SMALL))


def file_contents(path):
    """Every dataset of a scan file but the chunks' compute times (the only thing that
    depends on the machine's load)."""
    with h5py.File(path, "r") as h5:
        out = {}
        h5.visititems(
            lambda name, obj: (
                out.__setitem__(name, obj[()]) if isinstance(obj, h5py.Dataset) else None
            )
        )
    out.pop("chunks/seconds")
    return out


def assert_same_contents(a, b):
    """The two files hold the same datasets, bit for bit."""
    first, second = file_contents(a), file_contents(b)
    assert first.keys() == second.keys()
    for key in first:
        np.testing.assert_array_equal(first[key], second[key], err_msg=key)
