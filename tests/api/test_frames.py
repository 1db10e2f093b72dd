"""``Run.transition_frames`` and ``Run.frame_at``: the video's frames as arrays."""

import cv2
import h5py
import numpy as np
import pytest
from support.api_runs import QUICK_PROTOCOL

import labrig

# a run with video costs ~3 s of CPU (the camera process and the encoder)
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def video_run(tmp_path_factory):
    """The tutorial's protocol with ``video: true`` (5 frames a second, beside the file)."""
    from labrig.cli import main

    folder = tmp_path_factory.mktemp("video")
    protocol = folder / "video.yaml"
    text = QUICK_PROTOCOL.read_text().replace("camera_fps: 5}", "camera_fps: 5, video: true}")
    assert "video: true" in text
    protocol.write_text(text)
    out = folder / "video.h5"
    with pytest.raises(SystemExit) as exited:
        main(["run", str(protocol), "--sim", "--seed", "2", "--out", str(out)])
    assert exited.value.code == 0
    return out


def _frame(video_path, index):
    """Frame ``index`` read on its own, by OpenCV, as RGB."""
    capture = cv2.VideoCapture(str(video_path))
    capture.set(cv2.CAP_PROP_POS_FRAMES, index)
    ok, image = capture.read()
    capture.release()
    assert ok
    return image[..., ::-1]


def test_the_frames_at_each_transition_are_the_videos(video_run):
    run = labrig.open_run(video_run)
    frames = run.transition_frames()
    measured = run.transitions
    assert len(frames) == 2 * len(measured) > 0  # before and after each
    with h5py.File(video_run, "r") as h5:
        times = h5["entry/video/time"][:]
        video = video_run.parent / h5["entry/video"].attrs["file"]
    for frame in frames[:4]:
        assert frame.image.dtype == np.uint8 and frame.image.ndim == 3
        assert frame.t_s == times[frame.frame_index]
        np.testing.assert_array_equal(frame.image, _frame(video, frame.frame_index))
    before, after = frames[0], frames[1]
    assert before.label.startswith("before") and after.label.startswith("after")
    assert before.t_s <= measured["t_s"][0] <= after.t_s


def test_frame_at_is_the_nearest_frame_in_time(video_run):
    run = labrig.open_run(video_run)
    with h5py.File(video_run, "r") as h5:
        times = h5["entry/video/time"][:]
        video = video_run.parent / h5["entry/video"].attrs["file"]
    index = int(np.argmin(np.abs(times - 30.03)))
    np.testing.assert_array_equal(run.frame_at(30.03), _frame(video, index))
