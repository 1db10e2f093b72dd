"""Video of a simulated run: one frame per tracked length sample with its
time in the run file, a killed run's video still opens, the frame strips show the
transition frames, `labrig compare --json`, and a failed scale calibration faults."""

import json
import os
import signal
import subprocess
import sys
import time

import cv2
import numpy as np
import pytest
from support.simrig import DEMO, run_sim, short_protocol

from labrig.analysis.frame_strip import CAPTION_PX, TILE_WIDTH_PX
from labrig.cli import main
from labrig.config.rig_file import CameraConfig, PumpConfig, RigConfig, SimConfig
from labrig.drivers.markers import MarkerTracker
from labrig.recording.run_reader import open_run, read_log
from labrig.rig.simulated import SIM_CAMERA_SIZE

VIDEO_DEMO = (
    DEMO.read_text()
    .replace("camera_fps: 30}", "camera_fps: 30, video: true}")
    .replace("times: 3", "times: 1")
    .replace("average_last: 2", "average_last: 1")
)


@pytest.fixture(scope="module")
def video_run(tmp_path_factory):
    outcome = run_sim(tmp_path_factory.mktemp("video"), VIDEO_DEMO, seed=0)
    assert outcome.result.status == "complete", outcome.result.reason
    return outcome.path


def decoded_frames(path, keep=lambda i: True):
    """(number of frames the video decodes to, {index: frame} of those ``keep``-ed)."""
    capture = cv2.VideoCapture(str(path))
    assert capture.isOpened()
    count, frames = 0, {}
    while capture.grab():
        if keep(count):
            ok, frames[count] = capture.retrieve()
            assert ok
        count += 1
    capture.release()
    return count, frames


def length_rows(path):
    with open_run(path) as run:
        length = read_log(run, 1, "length")
        video_t = run["entry/video/time"][:]
        video_rep = run["entry/video/repetition"][:]
        name = run["entry/video"].attrs["file"]
    return length, video_t, video_rep, name


def assert_frames_show_the_logged_markers(frames, length, indices):
    """Each decoded frame shows the markers where the length log's row puts them."""
    for i in indices:
        fix = MarkerTracker().track(frames[i])
        assert fix.ok
        logged = [length.fields[k][i] for k in ("x1", "y1", "x2", "y2")]
        # the frame's own markers (MJPG costs a little precision), not a neighbour's
        np.testing.assert_allclose([fix.x1_px, fix.y1_px, fix.x2_px, fix.y2_px], logged, atol=0.2)


def test_one_video_frame_per_length_sample_with_its_time(video_run):
    length, video_t, video_rep, name = length_rows(video_run)
    assert name == "run.avi"
    # around the snap the specimen moves fastest: a frame off by one would show it
    snap = int(np.argmax(np.abs(np.diff(length.fields["value"]))))
    checked = [0, snap, snap + 1, len(length) - 1]
    count, frames = decoded_frames(video_run.with_suffix(".avi"), keep=checked.__contains__)
    assert count == len(video_t) == len(length) > 3000  # 30 fps over 124 s
    assert np.array_equal(video_t, length.time_s) and np.all(video_rep == 1)
    assert np.diff(video_t) == pytest.approx(np.full(len(video_t) - 1, 1 / 30), abs=1e-9)
    width, height = SIM_CAMERA_SIZE  # the simulated rig's monochrome sensor
    assert frames[0].shape == (height, width, 3)  # decoded as BGR, as OpenCV does
    assert_frames_show_the_logged_markers(frames, length, checked)


def test_a_killed_runs_video_opens_and_holds_the_frames_up_to_the_kill(tmp_path):
    protocol = tmp_path / "p.yaml"
    protocol.write_text(
        short_protocol(camera_fps=30).replace("camera_fps: 30}", "camera_fps: 30, video: true}")
    )
    out = tmp_path / "killed.h5"
    command = [sys.executable, "-m", "labrig", "run", str(protocol), "--sim", "--out", str(out)]
    process = subprocess.Popen([*command, "--speed", "5"], stdout=subprocess.PIPE)
    video = out.with_suffix(".avi")
    deadline = time.monotonic() + 120
    while not (video.exists() and video.stat().st_size > 2_000_000):
        assert process.poll() is None and time.monotonic() < deadline
        time.sleep(0.2)
    os.kill(process.pid, signal.SIGKILL)
    process.wait()
    length, video_t, _, _ = length_rows(out)
    count, _ = decoded_frames(video, keep=lambda i: False)
    n = min(count, len(video_t))
    _, frames = decoded_frames(video, keep={0, n - 1}.__contains__)
    assert count >= 40 and len(video_t) >= 1
    assert np.array_equal(video_t[:n], length.time_s[:n])
    assert_frames_show_the_logged_markers(frames, length, [0, n - 1])


def test_the_transition_strip_shows_the_frames_before_and_after(video_run, tmp_path, capsys):
    out = tmp_path / "strip.png"
    with pytest.raises(SystemExit) as done:
        main(["frames", str(video_run), "--at-transitions", "-o", str(out)])
    assert done.value.code == 0, capsys.readouterr()
    strip = cv2.imread(str(out))
    scale = TILE_WIDTH_PX / SIM_CAMERA_SIZE[0]  # frames scaled to the tile's width
    tile_h = round(SIM_CAMERA_SIZE[1] * scale) + CAPTION_PX  # caption under
    length = length_rows(video_run)[0]
    from labrig.analysis.analyse import analyse

    snaps = analyse(video_run).repetitions[0].transitions
    assert strip.shape == (len(snaps) * tile_h, 2 * TILE_WIDTH_PX, 3)  # a row a snap
    row = max(range(len(snaps)), key=lambda i: abs(snaps[i].dl_mm))  # the largest jump
    snap = snaps[row]
    t = length.time_s
    logged_px = np.hypot(
        length.fields["x2"] - length.fields["x1"], length.fields["y2"] - length.fields["y1"]
    )
    lengths = []
    for column in (0, 1):
        top = row * tile_h
        columns = slice(column * TILE_WIDTH_PX, (column + 1) * TILE_WIDTH_PX)
        tile = strip[top : top + tile_h - CAPTION_PX, columns]
        # the tile's markers: the darkest spots, at the logged positions of its frame
        grey = cv2.cvtColor(tile, cv2.COLOR_BGR2GRAY)
        dark = np.argwhere(grey < 60)  # the dots' cores (40); the background is 90 +- noise
        left, right = dark[dark[:, 1] < TILE_WIDTH_PX / 2], dark[dark[:, 1] >= TILE_WIDTH_PX / 2]
        centres = [side.mean(axis=0)[::-1] for side in (left, right)]  # (x, y)
        distance = np.hypot(*(centres[1] - centres[0])) / scale  # tile px -> frame px
        lengths.append(distance)
        # a frame of the log within 3 s on its side of the snap shows these markers
        # (the dots' cores, to 1.5 tile px, against the tracker's sub-pixel fix)
        side = (
            (t <= snap.t_s) & (t >= snap.t_s - 3)
            if column == 0
            else (t >= snap.t_s) & (t <= snap.t_s + 3)
        )
        shows = (np.abs(logged_px[side] - distance) < 1.5 / scale) & (
            np.abs(length.fields["y1"][side] * scale - centres[0][1]) < 1.5
        )
        assert shows.any(), (column, distance)
    # before and after differ by the measured jump, with its sign
    mm_per_px = length.fields["value"][0] / logged_px[0]
    shown = (lengths[1] - lengths[0]) * mm_per_px
    assert np.sign(shown) == np.sign(snap.dl_mm)
    assert shown == pytest.approx(snap.dl_mm, rel=0.3)


def test_the_volume_strip_has_a_frame_per_volume(video_run, tmp_path, capsys):
    out = tmp_path / "volumes.png"
    with pytest.raises(SystemExit) as done:
        main(["frames", str(video_run), "--at-volumes", "10,20,30", "-o", str(out)])
    assert done.value.code == 0, capsys.readouterr()
    assert cv2.imread(str(out)).shape == (360 + CAPTION_PX, 3 * TILE_WIDTH_PX, 3)
    with pytest.raises(SystemExit) as done:
        main(["frames", str(video_run), "--at-volumes", "10,99", "-o", str(out)])
    assert done.value.code == 2
    assert "reached only" in capsys.readouterr().err


def test_compare_json_is_the_contract_and_the_snap_length_change_is_measured(video_run, capsys):
    with pytest.raises(SystemExit) as done:
        main(["compare", str(video_run), "--json"])
    assert done.value.code == 0
    data = json.loads(capsys.readouterr().out)
    assert set(data["rmse"]) >= {"inflate_pressure_kpa", "deflate_pressure_kpa"}
    keys = {"phase", "type", "alpha", "beta", "v_ml", "v_meas_ml", "dp_kpa", "dp_meas_kpa",
            "dl_mm", "dl_meas_mm"}  # fmt: skip
    # the contract's fields in every row (fields added beside them are allowed)
    assert all(set(t) >= keys for t in data["transitions"])
    snaps = [t for t in data["transitions"] if (t["type"], t["phase"]) == ("snap", "inflate")]
    snap = max(snaps, key=lambda t: abs(t["dl_mm"]))
    assert snap["v_meas_ml"] is not None
    # the demo's lengthening snap: the measured length change within 0.5 mm of the model's
    assert snap["dl_meas_mm"] == pytest.approx(snap["dl_mm"], abs=0.5)


def test_a_failed_scale_calibration_faults_the_run_before_anything_moves(tmp_path):
    """A marker covered: the scale cannot be taken from the reference distance, and the
    run ends faulted with nothing moved, not after the first millilitres."""
    config = RigConfig(
        pump=PumpConfig(port="emulator"),
        camera=CameraConfig(reference_distance_mm=60.0, warmup_frames=0),
        sim=SimConfig(),
    )
    outcome = run_sim(
        tmp_path,
        short_protocol(camera_fps=30),
        config=config,
        inject=lambda rig: rig.simulation.camera.hide_marker(1),
    )
    assert outcome.result.status == "faulted"
    assert "no scale: both markers were not found" in outcome.result.reason
    emulator = outcome.rig.simulation.emulator
    assert emulator.net_volume_ml(outcome.end_s) == 0.0
    assert outcome.pump_is_stopped()
    with open_run(outcome.path) as run:
        assert run["entry/status"][()] == b"faulted"


def test_the_scale_is_taken_once_the_exposure_settled(tmp_path):
    """No warm-up frames: the first frames are dark; the scale comes from the first
    frame in which both markers are found, before the pump moves."""
    config = RigConfig(
        pump=PumpConfig(port="emulator"),
        camera=CameraConfig(reference_distance_mm=60.0, warmup_frames=0),
        sim=SimConfig(),
    )
    outcome = run_sim(tmp_path, short_protocol(camera_fps=30), config=config)
    assert outcome.result.status == "complete", outcome.result.reason
    camera = outcome.rig.simulation.camera
    assert outcome.rig.length.mm_per_px == pytest.approx(camera.mm_per_px, rel=0.01)


def test_a_video_file_standing_in_for_the_camera_is_read_at_camera_fps(tmp_path):
    """A file's read does not wait for frames: the camera loop paces it. Were it read
    in a loop without a wait, virtual time would never move and the run never end."""
    from labrig.config.protocol import load_protocol
    from labrig.config.rig_file import sim_rig_config
    from labrig.drivers.camera import CameraLength, FrameSource
    from labrig.rig.assembly import build_rig
    from labrig.run.runner import Runner
    from labrig.sim.camera import SimCamera
    from labrig.time.virtual import VirtualClock

    video = tmp_path / "specimen.avi"
    SimCamera(VirtualClock(), lambda t: 50.0, size=(640, 360), mm_per_px=0.1).write_video(
        video, n_frames=40, fps=25.0
    )
    protocol = tmp_path / "p.yaml"
    protocol.write_text(short_protocol(camera_fps=2))
    loaded = load_protocol(protocol)
    rig = build_rig(loaded.protocol, sim_rig_config())
    rig.length.close()
    rig.length = CameraLength(FrameSource.open_file(video), mm_per_px=0.1)
    with rig.clock.participate():
        result = Runner(loaded, rig, tmp_path / "run.h5").run()
    assert result.status == "complete", result.reason
    with open_run(result.path) as run:
        length = read_log(run, 1, "length")
    assert len(length) == 40 and length.fields["ok"].all()  # every frame, then the end
    assert length.fields["value"] == pytest.approx(np.full(40, 50.0), abs=0.02)


def test_a_real_cameras_frames_go_to_the_encoder_as_pixels(tmp_path):
    """Frames without a scene (a real camera's arrays) are sent whole and written in
    order; a directory that cannot hold the file is an OSError, not a hang."""
    from labrig.recording.video import VideoRecorder

    recorder = VideoRecorder(tmp_path / "real.avi", fps=30)
    images = [np.full((120, 160, 3), 30 * k + 20, dtype=np.uint8) for k in range(6)]
    for image in images:
        recorder.add(image)
    assert recorder.close() == 6 and recorder.error is None
    count, frames = decoded_frames(tmp_path / "real.avi")
    assert count == 6
    means = [float(frames[k].mean()) for k in range(6)]
    assert means == pytest.approx([30 * k + 20 for k in range(6)], abs=3)

    broken = VideoRecorder(tmp_path / "no-such-dir" / "x.avi", fps=30)
    with pytest.raises(OSError):
        for _ in range(2000):  # the encoder's failure reaches a later hand-over
            broken.add(images[0])
    assert broken.close() == 0 and "cannot write" in str(broken.error)


@pytest.mark.parametrize("suffix", [".avi", ".mkv", ".mp4"])
@pytest.mark.parametrize("colour", [False, True])
def test_every_container_holds_every_frame_at_its_rate(tmp_path, suffix, colour):
    """Motion-JPEG frames encoded by OpenCV and muxed as they are (AVI, Matroska) or
    MPEG-4 encoded by FFmpeg: each decodes, in order, at the nominal rate (to within
    4 grey levels: MPEG-4's colour frames go through limited-range YUV)."""
    from labrig.recording.video import VideoRecorder

    path = tmp_path / f"frames{suffix}"
    recorder = VideoRecorder(path, fps=25)
    shape = (96, 128, 3) if colour else (96, 128)
    levels = [12 * k + 10 for k in range(20)]
    for level in levels:
        recorder.add(np.full(shape, level, dtype=np.uint8))
    assert recorder.close() == 20 and recorder.error is None
    count, frames = decoded_frames(path)
    assert count == 20
    assert cv2.VideoCapture(str(path)).get(cv2.CAP_PROP_FPS) == pytest.approx(25)
    assert [float(frames[k].mean()) for k in range(20)] == pytest.approx(levels, abs=4)
