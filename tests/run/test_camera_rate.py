"""The camera's real frame rate is stored beside its nominal one: a webcam's auto
exposure in dim light lowers the rate while the camera still reports the nominal one.
The run's length series, one row a frame, counts the frames independently."""

import numpy as np
from support.simrig import run_sim, short_protocol

from labrig.recording.run_reader import open_run, read_log


def dim_light(rig):
    rig.simulation.camera.dim_light_fps = 3.0


def test_the_measured_frame_rate_is_stored_beside_the_nominal_one(tmp_path):
    outcome = run_sim(tmp_path, short_protocol(camera_fps=5), prepare=dim_light)
    assert outcome.result.status == "complete"
    with open_run(outcome.path) as run:
        camera = run["entry/camera"]
        assert camera["nominal_fps"][()] == 5.0
        assert camera["measured_fps"].attrs["units"] == "Hz"
        measured_fps = camera["measured_fps"][()]
        times = np.concatenate([read_log(run, rep, "length").time_s for rep in (1, 2)])
    from_the_file = (len(times) - 1) / (times[-1] - times[0])
    assert np.isclose(measured_fps, from_the_file, rtol=0.01)
    assert np.isclose(measured_fps, 3.0, rtol=0.01)
