"""Scans: combination ranks, chunks, the pure chunk function against paths computed
directly, failures recorded, the file the same with 1 or 2 workers, an interrupted scan
resumed to the same file, the summary and the ranking against brute force."""

import itertools
import math

import h5py
import numpy as np
import pytest
from support.scan_helpers import SMALL, assert_same_contents, small_library

import labrig.model.scan.scan as scan_module
from labrig.errors import InputError
from labrig.model.actuator.equilibria import Actuator
from labrig.model.actuator.paper_counting import paper_transitions
from labrig.model.actuator.path import quasi_static_path
from labrig.model.actuator.transitions import transitions
from labrig.model.scan.run import run_scan
from labrig.model.scan.scan import (
    Chunk,
    ScanLibrary,
    combination_at,
    combinations_between,
    default_chunk_size,
    load_library,
    make_chunks,
    run_chunk,
)
from labrig.model.scan.scan_file import read_scan
from labrig.model.scan.scan_summary import plot_fig4, rank_designs, summarise
from labrig.model.segments.catalog import LIBRARY_NAMES, analytical_segment
from labrig.model.segments.measured import write_csv


@pytest.mark.parametrize(("n_items", "k"), [(7, 3), (36, 2), (9, 5), (6, 6)])
def test_combination_ranks_follow_itertools(n_items, k):
    everything = list(itertools.combinations(range(n_items), k))
    assert [combination_at(r, n_items, k) for r in range(len(everything))] == everything
    third = len(everything) // 3
    assert (
        list(combinations_between(third, 2 * third + 1, n_items, k))
        == everything[third : 2 * third + 1]
    )
    assert list(combinations_between(3, 3, n_items, k)) == []


def test_ranks_of_the_n5_scan_without_enumerating_it():
    total = math.comb(36, 5)
    assert total == 376_992
    assert combination_at(0, 36, 5) == (0, 1, 2, 3, 4)
    assert combination_at(total - 1, 36, 5) == (31, 32, 33, 34, 35)
    rank = 123_456
    expected = next(itertools.islice(itertools.combinations(range(36), 5), rank, None))
    assert combination_at(rank, 36, 5) == expected


@pytest.mark.parametrize(("n", "total"), [(2, 630), (3, 7_140), (4, 58_905), (5, 376_992)])
def test_chunks_cover_every_combination_once(n, total):
    size = default_chunk_size(total)
    chunks = make_chunks(36, n, size)
    assert [c.index for c in chunks] == list(range(len(chunks)))
    assert chunks[0].start == 0 and chunks[-1].stop == total
    assert all(a.stop == b.start for a, b in itertools.pairwise(chunks))
    assert all(0 < c.stop - c.start <= size for c in chunks)
    assert 16 <= size <= 512


def test_a_chunk_holds_the_transitions_of_paths_computed_directly():
    """The chunk function shares kernels across actuators; a path computed from fresh
    curves, with fresh kernels, must give the very same numbers."""
    library = small_library()
    result = run_chunk(library, Chunk(0, 0, 28, 2, deflate=True))
    assert result.n_actuators == 28 and len(result.failed_actuator) == 0
    expected_rows = []
    for rank, combo in enumerate(itertools.combinations(range(8), 2)):
        actuator = Actuator([analytical_segment(SMALL[i]) for i in combo])
        for t in transitions(quasi_static_path(actuator, deflate=True)):
            expected_rows.append(
                (
                    rank,
                    combo,
                    t.direction,
                    t.v_ml,
                    t.alpha,
                    t.beta,
                    t.stable,
                    t.dE,
                    t.dv,
                    t.dl,
                    t.dp,
                )
            )
    c = result.columns
    rows = [
        (
            int(result.actuator[j]),
            tuple(int(x) for x in result.segments[j]),
            int(c["direction"][j]),
            float(c["v_ml"][j]),
            int(c["alpha"][j]),
            int(c["beta"][j]),
            bool(c["stable"][j]),
            *(float(c[m][j]) for m in ("dE", "dv", "dl", "dp")),
        )
        for j in range(len(result.actuator))
    ]
    assert rows == expected_rows
    assert {-1, 1} == set(c["direction"].tolist())  # deflation is in it


def test_a_failing_actuator_is_recorded_and_the_chunk_goes_on(monkeypatch):
    real = scan_module._rows_function  # the solver a chunk uses (compiled or reference)

    def failing_for_b40_t30(library):
        solve = real(library)

        def solve_or_fail(combo, deflate):
            if "B40-T30" in [library.curves[i].name for i in combo]:
                raise RuntimeError("no equilibrium (injected)")
            return solve(combo, deflate)

        return solve_or_fail

    monkeypatch.setattr(scan_module, "_rows_function", failing_for_b40_t30)
    result = run_chunk(small_library(), Chunk(3, 0, 28, 2))
    failed = [tuple(s) for s in result.failed_segments.tolist()]
    assert failed == [(0, 1), (1, 2), (1, 3), (1, 4), (1, 5), (1, 6), (1, 7)]
    assert result.failed_error == ("RuntimeError: no equilibrium (injected)",) * 7
    assert set(result.actuator.tolist()) == set(range(28)) - set(result.failed_actuator.tolist())


def test_the_file_is_the_same_with_one_or_two_workers(tmp_path):
    library = small_library()
    one, two = tmp_path / "one.h5", tmp_path / "two.h5"
    run_scan(library, 3, one, workers=1, chunk_size=7)
    run_scan(library, 3, two, workers=2, chunk_size=7)
    assert_same_contents(one, two)
    data = read_scan(two)
    assert data.complete and data.actuators_done == 56 and data.n_combinations == 56
    assert data.workers == 2 and data.elapsed_s > 0 and data.worker_peak_rss_mib > 10
    assert np.all(np.diff(data.actuator) >= 0)  # sorted by actuator as written
    assert set(data.actuator.tolist()) == set(range(56))  # every actuator has transitions


def test_an_interrupted_scan_resumes_to_the_same_file(tmp_path):
    library = small_library()
    whole, cut = tmp_path / "whole.h5", tmp_path / "cut.h5"
    run_scan(library, 2, whole, workers=1, chunk_size=1)

    def stop_after_three_chunks(progress):
        if progress.chunks_done == 3:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_scan(library, 2, cut, workers=2, chunk_size=1, progress=stop_after_three_chunks)
    partial = read_scan(cut)
    # the third chunk and those written with it (the chunks ready together are written
    # at once): at most the pool's window more, 2 * 2 + 2 chunks of the 28
    done = partial.actuators_done
    assert not partial.complete and 3 <= done <= 9
    assert set(partial.actuator.tolist()) <= set(range(done))
    # a scan killed while writing a chunk leaves rows past the last finished chunk
    with h5py.File(cut, "r+") as h5:
        for name, dataset in h5["transitions"].items():
            dataset.resize(dataset.shape[0] + 5, axis=0)
            if name == "actuator":
                dataset[-5:] = 99
    seen = []
    run_scan(library, 2, cut, workers=2, resume=True, progress=seen.append)
    assert seen[0].chunks_done == done and seen[-1].actuators_done == 28
    assert_same_contents(whole, cut)
    assert read_scan(cut).complete


def test_resume_and_create_refuse_what_does_not_fit(tmp_path):
    library = small_library()
    out = tmp_path / "scan.h5"
    run_scan(library, 2, out, workers=1)
    with pytest.raises(InputError, match="exists; --resume"):
        run_scan(library, 2, out, workers=1)
    with pytest.raises(InputError, match="n = 2"):
        run_scan(library, 3, out, workers=1, resume=True)
    with pytest.raises(InputError, match="deflate"):
        run_scan(library, 2, out, workers=1, resume=True, deflate=True)
    other = ScanLibrary("other", library.curves[:7])
    with pytest.raises(InputError, match="other segments' tables"):
        run_scan(other, 2, out, workers=1, resume=True)
    with pytest.raises(InputError, match="does not exist"):
        run_scan(library, 2, tmp_path / "none.h5", workers=1, resume=True)
    with pytest.raises(InputError, match="--n 9"):
        run_scan(library, 9, tmp_path / "n9.h5", workers=1)
    plain = tmp_path / "plain.h5"
    h5py.File(plain, "w").close()
    with pytest.raises(InputError, match="not a labrig scan"):
        read_scan(plain)
    with pytest.raises(InputError, match="not a labrig scan"):
        run_scan(library, 2, plain, workers=1, resume=True)


def test_libraries_by_name_and_folder(tmp_path):
    analytical = load_library(None)
    assert analytical.names == list(LIBRARY_NAMES) and load_library("Analytical") == analytical
    paper = load_library("paper")
    assert paper.label == "paper" and paper.names[0] == "paper:B40-T20"
    built = analytical_segment("paper:B50-T30")  # the scan's may come from its cache
    assert paper.curves[-1].name == built.name and paper.curves[-1].V0_ml == built.V0_ml
    np.testing.assert_array_equal(paper.curves[-1].p_kpa, built.p_kpa)
    assert load_library("gent").names == ["gent-a", "gent-b", "gent-c"]
    for name in ("B50-T20", "B46-T22"):
        write_csv(analytical_segment(name), tmp_path / f"m-{name}.csv")
    measured = load_library(str(tmp_path))
    assert measured.names == ["m-B46-T22", "m-B50-T20"] and measured.label == str(tmp_path)
    np.testing.assert_array_equal(measured.curves[1].p_kpa, analytical_segment("B50-T20").p_kpa)
    assert measured.digest != ScanLibrary("x", measured.curves[::-1]).digest
    (tmp_path / "m-B46-T22.csv").unlink()
    with pytest.raises(InputError, match="1 CSV file"):
        load_library(str(tmp_path))
    with pytest.raises(InputError, match="'analytical'"):
        load_library(str(tmp_path / "missing"))


@pytest.fixture(scope="module")
def pair_scan(tmp_path_factory):
    out = tmp_path_factory.mktemp("scan") / "pairs.h5"
    run_scan(small_library(), 2, out, workers=1, deflate=True)
    return read_scan(out)


# one block, and blocks of 7 rows: most actuators' rows straddle two blocks
@pytest.mark.parametrize("block_rows", [1 << 20, 7])
def test_the_summary_counts_what_the_paths_have(pair_scan, block_rows):
    """Counts and ranges per type (as the paper counts transitions), recomputed from the
    paths themselves, whatever the blocks the file is read in."""
    expected = {}
    events = 0
    for combo in itertools.combinations(SMALL, 2):
        actuator = Actuator([analytical_segment(n) for n in combo])
        found = transitions(quasi_static_path(actuator, deflate=True))
        events += len(found)
        for t in paper_transitions(found):
            expected.setdefault((t.direction, t.alpha, t.beta, t.stable), []).append(t)
    summary = summarise(pair_scan, block_rows)
    assert summary.actuators_done == 28 and summary.failed == 0
    assert {(t.direction, t.alpha, t.beta, t.stable): t.count for t in summary.types} == {
        key: len(found) for key, found in expected.items()
    }
    for t in summary.types:
        found = expected[(t.direction, t.alpha, t.beta, t.stable)]
        for metric in ("dE", "dv", "dl", "dp"):
            values = [getattr(x, metric) for x in found]
            assert t.ranges[metric] == (min(values), max(values))
    assert summary.transitions == sum(len(f) for f in expected.values())
    assert summary.events == events == pair_scan.row_stop
    snapping = {
        c
        for c in itertools.combinations(SMALL, 2)
        if any(
            not x.stable
            for x in transitions(
                quasi_static_path(Actuator([analytical_segment(n) for n in c]), deflate=True)
            )
        )
    }
    assert summary.actuators_with_snap == len(snapping)


@pytest.mark.parametrize(("by", "block_rows"), [("dl", 1 << 20), ("dv", 7), ("dp", 5), ("dE", 3)])
def test_rank_is_the_largest_transition_of_each_design(pair_scan, by, block_rows):
    best = {}
    for combo in itertools.combinations(SMALL, 2):
        actuator = Actuator([analytical_segment(n) for n in combo])
        found = paper_transitions(transitions(quasi_static_path(actuator, deflate=True)))
        best[combo] = max(abs(getattr(t, by)) for t in found)
    ranked = rank_designs(pair_scan, by, top=5, block_rows=block_rows)
    expected = sorted(best.items(), key=lambda item: -item[1])[:5]
    assert [tuple(d.segments) for d in ranked] == [combo for combo, _ in expected]
    assert [abs(d.value) for d in ranked] == [size for _, size in expected]
    assert [d.rank for d in ranked] == [1, 2, 3, 4, 5]
    assert all(d.value == d.metrics[by] for d in ranked)
    assert len(rank_designs(pair_scan, by, top=100, block_rows=block_rows)) == 28


def test_fig4_is_drawn(pair_scan, tmp_path):
    png = tmp_path / "fig4.png"
    plot_fig4(pair_scan, png)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 20_000
