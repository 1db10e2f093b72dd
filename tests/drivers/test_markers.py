"""MarkerTracker on rendered frames: sub-pixel accuracy, identity, lost and merged markers."""

import math

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from labrig.drivers.markers import MarkerFix, MarkerTracker, _median, mm_per_px_from_reference
from labrig.errors import InputError
from labrig.sim.camera import SimCamera
from labrig.time.virtual import VirtualClock


def camera(length_mm_at=lambda t: 40.0 + 3.0 * math.sin(t), **kwargs):
    return SimCamera(VirtualClock(), length_mm_at, **kwargs)


def centres(fix: MarkerFix) -> np.ndarray:
    return np.array([[fix.x1_px, fix.y1_px], [fix.x2_px, fix.y2_px]])


def test_subpixel_centres_and_length_on_rendered_frames():
    """Blur, noise and lighting drift at 1280x720 and 0.05 mm/px: within 0.1 px, 0.05 mm."""
    cam = camera(lighting_drift=0.15, drift_period_s=4.0, noise_grey=3.0, blur_px=1.2)
    tracker = MarkerTracker()
    t_s = np.linspace(0.0, 6.0, 40)
    errors_px, errors_mm = [], []
    for t in t_s:
        fix = tracker.track(cam.render(t))
        assert fix.ok and fix.status == "ok"
        errors_px.append(centres(fix) - cam.marker_centres_px(t))
        errors_mm.append(fix.distance_px * cam.mm_per_px - cam.length_mm_at(t))
    assert np.max(np.abs(errors_px)) < 0.1
    assert np.max(np.abs(errors_mm)) < 0.05
    assert tracker.full_searches == 1  # the first frame; the rest inside the windows


def test_intensity_weighting_beats_a_binary_centroid():
    """The reason for the weighted moments: compare with a binary blob centroid."""
    cam = camera(noise_grey=0.0, lighting_drift=0.0)
    rng = np.random.default_rng(2)
    weighted, binary = [], []
    for t in rng.uniform(0, 10, 15):
        frame = cam.render(t)
        truth = cam.marker_centres_px(t)
        weighted.append(centres(MarkerTracker().track(frame)) - truth)
        grey = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
        mask = cv2.threshold(grey, 0, 255, cv2.THRESH_BINARY_INV | cv2.THRESH_OTSU)[1]
        _, _, stats, cents = cv2.connectedComponentsWithStats(mask)
        dots = cents[np.argsort(stats[:, 4])[-3:-1]]  # the two dots; the largest is background
        dots = dots[np.argsort(dots[:, 0])]
        binary.append(dots - truth)
    assert np.sqrt(np.mean(np.square(weighted))) < 0.5 * np.sqrt(np.mean(np.square(binary)))


def test_identity_is_kept_when_the_pair_turns_past_vertical():
    """Left-to-right order flips as the pair rotates; nearest neighbour must not."""
    tracker = MarkerTracker()
    first = None
    for angle_deg in range(0, 181, 10):
        a = math.radians(angle_deg)
        frame = np.full((480, 640, 3), 200, np.uint8)
        p1 = (320 - 150 * math.cos(a), 240 - 150 * math.sin(a))
        p2 = (320 + 150 * math.cos(a), 240 + 150 * math.sin(a))
        for x, y in (p1, p2):
            cv2.circle(
                frame, (round(x * 16), round(y * 16)), 12 * 16, (30, 30, 30), -1, cv2.LINE_AA, 4
            )
        fix = tracker.track(frame)
        assert fix.ok
        first = first or p1
        assert (fix.x1_px, fix.y1_px) == pytest.approx(p1, abs=0.3)
        assert (fix.x2_px, fix.y2_px) == pytest.approx(p2, abs=0.3)
    assert first[0] < 320 < p1[0]  # marker 1 went from the left to the right


def test_a_lost_marker_gives_nan_then_is_found_again():
    cam = camera(length_mm_at=lambda t: 40.0)
    tracker = MarkerTracker()
    assert tracker.track(cam.render(0.0)).ok
    hidden = cam.render(0.1)
    (x2, y2) = cam.marker_centres_px(0.1)[1]
    cv2.circle(hidden, (round(x2), round(y2)), 25, (190, 190, 190), -1)
    fix = tracker.track(hidden)
    assert not fix.ok and fix.status == "lost"
    assert all(math.isnan(v) for v in (fix.x1_px, fix.y1_px, fix.x2_px, fix.y2_px))
    assert math.isnan(fix.distance_px)
    assert tracker.full_searches == 2  # the window failed, so the whole frame was searched
    fix = tracker.track(cam.render(0.2))
    assert fix.ok
    assert centres(fix) == pytest.approx(cam.marker_centres_px(0.2), abs=0.1)
    assert tracker.full_searches == 2  # back where it was last seen: found in its window


def test_a_marker_that_reappears_far_away_is_found_by_a_full_search():
    tracker = MarkerTracker()
    assert tracker.track(camera(length_mm_at=lambda t: 40.0).render(0.0)).ok
    cam = camera(length_mm_at=lambda t: 50.0)  # each marker 100 px from its last position
    fix = tracker.track(cam.render(0.0))
    assert fix.ok
    assert centres(fix) == pytest.approx(cam.marker_centres_px(0.0), abs=0.1)
    assert tracker.full_searches == 2


def test_markers_that_merge_give_nan_never_a_wrong_length():
    lengths = np.concatenate([np.linspace(6.0, 1.0, 26), np.linspace(1.0, 6.0, 26)])
    cam = camera(length_mm_at=lambda t: float(lengths[round(t)]), size=(640, 360))
    tracker = MarkerTracker()
    statuses = []
    for k, length_mm in enumerate(lengths):
        fix = tracker.track(cam.render(float(k)))
        statuses.append(fix.status)
        if fix.ok:
            assert fix.distance_px * cam.mm_per_px == pytest.approx(length_mm, abs=0.01)
        else:
            assert math.isnan(fix.distance_px)
    assert "merged" in statuses
    # Apart again (6 mm = 4 diameters), both are tracked again.
    assert statuses[-5:] == ["ok"] * 5


def one_by_one_and_batched(make_frames, batch):
    """Fixes of the frames ``make_frames()`` gives, tracked frame by frame and in
    batches of ``batch`` (each from frames made anew: a frame renders what is read
    once); and the batched tracker."""
    tracker = MarkerTracker()
    single = [tracker.track(frame) for frame in make_frames()]
    tracker = MarkerTracker()
    frames = make_frames()
    batched = [
        fix
        for i in range(0, len(frames), batch)
        for fix in tracker.track_many(frames[i : i + batch])
    ]
    return single, batched, tracker


@pytest.mark.parametrize("monochrome", [True, False])
def test_a_batch_of_held_markers_is_measured_as_frame_by_frame(monochrome):
    """``track_many`` on batches of lazily rendered frames: every fix within 0.05 px of
    the truth and of ``track`` on the same frames; the windows of the held markers are
    searched all at once (no full search after the first frame)."""

    def frames():
        cam = camera(length_mm_at=lambda t: 30.0 + 4.0 * math.sin(t / 3), size=(640, 360),
                     mm_per_px=0.1, noise_grey=3.0, monochrome=monochrome)  # fmt: skip
        return [cam.frame_at(k / 30) for k in range(180)]

    single, batched, batched_tracker = one_by_one_and_batched(frames, 6)
    scene = frames()[0].camera
    truth = np.array([scene.marker_centres_px(k / 30) for k in range(180)])
    assert all(f.ok for f in batched)
    got = np.array([centres(f) for f in batched])
    assert np.max(np.abs(got - truth)) < 0.05
    assert np.max(np.abs(got - np.array([centres(f) for f in single]))) < 0.05
    assert batched_tracker.full_searches == 1


def test_a_batch_goes_frame_by_frame_from_a_lost_or_merged_marker():
    """Markers that merge and part again, and one that is hidden, inside batches: the
    same statuses, frame by frame, as ``track`` gives; the lengths where both are seen."""
    lengths = np.concatenate([np.linspace(8.0, 1.0, 30), np.linspace(1.0, 8.0, 30), [8.0] * 30])
    mm_per_px = 0.05

    def frames():
        cam = camera(length_mm_at=lambda t: float(lengths[round(t * 30)]), size=(640, 360),
                     mm_per_px=mm_per_px)  # fmt: skip
        made = []
        for k in range(len(lengths)):
            cam.hide_marker(1, 70 <= k < 76)
            made.append(cam.frame_at(k / 30))
        return made

    single, batched, _ = one_by_one_and_batched(frames, 7)
    assert [f.status for f in batched] == [f.status for f in single]
    assert {"merged", "lost", "ok"} <= {f.status for f in batched}
    for k, fix in enumerate(batched):
        if fix.ok:
            assert fix.distance_px * mm_per_px == pytest.approx(lengths[k], abs=0.01)


def test_a_batch_of_plain_image_arrays_is_tracked_too():
    """Frames from a real camera are arrays: their windows are cut and stacked."""
    cam = camera(size=(640, 360), mm_per_px=0.1)
    images = [cam.render(k / 30) for k in range(12)]
    tracker = MarkerTracker()
    fixes = tracker.track_many(images[:1]) + tracker.track_many(images[1:])
    for k, fix in enumerate(fixes):
        assert fix.ok
        assert centres(fix) == pytest.approx(cam.marker_centres_px(k / 30), abs=0.05)
    assert tracker.full_searches == 1


def test_three_look_alike_dots_are_ambiguous_not_a_guess():
    frame = np.full((360, 640, 3), 200, np.uint8)
    for x in (150, 320, 490):
        cv2.circle(frame, (x, 180), 14, (30, 30, 30), -1, cv2.LINE_AA)
    fix = MarkerTracker().track(frame)
    assert not fix.ok and fix.status == "ambiguous"


def test_an_empty_scene_is_lost():
    fix = MarkerTracker().track(np.full((120, 160, 3), 180, np.uint8))
    assert not fix.ok and fix.status == "lost"


def test_coloured_markers_with_an_hsv_range():
    cam = camera(marker_bgr=(30, 30, 200), specimen_bgr=(215, 215, 215), noise_grey=2.0)
    tracker = MarkerTracker(hsv_range=((0, 80, 60), (10, 255, 255)))
    for t in (0.0, 0.5, 1.0):
        fix = tracker.track(cam.render(t))
        assert fix.ok
        assert centres(fix) == pytest.approx(cam.marker_centres_px(t), abs=0.1)


def test_a_fixed_grey_threshold_and_a_grey_frame():
    cam = camera(noise_grey=1.0)
    frame = cv2.cvtColor(cam.render(0.0), cv2.COLOR_BGR2GRAY)
    fix = MarkerTracker(threshold=120).track(frame)
    assert fix.ok
    assert centres(fix) == pytest.approx(cam.marker_centres_px(0.0), abs=0.1)


def test_scale_from_a_reference_frame():
    cam = camera(length_mm_at=lambda t: 42.0, mm_per_px=0.05)
    fix = MarkerTracker().track(cam.render(0.0))
    assert mm_per_px_from_reference(fix, 42.0) == pytest.approx(0.05, rel=1e-4)
    with pytest.raises(InputError, match=r"reference frame.*lost"):
        mm_per_px_from_reference(MarkerTracker().track(np.full((50, 50), 200, np.uint8)), 42.0)
    with pytest.raises(InputError, match="must be > 0 mm"):
        mm_per_px_from_reference(fix, 0.0)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"threshold": 300}, "grey level"),
        ({"hsv_range": ((0, 0), (1, 1))}, "h, s, v"),
        ({"min_area_px": 0}, "area limits"),
    ],
)
def test_bad_settings_are_input_errors(kwargs, match):
    with pytest.raises(InputError, match=match):
        MarkerTracker(**kwargs)


def test_a_frame_that_is_not_an_image_is_an_input_error():
    with pytest.raises(InputError, match="not an image"):
        MarkerTracker().track(np.zeros((0, 0, 3), np.uint8))
    with pytest.raises(InputError, match="need colour frames"):
        MarkerTracker(hsv_range=((0, 80, 60), (10, 255, 255))).track(np.zeros((9, 9), np.uint8))


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(-300.0, 300.0, width=32), min_size=1, max_size=400))
def test_the_ring_median_is_numpys(values):
    """The centroid window's background level: the fast median against np.median."""
    ring = np.array(values, dtype=np.float32)
    assert _median(ring) == pytest.approx(float(np.median(ring)), rel=1e-6, abs=1e-4)
