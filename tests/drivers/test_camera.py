"""FrameSource and CameraLength: video files read back through cv2, live simulated frames."""

import math

import cv2
import numpy as np
import pytest

from labrig.drivers.camera import CameraLength, CameraSettings, FrameSource, fourcc_text
from labrig.errors import DeviceError, InputError
from labrig.rig.devices import LengthSource
from labrig.sim.camera import SimCamera
from labrig.time.virtual import VirtualClock

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


def live_source(clock, cam, **settings):
    """A SimCamera behind the real driver, configured as the rig does."""
    frames = FrameSource.live(cam, clock, "simulated camera")
    frames.configure(CameraSettings(**settings))
    return frames


def test_live_frames_through_the_driver_are_set_up_and_stamped_with_their_capture_time():
    clock = VirtualClock()
    # the test takes part in the clock's time: the camera streams only while it waits
    with clock.participate():
        cam = SimCamera(clock, lambda t: 35.0, size=(640, 360), mm_per_px=MM_PER_PX, fps=5.0)
        frames = live_source(clock, cam, width=640, height=360, fps=20.0)
        assert frames.stamp == "capture"  # a V4L2 capture: the kernel's buffer time
        length = CameraLength(frames, mm_per_px=MM_PER_PX)
        stamps = []
        for _ in range(5):
            sample = length.read()
            stamps.append(sample.t_s)
            assert sample.t_s == cam.get(cv2.CAP_PROP_POS_MSEC) / 1000.0
            assert np.asarray(sample.image).shape == (360, 640, 3)
            assert sample.ok and sample.length_mm == pytest.approx(35.0, abs=0.01)
        np.testing.assert_allclose(np.diff(stamps), 0.05, atol=1e-9)  # at the rate it was set to
        assert frames.n_grabbed - frames.n_frames == frames.warmup_frames  # settling frames dropped
        cam.release()
        with pytest.raises(DeviceError, match="simulated camera returned no frame"):
            length.read()


def test_a_slow_reader_gets_the_newest_frame_not_the_oldest_buffered():
    """V4L2 hands back the oldest of its 4 buffers: read raw at 2 Hz from a 30 fps
    stream, each frame is 3 periods old; through the driver's reader thread, fresh."""
    clock = VirtualClock()
    # the test takes part in the clock's time: the camera streams only while it waits
    with clock.participate():
        raw = SimCamera(clock, lambda t: 35.0, size=(640, 360), mm_per_px=MM_PER_PX, fps=30.0)
        ages = []
        for _ in range(4):
            clock.sleep(0.5)
            raw.read()
            ages.append(clock.now() - raw.get(cv2.CAP_PROP_POS_MSEC) / 1000.0)
        assert min(ages[1:]) > 2.5 / 30.0  # the first read starts the stream

        cam = SimCamera(clock, lambda t: 35.0, size=(640, 360), mm_per_px=MM_PER_PX, fps=30.0)
        frames = live_source(clock, cam, width=640, height=360, fps=30.0)
        frames.read()
        for _ in range(4):
            clock.sleep(0.5)
            frame = frames.read()
            assert 0.0 <= clock.now() - frame.t_s <= 1.0 / 30.0 + 1e-9
        frames.close()
        assert not cam.isOpened()


def test_every_frame_is_kept_by_the_reader_and_measured_in_batches():
    """``read_new``: the reader thread keeps every frame until taken; a caller polling
    every 0.2 s gets every frame once, in order, none lost between batches, each batch
    measured in the tracker's process while the caller waits for the next; ``read_rest``
    returns the last one."""
    clock = VirtualClock()
    # the test takes part in the clock's time: the camera streams only while it waits
    with clock.participate():
        cam = SimCamera(clock, lambda t: 30.0 + t, size=(640, 360), mm_per_px=MM_PER_PX, fps=30.0)
        frames = live_source(clock, cam, width=640, height=360, fps=30.0)
        length = CameraLength(frames, mm_per_px=MM_PER_PX)
        assert length.read_new() == []  # starts the reader; nothing streamed yet
        batches, taken = [], []
        for _ in range(10):
            clock.sleep(0.2)
            batches.append(length.read_new())
            taken.append(frames.n_frames)
        batches.append(length.read_rest())
        # each call returns the frames taken by the call before it
        assert batches[0] == []
        assert [len(b) for b in batches[1:]] == list(np.diff([0, *taken]))
        samples = [s for batch in batches for s in batch]
        t_s = np.array([s.t_s for s in samples])
        assert all(4 <= len(batch) <= 8 for batch in batches[2:])
        np.testing.assert_allclose(np.diff(t_s), 1 / 30, atol=1e-9)  # every frame, once
        assert t_s[-1] <= clock.now() and len(samples) == frames.n_frames
        assert all(s.ok for s in samples)
        np.testing.assert_allclose([s.length_mm for s in samples], 30.0 + t_s, atol=0.01)
        length.close()


def test_a_batched_camera_that_is_unplugged_is_a_device_error():
    clock = VirtualClock()
    # the test takes part in the clock's time: the camera streams only while it waits
    with clock.participate():
        cam = SimCamera(clock, lambda t: 35.0, size=(640, 360), mm_per_px=MM_PER_PX, fps=30.0)
        length = CameraLength(live_source(clock, cam, width=640, height=360), mm_per_px=MM_PER_PX)
        length.read_new()
        clock.sleep(0.5)
        assert length.read_rest()
        cam.release()  # unplugged
        clock.sleep(0.2)
        with pytest.raises(DeviceError, match="returned no frame: is it still connected"):
            length.read_new()
        length.close()


def test_a_size_rate_or_exposure_the_camera_cannot_do_is_refused_in_one_line():
    clock = VirtualClock()
    # the test takes part in the clock's time: the camera streams only while it waits
    with clock.participate():
        cam = SimCamera(clock, lambda t: 35.0, size=(1280, 720), mm_per_px=MM_PER_PX)
        with pytest.raises(DeviceError) as error:
            live_source(clock, cam, width=1920, height=1080)
        assert "asked for width 1920, the camera gives 640" in str(error.value)
        assert "\n" not in str(error.value)
        frames = live_source(
            clock, cam, width=1280, height=720, fps=30.0, exposure=80.0, focus=12.0
        )
        assert cam.get(cv2.CAP_PROP_AUTO_EXPOSURE) == 1.0  # locked: manual exposure
        assert cam.get(cv2.CAP_PROP_EXPOSURE) == 80.0 and cam.get(cv2.CAP_PROP_AUTOFOCUS) == 0.0
        assert np.asarray(frames.read().image).shape == (720, 1280, 3)


def test_mjpg_is_asked_first_and_a_yuyv_only_camera_short_of_the_rate_is_refused():
    """A UVC webcam opens in YUYV, which USB 2.0 carries at 10 fps at 1280x720: MJPG is
    asked for and read back; a camera that cannot do it and so cannot give 30 fps is
    refused in one line that names the pixel format."""
    clock = VirtualClock()
    with clock.participate():
        cam = SimCamera(clock, lambda t: 35.0, size=(1280, 720), mm_per_px=MM_PER_PX)
        assert fourcc_text(cam.get(cv2.CAP_PROP_FOURCC)) == "YUYV"  # as it opens
        frames = live_source(clock, cam, width=1280, height=720, fps=30.0)
        assert frames.fourcc == "MJPG" and cam.get(cv2.CAP_PROP_FPS) == 30.0
        yuyv_only = SimCamera(
            clock, lambda t: 35.0, size=(1280, 720), mm_per_px=MM_PER_PX, formats=("YUYV",)
        )
        with pytest.raises(DeviceError) as error:
            live_source(clock, yuyv_only, width=1280, height=720, fps=30.0)
        message = str(error.value)
        assert "streams YUYV, not MJPG, and gives 10 fps at 1280x720 where 30 were asked" in (
            message
        )
        assert "\n" not in message
        # what YUYV carries at a smaller size is accepted
        small = live_source(clock, yuyv_only, width=640, height=480, fps=30.0)
        assert small.fourcc == "YUYV"


def test_a_capture_stamp_off_the_host_clock_fails_the_stream():
    clock = VirtualClock()
    with clock.participate():
        cam = SimCamera(clock, lambda t: 35.0, size=(640, 360), mm_per_px=MM_PER_PX, fps=10.0)
        frames = live_source(clock, cam, width=640, height=360, fps=10.0)
        clock.sleep(5.0)
        assert frames.read() is not None
        cam.jump_clock(-3.0)
        with pytest.raises(DeviceError, match=r"behind the host clock.*clock jumped"):
            for _ in range(5):
                frames.read()
        frames.close()


def first_sample(length, clock, batched):
    """One frame read and measured (``batched``: in the reader thread, as a run does)."""
    if not batched:
        return length.read()
    length.read_new()
    clock.sleep(0.2)
    return length.read_rest()[0]


@pytest.mark.parametrize("batched", [False, True])
def test_a_dark_first_frame_fails_the_reference_calibration_unless_dropped(batched):
    # batched: the calibration's own one-line error comes through the reader thread
    clock = VirtualClock()
    # the test takes part in the clock's time: the camera streams only while it waits
    with clock.participate():
        scene = dict(size=(640, 360), mm_per_px=MM_PER_PX, fps=30.0)
        cam = SimCamera(clock, lambda t: 35.0, **scene)
        frames = FrameSource.live(cam, clock, "simulated camera", warmup_frames=0)
        frames.configure(CameraSettings(width=640, height=360))
        with pytest.raises(InputError, match="reference frame: both markers must be visible"):
            first_sample(CameraLength(frames, reference_distance_mm=35.0), clock, batched)
        cam = SimCamera(clock, lambda t: 35.0, **scene)
        length = CameraLength(
            live_source(clock, cam, width=640, height=360), reference_distance_mm=35.0
        )
        assert first_sample(length, clock, batched).ok
        assert length.mm_per_px == pytest.approx(MM_PER_PX, rel=1e-3)


def test_other_backends_are_stamped_when_the_grab_returns():
    clock = VirtualClock()
    # the test takes part in the clock's time: the camera streams only while it waits
    with clock.participate():
        cam = SimCamera(clock, lambda t: 35.0, size=(320, 240), mm_per_px=0.2, fps=10.0)
        cam.getBackendName = lambda: "MSMF"  # its POS_MSEC would not be a capture time
        frames = FrameSource.live(cam, clock, "camera 0", warmup_frames=0)
        assert frames.stamp == "host"
        frame = frames.read()
        assert frame.t_s == clock.now()


def test_a_dev_video_path_is_a_camera_not_a_file():
    with pytest.raises(DeviceError, match="camera /dev/video97: no such device"):
        FrameSource.open("/dev/video97", VirtualClock())


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


def test_a_by_id_link_is_a_camera_opened_by_the_node_it_names(tmp_path):
    """udev's /dev/v4l/by-id/... links keep a camera's name whichever /dev/videoN it
    gets: a link that leads into /dev is a camera, not a video file."""
    by_id = tmp_path / "by-id"
    by_id.mkdir()
    unplugged = by_id / "usb-Logitech_HD_Pro_Webcam_C920-video-index0"
    unplugged.symlink_to("/dev/video97")
    with pytest.raises(DeviceError) as error:
        FrameSource.open(str(unplugged), VirtualClock())
    assert str(error.value) == (
        f"camera {unplugged} (/dev/video97): no such device (is the camera plugged in?)"
    )
    # a node that is there is handed to OpenCV's V4L2 backend (this one is no camera)
    not_a_camera = by_id / "usb-Other-video-index0"
    not_a_camera.symlink_to("/dev/null")
    with pytest.raises(DeviceError, match=rf"camera {not_a_camera} \(/dev/null\) could not be"):
        FrameSource.open(str(not_a_camera), VirtualClock())


def test_auto_exposure_is_applied_when_no_exposure_is_given():
    """A camera another program left in manual exposure (V4L2 mode 1) is put back in
    auto (mode 3, aperture priority) unless the rig file gives an exposure."""
    clock = VirtualClock()
    with clock.participate():
        cam = SimCamera(clock, lambda t: 35.0, size=(640, 360), mm_per_px=MM_PER_PX)
        cam.set(cv2.CAP_PROP_AUTO_EXPOSURE, 1.0)
        live_source(clock, cam, width=640, height=360, fps=30.0)
        assert cam.get(cv2.CAP_PROP_AUTO_EXPOSURE) == 3.0
        live_source(clock, cam, width=640, height=360, fps=30.0, exposure=80.0)
        assert cam.get(cv2.CAP_PROP_AUTO_EXPOSURE) == 1.0


def test_the_measured_frame_rate_shows_what_auto_exposure_priority_takes():
    """In dim light, auto exposure with exposure_auto_priority on gives 12 fps where
    30 were set, and CAP_PROP_FPS still says 30: the stamps tell the real rate."""
    clock = VirtualClock()
    with clock.participate():
        cam = SimCamera(
            clock, lambda t: 35.0, size=(320, 240), mm_per_px=0.2, fps=30.0, dim_light_fps=12.0
        )
        frames = live_source(clock, cam, width=320, height=240, fps=30.0)
        assert frames.measured_fps is None  # no frame yet
        length = CameraLength(frames, mm_per_px=0.2)
        for _ in range(24):
            length.read()
        assert cam.get(cv2.CAP_PROP_FPS) == 30.0
        assert length.measured_fps == pytest.approx(12.0, rel=1e-6)
        # a manual exposure: the rate set
        manual = live_source(clock, cam, width=320, height=240, fps=30.0, exposure=50.0)
        for _ in range(10):
            manual.read()
        assert manual.measured_fps == pytest.approx(30.0, rel=1e-6)


def test_exposure_auto_priority_is_set_by_its_ioctl_on_a_v4l2_node(tmp_path):
    """The control goes to the node with VIDIOC_S_CTRL; a node that is no V4L2 device
    answers ENOTTY, a missing one ENOENT, each said in one line."""
    from labrig.drivers.v4l2_control import V4L2_CID_EXPOSURE_AUTO_PRIORITY, set_control

    assert "Inappropriate ioctl" in set_control("/dev/null", V4L2_CID_EXPOSURE_AUTO_PRIORITY, 0)
    missing = set_control(str(tmp_path / "video97"), V4L2_CID_EXPOSURE_AUTO_PRIORITY, 0)
    assert missing == f"{tmp_path / 'video97'}: No such file or directory"


def test_a_camera_slow_to_start_delivers_its_first_frame_late():
    clock = VirtualClock()
    with clock.participate():
        cam = SimCamera(
            clock, lambda t: 35.0, size=(320, 240), mm_per_px=0.2, fps=10.0, first_frame_delay_s=0.8
        )
        frames = FrameSource.live(cam, clock, "simulated camera", warmup_frames=0)
        frames.configure(CameraSettings(width=320, height=240, fps=10.0))
        start_s = clock.now()
        first = frames.read()
        assert first.t_s - start_s == pytest.approx(0.8, abs=0.1 + 1e-9)
        assert frames.read().t_s - first.t_s == pytest.approx(0.1)  # then at its rate
