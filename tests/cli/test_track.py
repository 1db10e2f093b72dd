"""``labrig track VIDEO``: the CSV contract, the printed summary, and bad input."""

import csv
import math

import cv2
import numpy as np
import pytest

from labrig import cli as cli_module
from labrig.sim.camera import SimCamera
from labrig.time.virtual import VirtualClock

MM_PER_PX = 0.08


@pytest.fixture(scope="module")
def video(tmp_path_factory):
    """20 frames; the second marker is painted out in frames 5-9."""
    cam = SimCamera(VirtualClock(), lambda t: 32.0 + 4.0 * t, size=(640, 360), mm_per_px=MM_PER_PX)
    path = tmp_path_factory.mktemp("track") / "specimen.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 20.0, (640, 360))
    for k in range(20):
        cam.hide_marker(1, hidden=5 <= k < 10)
        writer.write(cam.render(k / 20.0))
    writer.release()
    return path, 32.0 + 4.0 * np.arange(20) / 20.0


def run(argv, capsys):
    with pytest.raises(SystemExit) as exited:
        cli_module.main(argv)
    out, err = capsys.readouterr()
    return exited.value.code, out, err


def test_track_writes_a_row_per_frame_and_prints_rate_and_fraction(video, tmp_path, capsys):
    path, length_mm = video
    out_csv = tmp_path / "length.csv"
    code, out, err = run(
        ["track", str(path), "--mm-per-px", str(MM_PER_PX), "--out", str(out_csv)], capsys
    )
    assert code == 0, err
    assert "frames/s" in out and "markers tracked in 15 (75.0 %)" in out
    with out_csv.open() as f:
        assert f.readline().strip() == "t_s,x1_px,y1_px,x2_px,y2_px,length_mm,ok"
        f.seek(0)
        rows = list(csv.DictReader(f))
    assert len(rows) == 20
    np.testing.assert_allclose([float(r["t_s"]) for r in rows], np.arange(20) / 20.0)
    for k, row in enumerate(rows):
        if 5 <= k < 10:
            assert row["ok"] == "0" and math.isnan(float(row["length_mm"]))
        else:
            assert row["ok"] == "1"
            assert float(row["length_mm"]) == pytest.approx(length_mm[k], abs=0.01)


def test_track_with_a_reference_distance_writes_csv_to_stdout(video, capsys):
    path, length_mm = video
    code, out, err = run(["track", str(path), "--reference-distance-mm", "32"], capsys)
    assert code == 0, err
    lines = out.strip().splitlines()
    assert lines[0] == "t_s,x1_px,y1_px,x2_px,y2_px,length_mm,ok" and len(lines) == 21
    assert float(lines[1].split(",")[5]) == pytest.approx(32.0, abs=1e-4)
    assert float(lines[-1].split(",")[5]) == pytest.approx(length_mm[-1], abs=0.01)
    assert "frames/s" in err


@pytest.mark.parametrize(
    ("args", "message"),
    [
        ([], "exactly one of --mm-per-px S and --reference-distance-mm D"),
        (["--mm-per-px", "0.1", "--reference-distance-mm", "30"], "exactly one of"),
        (["--mm-per-px", "0"], "mm_per_px must be > 0"),
        (["--reference-distance-mm", "-3"], "must be > 0 mm"),
    ],
)
def test_scale_options_are_checked(video, args, message, capsys):
    code, _, err = run(["track", str(video[0]), *args], capsys)
    assert code == 2
    assert message in err and len(err.strip().splitlines()) == 1


def test_bad_videos_are_one_line_and_leave_no_csv(tmp_path, capsys):
    out_csv = tmp_path / "never.csv"
    missing = tmp_path / "missing.avi"
    code, _, err = run(["track", str(missing), "--mm-per-px", "0.1", "--out", str(out_csv)], capsys)
    assert code == 2 and err.strip() == f"error: {missing}: no such video file"
    garbage = tmp_path / "garbage.avi"
    garbage.write_bytes(b"\x00junk" * 1000)
    code, _, err = run(["track", str(garbage), "--mm-per-px", "0.1", "--out", str(out_csv)], capsys)
    assert code == 2 and "OpenCV cannot read this file as a video" in err
    assert "Traceback" not in err and not out_csv.exists()


def test_an_unwritable_out_path_is_an_input_error(video, tmp_path, capsys):
    target = tmp_path / "no-such-dir" / "x.csv"
    code, _, err = run(["track", str(video[0]), "--mm-per-px", "0.1", "--out", str(target)], capsys)
    assert code == 2 and err.endswith("no-such-dir does not exist\n")
