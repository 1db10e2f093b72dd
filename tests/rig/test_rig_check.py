"""``labrig rig check``: the simulated rig passes; each fault a technician meets is
found, named, and exits 2; the check moves nothing."""

from __future__ import annotations

import re

import numpy as np
import pytest

from labrig.cli import main
from labrig.config.rig_file import PressureConfig, PumpConfig
from labrig.rig import check_sim as rig_check_sim
from labrig.rig.check import check_pressure, check_pump
from labrig.sim.pump import PumpEmulator
from labrig.time.clock import RealClock

BENCH = "protocols/rigs/bench.yaml"
# what the check may send: queries, NVRAM writes off, and the stop the driver sends
# after a reply that never came (a stop moves nothing)
READ_ONLY = {"ver", "version", "poll off", "nvram off", "metrics", "diameter", "svolume",
             "irate lim", "wrate lim", "force", "status", "ivolume", "wvolume", "stop",
             "mode"}  # fmt: skip


def rig_check(capsys, *args: str) -> tuple[int, dict[str, str]]:
    with pytest.raises(SystemExit) as exit_info:
        main(["rig", "check", *args])
    out = capsys.readouterr().out
    lines = {line.split()[0]: line for line in out.splitlines() if line.strip()}
    return exit_info.value.code, lines


def test_the_simulated_rig_passes(capsys):
    code, lines = rig_check(capsys, BENCH, "--sim")
    assert code == 0, lines
    assert " ok " in lines["pump"] and "PHD ULTRA" in lines["pump"]
    assert "syringe 27.60 mm, 50 mL" in lines["pump"] and "infuse" in lines["pump"]
    assert "supply 5.000 V on Dev1/ai1" in lines["pressure"]
    assert "+0.80 kPa" in lines["pressure"]  # the simulated sensor's offset error
    assert "640x360" in lines["camera"] and "both markers found" in lines["camera"]
    assert lines["rig"] == "rig check: 3 of 3 devices ok"


@pytest.mark.parametrize(
    ("fault", "device", "words"),
    [
        ("no-reply", "pump", ["no reply", "switched on, the cable"]),
        ("wrong-address", "pump", ["no reply at address 3", "answers at address 0",
                                   "set pump.address: 0"]),
        ("daq-missing", "pressure", ["-200220", "a DAQ named Dev2", "USB cable"]),
        ("marker-hidden", "camera", ["markers lost", "both markers in view"]),
        ("sensor-offset", "pressure", ["+4.00 kPa", "0 +- 2.5 kPa", "open to atmosphere"]),
    ],
)  # fmt: skip
def test_each_fault_is_named_and_exits_2(capsys, monkeypatch, fault, device, words):
    # the replies a pump fault leaves out are awaited 0.2 s, not 2 s each (8 of them):
    # silence is silence; the search for the pump at another address keeps its 2 s
    # where an answer is expected (wrong-address)
    monkeypatch.setattr(rig_check_sim, "SIM_REPLY_TIMEOUT_S", 0.2)
    if fault == "no-reply":
        monkeypatch.setattr(rig_check_sim, "SIM_SEARCH_TIMEOUT_S", 0.2)
    code, lines = rig_check(capsys, BENCH, "--sim", "--fault", fault)
    assert code == 2
    assert " FAIL " in lines[device]
    for word in words:
        assert word in lines[device], lines[device]
    others = [name for name in ("pump", "pressure", "camera") if name != device]
    assert all(" ok " in lines[name] for name in others), lines
    assert lines["rig"].endswith(f"failed: {device}")


def test_the_pump_check_finds_the_address_and_moves_nothing():
    clock = RealClock()
    with PumpEmulator(clock, address=5) as emulator:
        # no reply at address 2 is awaited 0.2 s per command; the search keeps 0.5 s
        wrong = check_pump(
            PumpConfig(port=emulator.port, address=2), clock, timeout_s=0.2, search_timeout_s=0.5
        )
        assert not wrong.ok and "answers at address 5" in wrong.found
        right = check_pump(PumpConfig(port=emulator.port, address=5), clock)
        assert right.ok, right.line()
        assert "at address 5" in right.found
        sent = {re.sub(r"^\d{1,2}:?", "", line) for line in emulator.received}
        assert sent <= READ_ONLY, sent - READ_ONLY
        assert emulator.net_volume_ml(clock.now()) == 0.0


def test_the_pump_check_awaits_replies_as_long_as_the_rig_file_says():
    """A pump that takes 0.6 s to answer passes with the rig file's 1.5 s, as a run would."""
    clock = RealClock()
    with PumpEmulator(clock) as emulator:
        emulator.slow_replies(0.6)
        check = check_pump(PumpConfig(port=emulator.port, reply_timeout_s=1.5), clock)
        assert check.ok, check.line()


def test_the_pump_check_on_a_pump_left_by_other_software_says_what_it_can_do():
    # poll on, only the manual's address form, infuse-only, no NVRAM command known
    clock = RealClock()
    options = {"poll_mode": "on", "strict_address_form": "none", "infuse_only": True}
    with PumpEmulator(clock, memory_command=None, **options) as emulator:
        check = check_pump(PumpConfig(port=emulator.port, force_limit_pct=30), clock)
        assert check.ok, check.line()
        assert "(none form)" in check.found
        assert "no withdraw (infuse-only pump)" in check.found
        # 100 % of 75 lbf over the 26.7 mm plunger: 595.8 kPa (docs/reference/pump.md)
        assert "force limit 100 % (stalls above 596 kPa; a run sets 30 %)" in check.found
        assert "its memory is written at every setting change" in check.found
        sent = {re.sub(r"^\d{1,2}:?", "", line) for line in emulator.received}
        assert sent <= READ_ONLY | {"nvram none", "rsave off"}, sent - READ_ONLY
        assert not any(line.startswith("w") for line in sent)  # metrics said infuse-only


def test_a_pump_found_infusing_fails_the_check_and_is_left_running():
    """The check moves nothing, a stop included: a moving pump is named, not touched."""
    clock = RealClock()
    with PumpEmulator(clock) as emulator:
        emulator.keypad("irate 1.2 ml/min", "irun")
        check = check_pump(PumpConfig(port=emulator.port), clock)
        assert not check.ok
        assert "; infusing" in check.found
        assert f"labrig pump --port {emulator.port} stop" in check.line()
        sent = {re.sub(r"^\d{1,2}:?", "", line) for line in emulator.received}
        assert "stop" not in sent and not any(s.startswith("load") for s in sent), sent
        assert emulator.net_volume_ml(clock.now()) > 0


def test_a_missing_ni_daqmx_driver_is_named():
    import nidaqmx

    try:
        nidaqmx.system.System.local().driver_version  # noqa: B018
    except Exception:
        pass
    else:
        pytest.skip("NI-DAQmx is installed on this machine")
    check = check_pressure(PressureConfig(), RealClock())
    assert not check.ok
    assert "NI-DAQmx" in check.found and "installdriver" in check.check


def test_a_bad_rig_file_is_one_line(tmp_path, capsys):
    bad = tmp_path / "rig.yaml"
    bad.write_text("pump: {port: /dev/ttyUSB0, address: 120}\n")
    with pytest.raises(SystemExit) as exit_info:
        main(["rig", "check", str(bad)])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(bad) in err and "address" in err
    with pytest.raises(SystemExit) as exit_info:
        main(["rig", "check"])
    assert exit_info.value.code == 2


def test_a_bench_rig_with_a_video_and_a_pump_on_a_port(tmp_path):
    """The bench path end to end: a rig file whose pump is on a serial device (the
    emulator's pty) and whose camera is a video file read with a reference distance;
    NI-DAQmx is absent here, and the check says so without stopping the others."""
    from labrig.config.rig_file import RigConfig
    from labrig.rig.check import check_rig
    from labrig.sim.camera import SimCamera

    video = tmp_path / "markers.avi"
    truth = SimCamera(RealClock(), lambda t: 60.0, mm_per_px=0.08).write_video(
        video, n_frames=5, fps=10.0
    )
    with PumpEmulator(RealClock()) as emulator:
        config = RigConfig(
            pump={"port": emulator.port},
            camera={"source": str(video), "reference_distance_mm": 60.0},
        )
        checks = {c.device: c for c in check_rig(config)}
    assert checks["pump"].ok, checks["pump"].line()
    camera = checks["camera"]
    assert camera.ok, camera.line()
    distance_px = float(np.hypot(*np.diff(truth.centres_px[0], axis=0)[0]))
    found = re.search(r"([\d.]+) px = 60 mm \(reference: ([\d.]+) mm/px\)", camera.found)
    assert found, camera.found
    assert abs(float(found[1]) - distance_px) < 0.2  # the tracker's sub-pixel centres
    assert abs(float(found[2]) - 0.08) < 1e-4
    assert "10 fps" in camera.found and "1280x720" in camera.found


@pytest.mark.parametrize("seed", [0, 199])  # 199: a mean of 5.001 V
def test_the_pressure_check_shows_the_range_daqmx_uses(seed):
    # The recommended wiring asks 0-5 V in RSE; a USB-6009 digitises +-10 V at 13 bits,
    # so the 5.0 V supply on ai1 is far from the top of the range.
    from labrig.sim.daq import SimAnalogMultiChannelReader, SimDaqTask
    from labrig.time.virtual import VirtualClock

    clock = VirtualClock()
    check = check_pressure(
        PressureConfig(min_v=0.0, max_v=5.0, supply_channel="Dev1/ai1"),
        clock,
        task_factory=lambda: SimDaqTask(
            clock, lambda t: np.zeros(np.shape(t)), supply_v=5.0, seed=seed
        ),
        reader_factory=SimAnalogMultiChannelReader,
    )
    assert check.ok, check.line()
    assert "Dev1/ai0 (RSE, -10 to 10 V at 13 bits, 1000 S/s)" in check.found
    # the mean of 100 noisy samples: 4.999-5.001 V (it read 4.999 or 5.001 for 13 of
    # 300 seeds; the test once failed on an unseeded task), within one 13-bit step
    supply_v = float(re.search(r"supply ([0-9.]+) V on Dev1/ai1", check.found)[1])
    assert abs(supply_v - 5.0) <= 20.0 / 2**13


def test_an_unreachable_daq_gets_cable_advice_not_wiring():
    """DAQmx -201003 (the device cannot be accessed) is a cable or power matter."""
    from labrig.sim.daq import SimAnalogMultiChannelReader, SimDaqTask
    from labrig.time.virtual import VirtualClock

    clock = VirtualClock()

    def unplugged():
        task = SimDaqTask(clock, lambda t: np.zeros(np.shape(t)), seed=0)
        task.fail("vanish", at_s=0.0)
        return task

    check = check_pressure(
        PressureConfig(), clock, task_factory=unplugged, reader_factory=SimAnalogMultiChannelReader
    )
    assert not check.ok
    assert "DAQmx error -201003" in check.found
    assert "USB cable" in check.check and "nilsdev" in check.check
    assert "terminal" not in check.check


@pytest.mark.parametrize(("noise_kpa", "quiet"), [(0.05, False), (0.15, False), (0.003, True)])
def test_the_pressure_check_reports_the_spread_of_codes_at_rest(noise_kpa, quiet):
    """The ADC codes behind one second at atmosphere: their std in LSB is the sensor's
    noise in LSB with the quantisation's 1/12 LSB^2 added (for noise that dithers); a
    sensor too quiet to dither sits on one or two codes, and the line says so."""
    from labrig.sim.daq import SimAnalogMultiChannelReader, SimDaqTask
    from labrig.time.virtual import VirtualClock

    clock = VirtualClock()
    check = check_pressure(
        PressureConfig(),
        clock,
        task_factory=lambda: SimDaqTask(
            clock, lambda t: np.zeros(np.shape(t)), noise_kpa=noise_kpa, seed=3
        ),
        reader_factory=SimAnalogMultiChannelReader,
    )
    assert check.ok, check.line()
    found = re.search(r"codes at rest: std ([0-9.]+) LSB over (\d+) codes", check.found)
    std_lsb, n_codes = float(found[1]), int(found[2])
    lsb_kpa = 20.0 / 2**13 / (0.009 * 5.0)  # 13-bit RSE over +-10 V, at 45 mV/kPa
    if quiet:
        assert std_lsb < 0.3 and n_codes <= 2
        assert "too quiet to dither the ADC" in check.found
    else:
        expected = np.hypot(noise_kpa / lsb_kpa, np.sqrt(1 / 12))
        assert std_lsb == pytest.approx(expected, rel=0.1)
        assert "too quiet" not in check.found


def test_the_camera_check_shows_the_rate_the_frames_really_come_at():
    """CAP_PROP_FPS says 30 while auto exposure in dim light gives 12: the check reads
    enough frames for their stamps to tell, and says what to do."""
    from labrig.drivers.camera import CameraLength, CameraSettings, FrameSource
    from labrig.rig.check import check_camera
    from labrig.sim.camera import SimCamera
    from labrig.time.virtual import VirtualClock

    clock = VirtualClock()
    with clock.participate():
        for dim_light_fps, shown in ((None, "30.0 measured)"), (12.0, "12.0 measured: short")):
            cam = SimCamera(
                clock, lambda t: 40.0, size=(320, 240), mm_per_px=0.2, dim_light_fps=dim_light_fps
            )
            frames = FrameSource.live(cam, clock, "simulated camera")
            frames.configure(CameraSettings(width=320, height=240, fps=30.0))
            length = CameraLength(frames, mm_per_px=0.2)
            check = check_camera(length, None, "simulated camera")
            length.close()
            assert check.ok, check.line()
            assert f"320x240, 30 fps MJPG ({shown}" in check.found
    assert "add light or give camera.exposure" in check.found
