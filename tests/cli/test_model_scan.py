"""``labrig model scan``, ``scan-summary`` and ``rank`` through the real entry point: a
library of measured CSV curves, the summary and ranking tables, the Fig. 4 plot, Ctrl-C
on a real process pool and --resume, and bad input as one line with exit code 2."""

import os
import re
import signal
import subprocess
import sys
import time

import h5py
import pytest

from labrig.cli import main
from labrig.model.scan.scan_file import read_scan
from labrig.model.segments.catalog import SI_NAMES, analytical_segment
from labrig.model.segments.measured import write_csv


def run(argv, capsys):
    with pytest.raises(SystemExit) as exited:
        main(argv)
    out, err = capsys.readouterr()
    return exited.value.code, out, err


def csv_library(folder, names):
    folder.mkdir(exist_ok=True)
    for name in names:
        write_csv(analytical_segment(name), folder / f"{name}.csv")
    return folder


def test_scan_a_measured_library_then_summary_and_rank(tmp_path, capsys):
    library = csv_library(
        tmp_path / "lib", ["SI-B48-T30", "SI-B50-T20", "SI-B46-T20", "SI-B46-T22"]
    )
    out = tmp_path / "pairs.h5"
    code, text, err = run(
        [
            "model",
            "scan",
            "--n",
            "2",
            "--library",
            str(library),
            "--out",
            str(out),
            "--workers",
            "1",
        ],
        capsys,
    )
    assert code == 0, err
    assert "6 of 6 actuators (complete)" in text
    assert "(0, 1)   stable" in text and "snap" in text
    data = read_scan(out)
    assert data.names == ["SI-B46-T20", "SI-B46-T22", "SI-B48-T30", "SI-B50-T20"]
    code, text, _ = run(["model", "rank", str(out), "--by", "dv", "--top", "2"], capsys)
    assert code == 0
    lines = [line for line in text.splitlines() if line.lstrip().startswith(("1 ", "2 "))]
    assert len(lines) == 2 and "SI-B48-T30 + SI-B50-T20" in lines[0]  # the 0.45 volume flow
    png = tmp_path / "fig4.png"
    code, text, _ = run(["model", "scan-summary", str(out), "--plot", str(png)], capsys)
    assert code == 0 and f"plot: {png}" in text and png.stat().st_size > 10_000


def _default_sigint():
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _done_chunks(path):
    """Read a file another process is writing (no lock; retried if caught mid-write)."""
    try:
        with h5py.File(path, "r", locking=False) as h5:
            return int(h5["chunks/done"][:].sum())
    except (OSError, KeyError):
        return 0


@pytest.mark.slow
def test_ctrl_c_keeps_the_finished_chunks_and_resume_completes(tmp_path, capsys):
    # 12 segments, 495 quadruples in 31 chunks of 16: interrupted after two chunks, the
    # rest is still seconds of a worker's compute (the scan runs twice, whole and resumed)
    library = csv_library(tmp_path / "lib", SI_NAMES[::2][:12])
    out = tmp_path / "quadruples.h5"
    argv = ["model", "scan", "--n", "4", "--library", str(library), "--out", str(out)]
    process = subprocess.Popen(
        [sys.executable, "-m", "labrig", *argv, "--workers", "2"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        # a shell running the tests in the background starts them with SIGINT ignored,
        # which Python would keep: give the scan the default, as a terminal would
        preexec_fn=_default_sigint,
    )
    # Ctrl-C once two chunks are written, however long the scan takes to get there (a
    # fresh clone compiles the solver first: over a minute on a busy host); the guard
    # only keeps a hung scan from hanging the suite
    deadline = time.monotonic() + 900
    while _done_chunks(out) < 2 and time.monotonic() < deadline and process.poll() is None:
        time.sleep(0.05)
    assert process.poll() is None and _done_chunks(out) >= 2, "the scan never wrote two chunks"
    os.kill(process.pid, signal.SIGINT)
    _, err = process.communicate(timeout=60)
    assert process.returncode == 130, err
    assert "--resume continues it" in err and "Traceback" not in err
    partial = read_scan(out)
    assert not partial.complete and 0 < partial.actuators_done < 495
    code, text, err = run([*argv, "--resume", "--workers", "2"], capsys)
    assert code == 0, err
    assert "495 of 495 actuators (complete)" in text
    assert re.search(r",\s+\d{1,3}(,\d{3})+\s+transitions", text)  # thousands separated
    resumed = read_scan(out)
    fresh = tmp_path / "fresh.h5"
    code, _, _ = run([*argv[:-1], str(fresh), "--workers", "1"], capsys)
    expected = read_scan(fresh)
    assert resumed.actuator.tolist() == expected.actuator.tolist()
    for name, column in expected.columns.items():
        assert resumed.columns[name].tolist() == column.tolist(), name


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["model", "scan", "--n", "1", "--out", "{tmp}/a.h5"], "--n 1: choose 2..6"),
        (
            ["model", "scan", "--n", "2", "--library", "{tmp}/none", "--out", "{tmp}/a.h5"],
            "--library",
        ),
        (["model", "scan", "--n", "2", "--out", "{tmp}/no/a.h5"], "does not exist"),
        (["model", "scan", "--n", "2", "--out", "{tmp}/a.h5", "--workers", "0"], "--workers 0"),
        (["model", "rank", "{tmp}/missing.h5"], "no such file"),
        (["model", "scan-summary", "{tmp}/plain.h5"], "not a labrig scan file"),
        (["model", "rank", "{tmp}/text.h5"], "not an HDF5 file"),
    ],
)
def test_bad_input_is_one_line_with_exit_code_2(tmp_path, capsys, argv, message):
    h5py.File(tmp_path / "plain.h5", "w").close()
    (tmp_path / "text.h5").write_text("not hdf5")
    code, _, err = run([a.format(tmp=tmp_path) for a in argv], capsys)
    assert code == 2
    assert message in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "a.h5").exists()


def test_an_existing_file_is_not_overwritten(tmp_path, capsys):
    out = tmp_path / "a.h5"
    out.write_bytes(b"precious")
    code, _, err = run(["model", "scan", "--n", "2", "--out", str(out)], capsys)
    assert code == 2 and "--resume continues it" in err
    assert out.read_bytes() == b"precious"


def test_rank_rejects_a_non_positive_top(tmp_path, capsys):
    library = csv_library(tmp_path / "lib", ["SI-B48-T30", "SI-B50-T20"])
    out = tmp_path / "one.h5"
    assert (
        run(["model", "scan", "--n", "2", "--library", str(library), "--out", str(out)], capsys)[0]
        == 0
    )
    code, _, err = run(["model", "rank", str(out), "--top", "0"], capsys)
    assert code == 2 and "--top 0" in err


def test_the_help_names_every_library_the_catalog_scans():
    """The help is text written in the command (the catalog imports scipy, too slow for
    ``--help``), so this keeps it from falling behind a library added to the catalog."""
    from labrig.cli.model_scan import scan
    from labrig.model.segments.catalog import LIBRARIES

    (option,) = [p for p in scan.params if p.name == "library_spec"]
    assert [name for name in LIBRARIES if f"'{name}'" not in option.help] == []
