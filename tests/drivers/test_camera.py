"""FrameSource and CameraLength: video files read back through cv2, live simulated frames."""

import math

import cv2
import numpy as np
import pytest

from labrig.devices import LengthSource
from labrig.drivers.camera import CameraLength, FrameSource
from labrig.errors import DeviceError, InputError
from labrig.sim.camera import SimCamera
from labrig.virtual_clock import VirtualClock

MM_PER_PX = 0.08


@pytest.fixture(scope="module")
def video(tmp_path_factory):
    """A rendered MJPG/AVI: 640x360, the specimen stretching from 30 to 36 mm."""
    cam = SimCamera(VirtualClock(), lambda t: 30.0 + 6.0 * t, size=(640, 360), mm_per_px=MM_PER_PX)
    path = tmp_path_factory.mktemp("video") / "run.avi"
    return path, cam.write_video(path, n_frames=25, fps=25.0)


def read_all(source):
    samples = []
    while (sample := source.read()) is not None:
        samples.append(sample)
    return samples


def test_length_from_a_video_file(video):
    path, truth = video
    length = CameraLength(FrameSource.open(str(path), VirtualClock()), mm_per_px=MM_PER_PX)
    assert isinstance(length, LengthSource)
    samples = read_all(length)
    length.close()
    assert len(samples) == 25 and all(s.ok for s in samples)
    # File frames carry the file's own times: 0, 40, 80 ms at 25 fps.
    np.testing.assert_allclose([s.t_s for s in samples], truth.t_s, atol=1e-9)
    np.testing.assert_allclose([s.length_mm for s in samples], truth.length_mm, atol=0.01)
    positions = np.array([[[s.x1_px, s.y1_px], [s.x2_px, s.y2_px]] for s in samples])
    assert np.max(np.abs(positions - truth.centres_px)) < 0.1  # through MJPG compression


def test_scale_from_the_first_frame_as_reference(video):
    path, truth = video
    length = CameraLength(FrameSource.open_file(path), reference_distance_mm=30.0)
    samples = read_all(length)
    assert samples[0].length_mm == pytest.approx(30.0, abs=1e-9)
    assert length.mm_per_px == pytest.approx(MM_PER_PX, rel=2e-4)
    np.testing.assert_allclose([s.length_mm for s in samples], truth.length_mm, atol=0.01)


def test_live_frames_are_stamped_on_the_shared_clock():
    clock = VirtualClock()
    cam = SimCamera(clock, lambda t: 35.0, size=(640, 360), mm_per_px=MM_PER_PX, fps=20.0)
    length = CameraLength(FrameSource(cam, clock=clock, name="simulated camera"), mm_per_px=0.08)
    for _ in range(5):
        sample = length.read()
        frame_time_s = cam.get(cv2.CAP_PROP_POS_MSEC) / 1000.0
        # The host clock right after the grab: just after the frame was taken (its render
        # takes a millisecond or two; the bound leaves room for a busy machine).
        assert 0.0 <= sample.t_s - frame_time_s < 0.1
        assert sample.ok and sample.length_mm == pytest.approx(35.0, abs=0.01)
    cam.release()
    with pytest.raises(DeviceError, match="simulated camera returned no frame"):
        length.read()


def test_lost_markers_in_a_video_give_nan_rows(tmp_path):
    cam = SimCamera(VirtualClock(), lambda t: 30.0, size=(640, 360), mm_per_px=MM_PER_PX)
    path = tmp_path / "lost.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 25.0, (640, 360))
    for k in range(6):
        cam.hide_marker(0, hidden=k in (2, 3))
        writer.write(cam.render(k / 25.0))
    writer.release()
    samples = read_all(CameraLength(FrameSource.open_file(path), mm_per_px=MM_PER_PX))
    assert [s.ok for s in samples] == [True, True, False, False, True, True]
    assert math.isnan(samples[2].length_mm) and math.isnan(samples[3].x1_px)


def test_missing_unreadable_and_empty_videos_are_input_errors(tmp_path):
    with pytest.raises(InputError, match="no such video file"):
        FrameSource.open_file(tmp_path / "missing.avi")
    garbage = tmp_path / "garbage.avi"
    garbage.write_bytes(b"not a video" * 500)
    with pytest.raises(InputError, match="OpenCV cannot read this file as a video"):
        FrameSource.open_file(garbage)
    empty = tmp_path / "empty.avi"
    cv2.VideoWriter(str(empty), cv2.VideoWriter_fourcc(*"MJPG"), 25.0, (64, 64)).release()
    with pytest.raises(InputError, match="no frame could be read"):
        FrameSource.open_file(empty).read()


def test_a_camera_that_cannot_be_opened_is_a_device_error_naming_sim():
    with pytest.raises(DeviceError, match=r"camera 97 could not be opened.*--sim"):
        FrameSource.open("97", VirtualClock())


def test_exactly_one_scale_is_required(video):
    frames = FrameSource.open_file(video[0])
    with pytest.raises(InputError, match="exactly one"):
        CameraLength(frames)
    with pytest.raises(InputError, match="exactly one"):
        CameraLength(frames, mm_per_px=0.1, reference_distance_mm=30.0)
    with pytest.raises(InputError, match="must be > 0"):
        CameraLength(frames, mm_per_px=-0.1)


def test_exposure_timestamps_come_from_the_capture():
    clock = VirtualClock()
    camera = SimCamera(clock, lambda t: 40.0 + t, fps=5.0)
    frames = FrameSource(camera, clock=clock, name="sim", exposure_timestamps=True)
    stamps = [frames.read().t_s for _ in range(3)]
    assert stamps == sorted(stamps)
    assert stamps[-1] == camera.get(cv2.CAP_PROP_POS_MSEC) / 1000.0
    assert np.allclose(np.diff(stamps), 0.2, atol=0.05)  # one frame per 1/fps
