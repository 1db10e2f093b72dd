"""SimCamera: the rendered truth, lighting and noise, the capture interface, video files."""

import functools
import math

import cv2
import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from labrig.drivers.markers import MarkerTracker
from labrig.sim.camera import SimCamera
from labrig.sim.camera_frame import SimFrame
from labrig.sim.camera_scene import blur_matrix
from labrig.time.virtual import VirtualClock


def camera(**kwargs):
    kwargs.setdefault("clock", VirtualClock())
    kwargs.setdefault("length_mm_at", lambda t: 40.0)
    return SimCamera(**kwargs)


def centres(fix):
    return np.array([[fix.x1_px, fix.y1_px], [fix.x2_px, fix.y2_px]])


def streaming_at_sensor_size(cam):
    """Set the stream to the sensor's size, as the driver does (V4L2 opens at 640x480)."""
    cam.set(cv2.CAP_PROP_FRAME_WIDTH, cam.width)
    cam.set(cv2.CAP_PROP_FRAME_HEIGHT, cam.height)
    return cam


def test_markers_sit_where_the_length_puts_them():
    cam = camera(length_mm_at=lambda t: 30.0 + t, mm_per_px=0.05)
    for t in (0.0, 2.5, 7.0):
        (x1, y1), (x2, y2) = cam.marker_centres_px(t)
        assert math.hypot(x2 - x1, y2 - y1) * 0.05 == pytest.approx(30.0 + t)
        assert x1 < x2


@pytest.mark.parametrize("blur_px", [0.0, 1.5])
def test_dots_are_rendered_at_their_exact_subpixel_centre_and_area(blur_px):
    """Independent of the tracker: moments of the noise-free image against the truth."""
    rng = np.random.default_rng(5)
    for _ in range(10):
        centre = (640 + rng.uniform(-1, 1), 360 + rng.uniform(-1, 1))
        cam = camera(
            centre_px=centre,
            blur_px=blur_px,
            noise_grey=0.0,
            lighting_drift=0.0,
            sway_px=0.0,
            marker_bgr=(0, 0, 0),
            specimen_bgr=(250, 250, 250),
        )
        frame = cam.render(0.0)[:, :, 0].astype(np.float64)
        (x, y), _ = cam.marker_centres_px(0.0)
        x0, y0 = int(x) - 30, int(y) - 30
        m = cv2.moments((250.0 - frame[y0 : y0 + 61, x0 : x0 + 61]).astype(np.float32))
        # Rounding to 8 bits costs a little; the truth holds to ~0.01 px.
        assert x0 + m["m10"] / m["m00"] == pytest.approx(x, abs=0.015)
        assert y0 + m["m01"] / m["m00"] == pytest.approx(y, abs=0.015)
        assert m["m00"] / 250.0 == pytest.approx(math.pi * cam.radius_px**2, rel=2e-3)


def test_noise_and_lighting_drift():
    cam = camera(noise_grey=3.0, lighting_drift=0.1, drift_period_s=40.0)
    (x1, y), (x2, _) = cam.marker_centres_px(0.0)
    rows = slice(int(y) + 40, int(y) + 80)  # plain specimen, below the dots
    cols = slice(int(x1) + 60, int(x2) - 60)
    bright = cam.render(10.0)[rows, cols].astype(float)  # a quarter period: gain 1.1
    dim = cam.render(30.0)[rows, cols].astype(float)  # three quarters: gain 0.9
    assert np.std(bright) == pytest.approx(3.0, rel=0.1)
    assert np.mean(bright) == pytest.approx(190 * 1.1, abs=0.5)
    assert np.mean(dim) == pytest.approx(190 * 0.9, abs=0.5)
    # Fresh noise each frame, not the same pattern again.
    assert not np.array_equal(cam.render(1.0)[rows, cols], cam.render(1.0)[rows, cols])


def test_read_is_a_capture_paced_by_the_clock():
    clock = VirtualClock()
    cam = streaming_at_sensor_size(camera(clock=clock, fps=10.0, size=(320, 240), mm_per_px=0.2))
    stamps = []
    for _ in range(4):
        ok, frame = cam.read()
        assert ok and frame.shape == (240, 320, 3) and frame.dtype == np.uint8
        stamps.append(cam.get(cv2.CAP_PROP_POS_MSEC))
        assert clock.now() >= stamps[-1] / 1000.0  # never a frame from the future
    # Consecutive frames, 100 ms apart, none skipped.
    np.testing.assert_allclose(np.diff(stamps), 100.0)
    assert cam.get(cv2.CAP_PROP_FRAME_WIDTH) == 320 and cam.get(cv2.CAP_PROP_FPS) == 10.0
    cam.release()
    assert not cam.isOpened()
    assert cam.read() == (False, None)


def test_a_reader_behind_gets_the_queued_frames_and_loses_only_what_fell_out():
    clock = VirtualClock()  # slow enough that rendering takes no frame time
    cam = streaming_at_sensor_size(camera(clock=clock, fps=10.0, size=(160, 120), mm_per_px=0.4))
    start = cam.read()[1] is not None and cam.get(cv2.CAP_PROP_POS_MSEC)
    clock.sleep(0.25)  # 2.5 frames behind: frames 1 and 2 are queued
    stamps = [cam.read()[1] is not None and cam.get(cv2.CAP_PROP_POS_MSEC) for _ in range(3)]
    np.testing.assert_allclose(np.diff([start, *stamps]), 100.0)  # none lost
    assert clock.now() >= stamps[-1] / 1000.0  # the third one was waited for
    clock.sleep(1.0)  # 10 frames behind: only the last 4 are still queued
    now_frame = int(clock.now() * 10.0)
    cam.read()
    assert cam.get(cv2.CAP_PROP_POS_MSEC) == pytest.approx(100.0 * (now_frame - 3))


def test_written_video_reads_back_through_videocapture(tmp_path):
    cam = camera(size=(320, 240), mm_per_px=0.2, length_mm_at=lambda t: 30.0 + 10.0 * t)
    path = tmp_path / "specimen.avi"
    truth = cam.write_video(path, n_frames=12, fps=20.0)
    np.testing.assert_allclose(truth.t_s, np.arange(12) / 20.0)
    np.testing.assert_allclose(truth.length_mm, 30.0 + 10.0 * truth.t_s)
    assert truth.centres_px.shape == (12, 2, 2)
    capture = cv2.VideoCapture(str(path))
    assert capture.isOpened()
    assert capture.get(cv2.CAP_PROP_FRAME_COUNT) == 12
    assert capture.get(cv2.CAP_PROP_FPS) == 20.0
    frames = []
    while True:
        ok, frame = capture.read()
        if not ok:
            break
        frames.append(frame)
    capture.release()
    assert len(frames) == 12 and frames[0].shape == (240, 320, 3)
    # MJPG is lossy but close: the decoded frame is the rendered one within a few levels.
    difference = np.abs(frames[5].astype(int) - cam.render(5 / 20.0).astype(int))
    assert np.mean(difference) < 3.0


def test_a_marker_outside_the_frame_is_simply_not_drawn():
    cam = camera(size=(320, 240), mm_per_px=0.2, length_mm_at=lambda t: 90.0, noise_grey=0.0)
    frame = cam.render(0.0)
    assert frame.min() >= 80  # only background and specimen: no dark dot anywhere


def test_a_hidden_marker_is_not_drawn_until_shown_again():
    cam = camera(size=(320, 240), mm_per_px=0.2, noise_grey=0.0)
    (x1, y1), (x2, y2) = cam.marker_centres_px(0.0)
    cam.hide_marker(1)
    frame = cam.render(0.0)
    assert frame[round(y1), round(x1)].max() < 60 and frame[round(y2), round(x2)].min() > 150
    cam.hide_marker(1, hidden=False)
    assert cam.render(0.0)[round(y2), round(x2)].max() < 60
    with pytest.raises(ValueError, match="markers 0 and 1"):
        cam.hide_marker(2)


def test_a_lazy_frame_region_is_that_region_of_the_full_frame_bit_for_bit():
    cam = camera(length_mm_at=lambda t: 40.0 + t)
    for t in (0.0, 0.7, 3.1):
        frame = cam.frame_at(t)
        full = np.asarray(frame)
        assert frame.shape == full.shape == (720, 1280, 3) and frame.size == full.size
        (x1, y1), (x2, _) = cam.marker_centres_px(t)
        for y0, y1_, x0, x1_ in [
            (int(y1) - 40, int(y1) + 41, int(x1) - 40, int(x1) + 41),  # around a dot
            (int(y1) - 5, int(y1) + 5, int(x1) - 3, int(x2) + 90),  # across both, past the band
            (0, 720, 0, 1280),
        ]:
            np.testing.assert_array_equal(frame[y0:y1_, x0:x1_], full[y0:y1_, x0:x1_])
        np.testing.assert_array_equal(frame[10, 20], full[10, 20])  # any other index


def test_a_monochrome_camera_sees_the_grey_levels_of_the_colour_scene():
    """Independent of the grey renderer: OpenCV's BGR-to-grey of the colour frame."""
    scene = dict(noise_grey=0.0, length_mm_at=lambda t: 40.0 + t, mm_per_px=0.05)
    colour, grey = camera(**scene), camera(monochrome=True, **scene)
    for t in (0.0, 1.3):
        frame = grey.frame_at(t)
        full = np.asarray(frame)
        assert frame.shape == full.shape == (720, 1280) and frame.ndim == 2
        expected = cv2.cvtColor(colour.render(t), cv2.COLOR_BGR2GRAY).astype(int)
        assert np.max(np.abs(full.astype(int) - expected)) <= 1  # 8-bit rounding
        fix = MarkerTracker().track(frame)
        assert np.max(np.abs(centres(fix) - grey.marker_centres_px(t))) < 0.02


@pytest.mark.parametrize("monochrome", [False, True])
def test_the_noise_is_one_saturating_addition_of_the_noise_frame(monochrome):
    """The two uint8 passes (positive part added, negative part subtracted) against a
    direct signed addition, clipped once."""
    cam = camera(monochrome=monochrome, noise_grey=40.0, specimen_bgr=(250, 250, 250),
                 marker_bgr=(5, 5, 5))  # fmt: skip
    frame = cam.frame_at(0.4)
    noisy = np.asarray(frame).astype(int)
    k, dy, dx = frame.noise
    frame.noise, frame._full = None, None
    clean = np.asarray(frame).astype(int)
    plus, minus = cam._noise
    signed = plus[k].astype(int) - minus[k].astype(int)
    signed = signed[dy : dy + cam.height, dx : dx + cam.width]
    assert np.all((plus == 0) | (minus == 0))  # each pixel's noise is one or the other
    np.testing.assert_array_equal(noisy, np.clip(clean + signed, 0, 255))
    assert np.any(clean + signed > 255) and np.any(clean + signed < 0)  # both clip


def test_v4l2_streams_at_640x480_until_the_size_is_set_and_restarts_dark():
    clock = VirtualClock()
    cam = camera(clock=clock, fps=30.0, length_mm_at=lambda t: 40.0, mm_per_px=0.05)
    assert (cam.get(cv2.CAP_PROP_FRAME_WIDTH), cam.get(cv2.CAP_PROP_FRAME_HEIGHT)) == (640, 480)
    ok, frame = cam.read()
    assert ok and np.asarray(frame).shape == (480, 640, 3)  # the sensor scaled down
    brightness = [float(np.mean(np.asarray(cam.read()[1]))) for _ in range(5)]
    assert cam.set(cv2.CAP_PROP_FRAME_WIDTH, 1280) and cam.set(cv2.CAP_PROP_FRAME_HEIGHT, 720)
    assert (cam.get(cv2.CAP_PROP_FRAME_WIDTH), cam.get(cv2.CAP_PROP_FRAME_HEIGHT)) == (1280, 720)
    first = np.asarray(cam.read()[1])
    assert first.shape == (720, 1280, 3)
    # a new format restarts the stream: the auto exposure settles again from dark
    later = [float(np.mean(np.asarray(cam.read()[1]))) for _ in range(4)]
    assert float(np.mean(first)) < 0.1 * later[-1]
    assert later[-1] == pytest.approx(brightness[-1], rel=0.05)
    cam.set(cv2.CAP_PROP_FRAME_WIDTH, 1000)  # not a mode: V4L2 keeps the last valid one
    assert cam.get(cv2.CAP_PROP_FRAME_WIDTH) == 1280


def test_exposure_and_focus_are_kept_and_read_back():
    cam = camera()
    assert cam.get(cv2.CAP_PROP_AUTO_EXPOSURE) == 3.0  # auto, as a webcam opens
    assert cam.set(cv2.CAP_PROP_AUTO_EXPOSURE, 1.0) and cam.set(cv2.CAP_PROP_EXPOSURE, 50.0)
    assert cam.set(cv2.CAP_PROP_AUTOFOCUS, 0.0) and cam.set(cv2.CAP_PROP_FOCUS, 20.0)
    assert cam.get(cv2.CAP_PROP_EXPOSURE) == 50.0 and cam.get(cv2.CAP_PROP_FOCUS) == 20.0
    assert not cam.set(cv2.CAP_PROP_ZOOM, 2.0)  # a control this camera does not have


@settings(max_examples=60, deadline=None)
@example(t=0.0, box=(0, 0, 0, 0), seed=0)  # an empty region (found by hypothesis)
@given(
    t=st.floats(0.0, 30.0),
    box=st.tuples(
        st.integers(-50, 700), st.integers(-50, 1300), st.integers(0, 300), st.integers(0, 300)
    ),
    seed=st.integers(0, 5),
)
def test_any_region_a_tracker_reads_is_that_region_of_the_full_frame(t, box, seed):
    """Whatever box is read (cut by the edges, empty, across dots and band), the lazily
    rendered pixels are the full frame's (the tracker must see the frame the video
    records)."""
    cam = _shared(seed)
    frame = cam.frame_at(t)
    full = np.asarray(frame)
    y0, x0, h, w = box
    np.testing.assert_array_equal(frame[y0 : y0 + h, x0 : x0 + w], full[y0 : y0 + h, x0 : x0 + w])


@settings(max_examples=40, deadline=None)
@given(
    t0=st.floats(0.0, 30.0),
    n=st.integers(1, 9),
    size=st.tuples(st.integers(1, 200), st.integers(1, 300)),
    origins=st.lists(st.tuples(st.integers(0, 719), st.integers(0, 1279)), min_size=1, max_size=2),
    seed=st.integers(0, 5),
    hidden_from=st.integers(0, 9),
)
def test_frames_rendered_as_a_batch_are_each_frame_bit_for_bit(
    t0, n, size, origins, seed, hidden_from
):
    """A batch of frames (a run tracks its frames in batches: each frame's window on
    each marker) rendered together gives each frame's pixels exactly, whatever the
    boxes, the frames' light and noise, and a marker hidden part way through."""
    cam = _shared(seed)
    frames = []
    for k in range(n):
        cam.hide_marker(0, k >= hidden_from)
        frames.append(cam.frame_at(t0 + k / 30))
    cam.hide_marker(0, False)
    h, w = (min(size[0], min(cam.height - y0 for y0, _ in origins)),
            min(size[1], min(cam.width - x0 for _, x0 in origins)))  # fmt: skip
    boxes = [(x0, y0, x0 + w, y0 + h) for y0, x0 in origins for _ in range(n)]
    stack = SimFrame.stack_regions(frames * len(origins), boxes)
    for frame, (x0, y0, x1, y1), pixels in zip(frames * len(origins), boxes, stack, strict=True):
        np.testing.assert_array_equal(pixels, np.asarray(frame)[y0:y1, x0:x1])


@functools.cache
def _shared(seed):
    """Six cameras (seeds 0-3 in colour, 4-5 grey as seeds 0-1) that a property test's
    examples share: each makes its noise once (~0.1 s), when first asked for."""
    grey = seed >= 4
    return camera(
        length_mm_at=lambda t: 40.0 + t, seed=seed - 4 * grey, mm_per_px=0.05, monochrome=grey
    )


@pytest.mark.parametrize("monochrome", [True, False])
def test_a_scene_pickled_and_drawn_elsewhere_is_the_frame_bit_for_bit(monochrome):
    """The video encoder draws frames from their scenes in its own process: a renderer
    unpickled there (no clock, no length source) must give the pixels the tracker read,
    whatever the light, the noise's pick, a hidden marker or a streaming size."""
    import pickle

    cam = camera(size=(320, 200), mm_per_px=0.2, monochrome=monochrome, seed=None)
    renderer = pickle.loads(pickle.dumps(cam.renderer()))
    frames = [cam.frame_at(k / 30, exposure) for k, exposure in enumerate((0.3, 1.0, 1.0))]
    cam.hide_marker(1)
    frames.append(cam.frame_at(0.1))
    frames.append(cam.frame_at(0.2).resized((160, 100)))
    for frame in frames:
        _ = frame[40:80, 50:120]  # read in part first, as the tracker does
        scene = pickle.loads(pickle.dumps(frame.scene))
        assert np.array_equal(renderer(scene), np.asarray(frame))
    assert not np.array_equal(np.asarray(frames[1]), np.asarray(frames[2]))  # fresh noise


@pytest.mark.parametrize("sigma_px", [0.5, 1.0, 1.2, 2.0])
def test_the_dots_blur_is_opencvs_gaussian_blur(sigma_px):
    """The dots of a batch are blurred by matrix products (``blur_matrix``): against
    ``cv2.GaussianBlur`` on the same coverage, any size down to one pixel (a dot cut by
    the frame's edge), its reflecting border included."""
    rng = np.random.default_rng(1)
    for height, width in [(1, 1), (2, 5), (3, 23), (13, 9), (27, 27), (40, 3)]:
        coverage = rng.random((height, width)).astype(np.float32)
        blurred = blur_matrix(height, sigma_px) @ coverage @ blur_matrix(width, sigma_px).T
        expected = cv2.GaussianBlur(coverage, (0, 0), sigma_px)
        np.testing.assert_allclose(blurred, expected, atol=1e-6)
