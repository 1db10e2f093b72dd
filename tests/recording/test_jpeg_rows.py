"""Motion-JPEG frames assembled from cached rows (labrig.recording.jpeg_rows): byte for byte what
libjpeg writes for the whole frame, decoded to the pixels of a frame encoded without
restarts; and the simulated camera's row keys are equal only where the pixels are."""

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from labrig.recording.jpeg_rows import RowJpeg
from labrig.recording.video import JPEG_QUALITY
from labrig.sim.camera import SimCamera
from labrig.time.virtual import VirtualClock


def plain_jpeg_pixels(image):
    """The frame as a JPEG without restarts decodes to: what the video held before."""
    data = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])[1]
    return cv2.imdecode(data, cv2.IMREAD_UNCHANGED)


@settings(max_examples=30, deadline=None)
@given(
    width=st.integers(1, 90),
    height=st.integers(1, 70),
    colour=st.booleans(),
    n_blocks=st.integers(1, 3),
    seed=st.integers(0, 2**32 - 1),
)
def test_frames_of_repeated_rows_are_libjpegs_own_encoding(width, height, colour, n_blocks, seed):
    """Frames built from a few kinds of rows (key: the kind), any size (rows cut short
    at the bottom, MCUs at the right edge, 4:2:0 colour's 16-pixel rows): each assembled
    frame equals cv2.imencode's of the whole frame, and decodes as the frame without
    restarts does; rows are encoded once per kind, a None key every time."""
    rng = np.random.default_rng(seed)
    jpeg = RowJpeg(width, height, colour, JPEG_QUALITY)
    shape = (jpeg.row_px, width, 3) if colour else (jpeg.row_px, width)
    kinds = rng.integers(0, 256, (n_blocks, *shape), dtype=np.uint8)
    encoded, kinds_seen = 0, set()
    for _ in range(3):  # batches of frames
        images, keys = [], []
        for _ in range(3):
            choice = rng.integers(-1, n_blocks, jpeg.n_rows)  # -1: a row of its own (None)
            rows = [kinds[c] if c >= 0 else rng.integers(0, 256, shape, dtype=np.uint8)
                    for c in choice]  # fmt: skip
            images.append(np.concatenate(rows)[:height])
            keys.append([None if c < 0 else (int(c), min(jpeg.row_px, height - i * jpeg.row_px))
                         for i, c in enumerate(choice)])  # fmt: skip
            encoded += keys[-1].count(None) + len(set(keys[-1]) - {None} - kinds_seen)
            kinds_seen |= set(keys[-1]) - {None}
        data = jpeg.frames(
            keys, lambda spans, images=images: [images[f][y0:y1] for f, y0, y1 in spans]
        )
        for image, frame_data in zip(images, data, strict=True):
            assert frame_data == jpeg.encode(image)
            decoded = cv2.imdecode(np.frombuffer(frame_data, np.uint8), cv2.IMREAD_UNCHANGED)
            np.testing.assert_array_equal(decoded, plain_jpeg_pixels(image))
    assert jpeg.n_encoded_rows == encoded


@pytest.mark.parametrize(
    ("size", "monochrome"), [((640, 360), True), ((203, 117), True), ((320, 200), False)]
)
def test_a_simulated_runs_frames_are_assembled_exactly_and_mostly_copied(size, monochrome):
    """Frames of a specimen that lengthens under a drifting light, the first ones dark
    while the exposure settles, one marker hidden for a while, the other leaving the
    frame: each assembled from the camera's row keys equals libjpeg's encoding of the
    whole frame; rows of equal keys have equal pixels (the keys checked against the
    pixels themselves); each key's row is encoded once."""
    cam = SimCamera(
        VirtualClock(),
        lambda t: 30.0 + 40.0 * t,
        size=size,
        mm_per_px=0.1,
        monochrome=monochrome,
        seed=3,
    )
    renderer = cam.renderer()
    jpeg = RowJpeg(size[0], size[1], not monochrome, JPEG_QUALITY)
    seen = {}
    n_unique = 0
    for batch in range(4):  # a second of frames at a time, as a run hands them over
        frames = []
        for k in range(30 * batch, 30 * batch + 30):
            t_s = k / 30
            cam.hide_marker(1, 1.0 <= t_s < 1.5)
            exposure = (0.0, 0.3, 0.7)[k] if k < 3 else 1.0
            frames.append(renderer.frame(cam.frame_at(t_s, exposure).scene))
        keys = [renderer.row_keys(frame, jpeg.row_px) for frame in frames]
        data = jpeg.frames(keys, lambda spans, frames=frames: renderer.render_rows(frames, spans))
        for frame, frame_keys, frame_data in zip(frames, keys, data, strict=True):
            whole = np.asarray(cam.scene_frame(frame.scene))
            assert frame_data == jpeg.encode(whole)
            for i, key in enumerate(frame_keys):
                rows = whole[i * jpeg.row_px : (i + 1) * jpeg.row_px]
                if key is not None:
                    np.testing.assert_array_equal(seen.setdefault(key, rows), rows)
            n_unique += frame_keys.count(None)
    assert jpeg.n_encoded_rows == n_unique + len(seen)  # each key's row encoded once


def test_a_scaled_frame_has_no_row_keys():
    """A frame the camera's scaler resized is drawn whole: its rows are not known."""
    cam = SimCamera(VirtualClock(), lambda t: 40.0, size=(320, 200), monochrome=True)
    frame = cam.frame_at(0.1).resized((160, 100))
    assert cam.renderer().row_keys(frame, 8) is None
