"""``labrig run --out``: an existing file is refused unless ``--overwrite`` moves it aside,
and two runs started at once onto one file leave one complete run and one clear line."""

import subprocess
import sys
import textwrap

import pytest

from labrig.cli import main
from labrig.recording.run_reader import open_run
from tests.support.simulated_runs import tiny_run

TINY = textwrap.dedent(
    """
    name: tiny
    specimen: {segments: [SI-B48-T30]}
    rig: sim
    limits: {max_pressure_kpa: 95, max_volume_ml: 45}
    acquisition: {pressure_rate_hz: 100}
    steps:
      - zero_pressure: {duration_s: 0.1}
      - infuse: {rate_ml_min: 60, volume_ml: 1}
    analysis: {average_last: 1, compare_model: false}
    """
)


def run(argv, capsys):
    with pytest.raises(SystemExit) as exited:
        main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return exited.value.code, out, err


def test_a_finished_run_is_never_overwritten(tmp_path, capsys):
    protocol = tmp_path / "tiny.yaml"
    protocol.write_text(TINY)
    done = tiny_run(tmp_path / "done.h5")
    before = done.read_bytes()
    code, _, err = run(["run", protocol, "--sim", "--out", done], capsys)
    assert code == 2
    assert err.strip().splitlines()[-1] == (
        f"error: {done}: a run file is already there; choose another --out, or "
        "--overwrite to move it aside first (it is never deleted)"
    )
    assert done.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["done.h5", "tiny.yaml"]


@pytest.mark.slow  # two simulated runs in their own processes: ~6 s
def test_two_runs_started_at_once_on_one_file(tmp_path):
    protocol = tmp_path / "tiny.yaml"
    protocol.write_text(TINY)
    out = tmp_path / "one.h5"
    command = [sys.executable, "-m", "labrig", "run", str(protocol), "--sim", "--out", str(out)]
    runs = [
        subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        for _ in range(2)
    ]
    ended = sorted((p.wait(timeout=300), p.stderr.read()) for p in runs)
    for p in runs:
        p.stdout.close()
        p.stderr.close()
    (won, _), (lost, lost_err) = ended
    assert (won, lost) == (0, 2)
    (line,) = [x for x in lost_err.splitlines() if x.startswith("error:")]
    assert "internal error" not in line
    assert line.startswith(f"error: {out}: ")
    assert "another --out" in line or "a file is already there" in line
    with open_run(out) as finished:
        assert finished["entry/status"][()] == b"complete"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["one.h5", "tiny.yaml"]


@pytest.mark.parametrize(
    ("out", "expected"),
    [
        ("x" * 300 + ".h5", "not a usable run file name (File name too long)"),
        ("/dev/null", "exists and is not a regular file; choose another --out"),
        ("a-file/run.h5", "cannot create its folder (File exists)"),
    ],
)
def test_an_unusable_out_path_is_one_line(tmp_path, capsys, out, expected):
    protocol = tmp_path / "tiny.yaml"
    protocol.write_text(TINY)
    (tmp_path / "a-file").write_text("")
    target = out if out.startswith("/") else tmp_path / out
    code, _, err = run(["run", protocol, "--sim", "--out", target], capsys)
    assert code == 2
    assert err.strip().splitlines()[-1] == f"error: {target}: {expected}"


VIDEO = TINY.replace("pressure_rate_hz: 100}", "pressure_rate_hz: 100, camera_fps: 5, video: true}")


@pytest.mark.parametrize(
    ("out", "expected"),
    [
        (
            "x.avi",
            "a run file's name cannot end in .avi: the run's video is RUN.avi and its lock "
            "RUN.h5.lock beside it; give a name ending in .h5",
        ),
        (
            "x.h5.lock",
            "a run file's name cannot end in .lock: the run's video is RUN.avi and its lock "
            "RUN.h5.lock beside it; give a name ending in .h5",
        ),
    ],
)
def test_the_run_file_and_its_video_never_share_a_name(tmp_path, capsys, out, expected):
    protocol = tmp_path / "video.yaml"
    protocol.write_text(VIDEO)
    code, _, err = run(["run", protocol, "--sim", "--out", tmp_path / out], capsys)
    assert code == 2
    assert err.strip().splitlines()[-1] == f"error: {tmp_path / out}: {expected}"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["video.yaml"]


@pytest.mark.parametrize("out", ["a\nb.h5", "run\u202egpj.h5", "bell\a.h5"])
def test_an_out_name_that_shows_as_another_is_refused(tmp_path, capsys, out):
    protocol = tmp_path / "tiny.yaml"
    protocol.write_text(TINY)
    code, _, err = run(["run", protocol, "--sim", "--out", tmp_path / out], capsys)
    assert code == 2
    assert "is a control or a text-direction mark" in err.strip().splitlines()[-1]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tiny.yaml"]
