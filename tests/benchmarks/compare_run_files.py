"""Are two run files the same data, bit for bit? For checking that a speed-up changed
nothing: run the same protocol and seed before and after, then compare the files.

Every dataset (dtype, shape, bytes) and every attribute is compared; what records when
and by which code the file was written (the file and analysis dates, the run's start
and end time, the git commit) and the pump's port (a temporary path on the simulated
rig) are left out. Prints each difference and exits 1 if any.
Run: ``python tests/benchmarks/compare_run_files.py BEFORE.h5 AFTER.h5``.
"""

from __future__ import annotations

import sys

import h5py
import numpy as np

# (object, attribute): wall-clock stamps, the code's identity and the host's device
# names, not data; an attribute of None leaves the dataset itself out. The pump's port
# is the path the driver opened: on the simulated rig a link in a temporary folder
# whose name is new in every run.
NOT_DATA = {
    ("/", "file_time"),
    ("entry/analysis", "date"),
    ("entry/start_time", None),
    ("entry/end_time", None),
    ("entry/versions/git_commit", None),
    ("entry/pump_identity/port", None),
}


def _members(f: h5py.File) -> dict[str, h5py.Group | h5py.Dataset]:
    members: dict[str, h5py.Group | h5py.Dataset] = {"/": f}
    f.visititems(lambda name, obj: members.__setitem__(name, obj))
    return members


def _same(a, b) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    if a.dtype != b.dtype or a.shape != b.shape:
        return False
    if a.dtype.kind == "O":  # variable-length strings: compare the objects
        return [repr(x) for x in a.ravel()] == [repr(x) for x in b.ravel()]
    return a.tobytes() == b.tobytes()


def differences(before: str, after: str) -> list[str]:
    """What differs between the two files, one line each (empty: the same data)."""
    found = []
    with h5py.File(before, "r") as fa, h5py.File(after, "r") as fb:
        ma, mb = _members(fa), _members(fb)
        found += [f"only in one file: {name}" for name in sorted(set(ma) ^ set(mb))]
        for name in sorted(set(ma) & set(mb)):
            if (name, None) in NOT_DATA:
                continue
            a, b = ma[name], mb[name]
            skipped = {attr for (where, attr) in NOT_DATA if where == name}
            attrs = (set(a.attrs) | set(b.attrs)) - skipped
            for attr in sorted(attrs):
                if attr not in a.attrs or attr not in b.attrs:
                    found.append(f"attribute {attr!r} of {name} in one file only")
                elif not _same(a.attrs[attr], b.attrs[attr]):
                    found.append(f"attribute {attr!r} of {name} differs")
            if isinstance(a, h5py.Dataset) and not _same(a[()], b[()]):
                found.append(f"dataset {name} differs")
    return found


def main() -> None:
    before, after = sys.argv[1:3]
    found = differences(before, after)
    for line in found:
        print(line)
    with h5py.File(before, "r") as f:
        n = sum(isinstance(obj, h5py.Dataset) for obj in _members(f).values())
    print(f"{n} datasets compared: {len(found)} differences")
    sys.exit(1 if found else 0)


if __name__ == "__main__":
    main()
