"""The marker tracker in its own process: the same fixes as in the caller's process, a
clear error when the process fails, and no process left behind."""

import os
import signal

import numpy as np
import pytest

from labrig.drivers.markers import MarkerTracker
from labrig.drivers.tracker_process import TrackerProcess
from labrig.errors import DeviceError
from labrig.sim.camera import SimCamera


def frames_of_a_run():
    """1.5 s of a 30 fps camera in batches of 9: the specimen stretching, snapping
    (a jump the batched search cannot follow), one marker hidden for a while (a full
    search when it is back), and both markers leaving the frame at the end."""

    def length_mm_at(t_s):
        snap_mm = 6.0 if t_s >= 0.55 else 0.0
        out_mm = 40.0 if t_s >= 1.35 else 0.0
        return 25.0 + 4.0 * t_s + snap_mm + out_mm

    camera = SimCamera(None, length_mm_at, size=(320, 200), mm_per_px=0.2, noise_grey=3.0)
    frames = []
    for k in range(45):
        camera.hide_marker(0, 0.8 <= k / 30 < 1.0)
        frames.append(camera.frame_at(k / 30))
    return [frames[i : i + 9] for i in range(0, len(frames), 9)]


def as_array(fixes):
    return np.array([(f.x1_px, f.y1_px, f.x2_px, f.y2_px, f.ok) for f in fixes], dtype=float)


@pytest.mark.parametrize("pixels", [False, True], ids=["scenes", "pixels"])
def test_the_process_gives_the_fixes_of_the_callers_own_tracker(pixels):
    """Bit for bit, batch after batch (the tracker's state carries over in the child),
    whether the frames go as their scenes (simulated) or as their pixels (a camera's)."""
    batches = frames_of_a_run()
    if pixels:
        batches = [[np.asarray(frame) for frame in batch] for batch in batches]
    here = MarkerTracker()
    expected = [here.track_many(batch) for batch in batches]
    process = TrackerProcess(MarkerTracker())
    try:
        got = []
        process.submit(batches[0])
        for batch in batches[1:]:  # as a run does: hand the next over, then collect
            process.submit(batch)
            got.append(process.collect())
        got.append(process.collect())
        assert process.pending == 0
    finally:
        process.close()
    statuses = [f.status for batch in got for f in batch]
    assert {"ok", "lost"} <= set(statuses)  # the run has both
    for want, fixes in zip(expected, got, strict=True):
        assert [f.status for f in fixes] == [f.status for f in want]
        np.testing.assert_array_equal(as_array(fixes), as_array(want))


def test_a_tracking_error_is_reported_and_the_process_goes_on():
    process = TrackerProcess(MarkerTracker())
    try:
        process.submit([np.zeros((0, 0), dtype=np.uint8)])
        with pytest.raises(DeviceError, match=r"marker tracker failed: InputError.*frame is empty"):
            process.collect()
        process.submit(frames_of_a_run()[0])
        assert all(fix.ok for fix in process.collect())
    finally:
        process.close()


def test_a_process_that_died_is_a_device_error_not_a_hang():
    process = TrackerProcess(MarkerTracker(), "camera 0 tracker")
    os.kill(process._child.pid, signal.SIGKILL)
    process._child.wait()
    with pytest.raises(DeviceError, match="camera 0 tracker: its process ended"):
        process.submit(frames_of_a_run()[0])
        process.collect()
    with pytest.raises(DeviceError, match="camera 0 tracker: closed"):
        process.submit(frames_of_a_run()[0])


def test_close_with_a_batch_in_hand_ends_the_process():
    process = TrackerProcess(MarkerTracker())
    child = process._child
    process.submit(frames_of_a_run()[0])
    process.close()
    assert child.returncode == 0
    process.close()  # twice is harmless


def test_the_child_runs_below_the_callers_priority():
    process = TrackerProcess(MarkerTracker())
    try:
        process.submit(frames_of_a_run()[0])
        process.collect()  # the child has set itself up by its first answer
        assert os.getpriority(os.PRIO_PROCESS, process._child.pid) > os.getpriority(
            os.PRIO_PROCESS, 0
        )
    finally:
        process.close()
