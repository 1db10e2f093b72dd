"""A named library's tables kept between scans: the same bits as built, found again only
for the same segments, code and versions, and never a reason for a scan to fail."""

import dataclasses
import os
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
from support.scan_helpers import SMALL, assert_same_contents, small_library

from labrig.errors import InputError
from labrig.model.scan.scan import (
    TRANSITION_FIELDS,
    ChunkResult,
    ScanLibrary,
    combination_at,
    make_chunks,
)
from labrig.model.scan.scan_file import ScanFile, read_scan
from labrig.model.segments import curve_cache
from labrig.model.segments.catalog import analytical_segment
from labrig.model.segments.measured import load_csv, write_csv


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """An empty cache folder, and a process that has loaded no library yet."""
    folder = tmp_path / "cache"
    monkeypatch.setenv(curve_cache.CACHE_VARIABLE, str(folder))
    monkeypatch.setattr(curve_cache, "_IN_PROCESS", {})
    return folder


def _built():
    return tuple(analytical_segment(n) for n in SMALL)


def _never():
    pytest.fail("built again although the cache holds the tables")


def _new_process(monkeypatch):
    monkeypatch.setattr(curve_cache, "_IN_PROCESS", {})


def test_the_cached_tables_are_the_built_ones_bit_for_bit(cache, monkeypatch):
    built = curve_cache.cached_curves("small", SMALL, _built)
    assert len(list(cache.glob("curves-small-*"))) == 1
    assert curve_cache.cached_curves("small", SMALL, _never) is built  # same process
    _new_process(monkeypatch)
    read = curve_cache.cached_curves("small", SMALL, _never)
    assert read is not built
    for a, b in zip(read, built, strict=True):
        for field in dataclasses.fields(a):
            x, y = getattr(a, field.name), getattr(b, field.name)
            if isinstance(x, np.ndarray):
                assert x.dtype == y.dtype and x.tobytes() == y.tobytes(), field.name
            else:
                assert x == y and type(x) is type(y), field.name
    assert ScanLibrary("s", read).digest == ScanLibrary("s", built).digest
    for a, b in zip(read, built, strict=True):
        for field in dataclasses.fields(a.pieces):
            x, y = getattr(a.pieces, field.name), getattr(b.pieces, field.name)
            assert np.asarray(x).tobytes() == np.asarray(y).tobytes(), field.name


def test_a_warm_librarys_kernels_never_import_scipys_interpolation(cache):
    """A scan's kernels from the cached library: the PCHIP pieces as stored, so the
    process never imports scipy.interpolate (most of a warm scan's start-up)."""
    curve_cache.cached_curves("small", SMALL, _built)
    child = f"""
import sys
from pathlib import Path
from labrig.model.actuator.kernel import kernel_of
from labrig.model.segments import curve_cache
curves = curve_cache.cached_curves("small", {list(SMALL)!r}, None)
kernels = [kernel_of(c) for c in curves]
assert kernels[0].pressure(kernels[0].x[1]) == float(curves[0].p_kpa[1])
print(sorted(m for m in sys.modules if m.startswith("scipy.interpolate")))
"""
    out = subprocess.run(
        [sys.executable, "-c", child], capture_output=True, text=True, check=True
    ).stdout
    assert out.strip() == "[]"


def test_other_segments_or_code_are_built_anew(cache, monkeypatch, tmp_path):
    curve_cache.cached_curves("small", SMALL, _built)
    _new_process(monkeypatch)
    rebuilt = []
    curve_cache.cached_curves("fewer", SMALL[:-1], lambda: rebuilt.append(1) or _built()[:-1])
    assert rebuilt == [1]
    code = tmp_path / "segments"
    shutil.copytree(curve_cache.SEGMENTS_PACKAGE, code, ignore=shutil.ignore_patterns("__py*"))
    monkeypatch.setattr(curve_cache, "SEGMENTS_PACKAGE", code)
    _new_process(monkeypatch)
    curve_cache.cached_curves("small", SMALL, _never)  # a copy of the same code
    with (code / "tabulate.py").open("a") as source:
        source.write("# changed\n")
    _new_process(monkeypatch)
    curve_cache.cached_curves("small", SMALL, lambda: rebuilt.append(2) or _built())
    assert rebuilt == [1, 2]
    # the file of the code before is gone, the other library's kept
    assert len(list(cache.glob("curves-small-*"))) == 1
    assert len(list(cache.glob("curves-fewer-*"))) == 1


def test_a_label_that_begins_with_another_keeps_its_file(cache, monkeypatch):
    """A segment's label may begin with another's (``segment-B46-T2`` and
    ``segment-B46-T20``): a new file of one never removes the other's."""
    curve_cache.cached_curves("small-b", SMALL, _built)
    monkeypatch.setattr(curve_cache, "_FORMAT", "another format")  # a new key for both
    _new_process(monkeypatch)
    curve_cache.cached_curves("small", SMALL, _built)
    assert len(list(cache.glob("curves-small-b-*"))) == 1


def test_a_library_segment_is_tabulated_once_per_install(tmp_path):
    """``analytical_segment`` in a fresh process: the first tabulates and keeps the
    table, the next reads it, the same bits, without importing scipy's solvers."""
    child = """
import sys
from pathlib import Path
from labrig.model.segments.catalog import analytical_segment
curve = analytical_segment("B48-T30")
print("scipy.optimize" in sys.modules, curve.p_kpa.tobytes().hex()[:4000], curve.l_mm.sum())
"""
    env = os.environ | {curve_cache.CACHE_VARIABLE: str(tmp_path)}
    runs = [
        subprocess.run(
            [sys.executable, "-c", child], capture_output=True, text=True, check=True, env=env
        ).stdout.split()
        for _ in range(2)
    ]
    assert runs[0][0] == "True" and runs[1][0] == "False"
    assert runs[0][1:] == runs[1][1:]
    assert len(list(tmp_path.glob("curves-segment-B48-T30-*.npz"))) == 1


def test_a_damaged_or_unwritable_cache_only_costs_the_build(cache, monkeypatch, tmp_path):
    curve_cache.cached_curves("small", SMALL, _built)
    (stored,) = cache.glob("curves-small-*")
    stored.write_bytes(b"not a numpy file")
    _new_process(monkeypatch)
    assert len(curve_cache.cached_curves("small", SMALL, _built)) == len(SMALL)
    a_file = tmp_path / "a-file"
    a_file.write_text("")
    monkeypatch.setenv(curve_cache.CACHE_VARIABLE, str(a_file / "cache"))
    _new_process(monkeypatch)
    assert len(curve_cache.cached_curves("small", SMALL, _built)) == len(SMALL)


def test_measured_tables_are_not_kept(cache, tmp_path):
    write_csv(analytical_segment("B50-T20"), tmp_path / "m.csv")
    measured = (load_csv(tmp_path / "m.csv", name="m"),) * 2
    curve_cache.cached_curves("measured", ["m", "m"], lambda: measured)
    assert not list(cache.glob("curves-measured-*"))


def _results(library, n: int, chunk_size: int) -> list[ChunkResult]:
    """Chunk results as the workers hand them over, with made-up rows (the file's
    layout is what is tested here): a few transitions per actuator, one failure in
    every third chunk."""
    rng = np.random.default_rng(5)
    out = []
    for chunk in make_chunks(len(library.curves), n, chunk_size):
        ranks = np.arange(chunk.start, chunk.stop)
        combos = [combination_at(int(r), len(library.curves), n) for r in ranks]
        counts = rng.integers(0, 4, len(ranks))
        failed = ranks[:1] if chunk.index % 3 == 0 else ranks[:0]
        out.append(
            ChunkResult(
                index=chunk.index,
                n_actuators=len(ranks),
                actuator=np.repeat(ranks, counts),
                segments=np.repeat(np.array(combos, dtype=np.int16), counts, axis=0),
                columns={
                    name: rng.random(counts.sum()) < 0.5
                    if name == "stable"
                    else rng.integers(-1, 3, counts.sum()).astype(np.int8)
                    if name in ("direction", "alpha", "beta")
                    else rng.random(counts.sum())
                    for name in TRANSITION_FIELDS
                },
                failed_actuator=failed,
                failed_segments=np.array([combos[0]] * len(failed), dtype=np.int16).reshape(-1, n),
                failed_error=("FlowError: did not settle",) * len(failed),
                seconds=0.1,
                peak_rss_mib=100.0 + chunk.index,
            )
        )
    return out


def test_a_scan_never_truncates_a_file_that_appeared_at_its_path(tmp_path):
    """The command checks --out before a compile of minutes; a file made there meanwhile
    is refused, not written over."""
    path = tmp_path / "scan.h5"
    path.write_bytes(b"made while the solver compiled")
    with pytest.raises(InputError, match="the file exists; --resume continues it"):
        ScanFile.create(path, small_library(), 2, chunk_size=5, deflate=False)
    assert path.read_bytes() == b"made while the solver compiled"


def test_chunks_written_together_make_the_file_written_one_by_one(tmp_path):
    library = small_library()
    results = _results(library, 2, 5)
    one, together = tmp_path / "one.h5", tmp_path / "together.h5"
    for path, batches in ((one, [[r] for r in results]), (together, [results[:3], results[3:]])):
        scan = ScanFile.create(path, library, 2, chunk_size=5, deflate=False)
        for batch in batches:
            scan.append(batch)
        scan.close(workers=1, parent_peak_rss_mib=0.0)
    assert_same_contents(one, together)
    data = read_scan(together)
    assert data.complete and len(data.failed_error) == 2
    assert list(data.actuator) == sorted(np.concatenate([r.actuator for r in results]))
    stops = np.cumsum([len(r.actuator) for r in results])
    failure_stops = np.cumsum([len(r.failed_actuator) for r in results])
    with h5py.File(together) as h5:
        chunks = {name: h5["chunks"][name][()] for name in h5["chunks"]}
    np.testing.assert_array_equal(chunks["row_stop"], stops)
    np.testing.assert_array_equal(chunks["row_start"], np.concatenate([[0], stops[:-1]]))
    np.testing.assert_array_equal(chunks["failure_stop"], failure_stops)
    np.testing.assert_array_equal(chunks["failure_start"], [0, *failure_stops[:-1]])
    scan = ScanFile.resume(one, library, 2, deflate=False)
    with pytest.raises(ValueError, match="not one after another"):
        scan.append([results[0], results[2]])
    scan.close(workers=1, parent_peak_rss_mib=0.0)
    assert_same_contents(one, together)


def test_a_dry_run_with_its_segments_tabulated_imports_no_scipy(tmp_path):
    """The demo's checks (its model peak) from tables kept by an earlier command: scipy,
    a second of a simulated run's start-up, is for tabulating and solving, neither of
    which a run whose segments are in the cache does."""
    demo = Path(__file__).parents[3] / "protocols" / "demo.yaml"
    child = """
import atexit, sys
atexit.register(lambda: print(sorted(m for m in sys.modules if m.startswith("scipy"))))
import labrig.cli
sys.argv = ["labrig", "run", sys.argv[1], "--sim", "--dry-run"]
labrig.cli.main()
"""
    env = os.environ | {curve_cache.CACHE_VARIABLE: str(tmp_path)}
    runs = [
        subprocess.run(
            [sys.executable, "-c", child, str(demo)],
            capture_output=True,
            text=True,
            check=True,
            env=env,
        ).stdout.splitlines()
        for _ in range(2)
    ]
    assert "model peak" in "\n".join(runs[1])
    assert runs[0][-1] != "[]"  # the first tabulated them, with scipy
    assert runs[1][-1] == "[]"
