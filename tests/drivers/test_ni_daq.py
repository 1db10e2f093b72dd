"""NiDaqPressure, the real driver, against SimDaqTask: blocks, timestamps, zeroing, errors."""

import ctypes.util
import subprocess
import sys

import nidaqmx
import nidaqmx.errors
import nidaqmx.stream_readers
import numpy as np
import pytest
from nidaqmx.constants import TaskMode
from nidaqmx.error_codes import DAQmxErrors

from labrig.drivers import mpx5100
from labrig.drivers.ni_daq import (
    DRIFT_CHECK_S,
    DaqConfigError,
    DaqNotInstalledError,
    DaqOverflowError,
    DaqTimeoutError,
    DaqUnreachableError,
    NiDaqPressure,
)
from labrig.errors import DeviceError, InputError
from labrig.rig.devices import PressureSource
from labrig.sim.daq import SimAnalogMultiChannelReader, SimDaqTask, quantise
from labrig.time.virtual import VirtualClock

# One ADC step of the USB-6009 in RSE (±10 V, 13 bits), in kPa at Vs = 5 V.
QUANTUM_KPA = 20.0 / 2**13 / (0.009 * 5.0)


def ramp_after(t_on_s, kpa_per_s):
    """Atmospheric until t_on, then a steady ramp: easy to check sample times against."""
    return lambda t: np.where(t > t_on_s, kpa_per_s * (t - t_on_s), 0.0)


class Rig:
    """The driver wired to simulated tasks; keeps each task it made for inspection."""

    def __init__(self, truth, sim=None, **driver):
        self.clock = VirtualClock()
        self.truth = truth
        self.tasks = []
        sim = {"seed": 7, **(sim or {})}

        def task_factory():
            task = SimDaqTask(self.clock, truth, **sim)
            self.tasks.append(task)
            return task

        self.daq = NiDaqPressure(
            self.clock,
            task_factory=task_factory,
            reader_factory=SimAnalogMultiChannelReader,
            **driver,
        )

    def collect(self, duration_s, every_s):
        blocks = []
        end = self.clock.now() + duration_s
        while self.clock.now() < end:
            self.clock.sleep(every_s)
            self.last_read_s = [self.clock.now()]
            blocks.append(self.daq.read())
            self.last_read_s.append(self.clock.now())
        t = np.concatenate([b.t_s for b in blocks])
        p = np.concatenate([b.pressure_kpa for b in blocks])
        flags = np.concatenate([b.out_of_range for b in blocks])
        return blocks, t, p, flags


def test_fits_the_pressure_source_contract():
    assert isinstance(Rig(ramp_after(0, 0)).daq, PressureSource)


def test_zero_then_continuous_blocks_match_the_truth():
    rig = Rig(ramp_after(3.0, 4.0), sim={"offset_error_kpa": 1.3, "noise_kpa": 0.05})
    offset = rig.daq.zero(1.0)
    # The mean of 1000 noisy samples recovers the sensor's offset error below one step.
    assert offset == pytest.approx(1.3, abs=QUANTUM_KPA)
    assert rig.tasks[0]._closed  # zeroing releases its task
    rig.daq.start(1000.0)
    blocks, t, p, flags = rig.collect(8.0, every_s=0.37)
    rig.daq.stop()
    assert len(blocks) > 10 and all(len(b) > 0 for b in blocks)
    np.testing.assert_allclose(np.diff(t), 1e-3, rtol=1e-6)  # contiguous, across blocks
    error = p - rig.truth(t)
    assert abs(np.mean(error)) < 2 * QUANTUM_KPA
    assert np.std(error) == pytest.approx(0.05, rel=0.15)
    assert not flags.any()


def test_long_run_loses_no_sample_and_timestamps_follow_the_ramp():
    rig = Rig(
        ramp_after(0.0, 0.1),
        sim={"noise_kpa": 0.0, "offset_error_kpa": 0.0},
    )
    rig.daq.start(1000.0)
    _, t, p, _ = rig.collect(900.0, every_s=2.0)  # 15 simulated minutes
    rig.daq.stop()
    # Every sample taken before the last read was delivered, and none twice.
    before_s, after_s = rig.last_read_s
    assert 1000.0 * (before_s - t[0]) - 5 <= t.size <= 1000.0 * (after_s - t[0]) + 5
    np.testing.assert_allclose(np.diff(t), 1e-3, rtol=1e-6)
    # The ramp moves 0.1 kPa per s: the readings would show any timestamp error beyond
    # about one quantisation step's worth of time (~0.5 s) — and the start latency is far less.
    assert np.max(np.abs(p - rig.truth(t))) <= QUANTUM_KPA


def test_measured_supply_removes_the_ratiometric_error():
    truth = ramp_after(2.0, 10.0)
    sim = {"supply_v": 5.2, "noise_kpa": 0.0, "offset_error_kpa": 0.0}
    slopes = {}
    for supply_channel in (None, "Dev1/ai1"):
        rig = Rig(truth, sim=sim, supply_channel=supply_channel)
        rig.daq.zero(0.5)
        rig.daq.start(500.0)
        _, t, p, _ = rig.collect(6.0, every_s=0.5)
        rig.daq.stop()
        rising = truth(t) > 1.0
        slopes[supply_channel] = np.polyfit(truth(t)[rising], p[rising], 1)[0]
    # Assuming 5.0 V when the supply is 5.2 V scales every reading by 5.2/5.0.
    assert slopes[None] == pytest.approx(5.2 / 5.0, abs=1e-3)
    assert slopes["Dev1/ai1"] == pytest.approx(1.0, abs=1e-3)


def test_readings_beyond_the_sensor_or_adc_are_flagged_not_clipped():
    rig = Rig(lambda t: np.full(np.shape(t), 110.0), sim={"noise_kpa": 0.0})
    rig.daq.start(200.0)
    _, _, p, flags = rig.collect(1.0, every_s=0.25)
    assert flags.all()
    assert np.mean(p) == pytest.approx(110.8, abs=0.1)  # 110 kPa + the 0.8 kPa offset error
    # On a ±1 V differential range the 0.2 V zero fits, 30 kPa (1.55 V) saturates the ADC.
    rig = Rig(ramp_after(0.5, 60.0), sim={"noise_kpa": 0.0}, terminal="DIFF", min_v=-1, max_v=1)
    rig.daq.start(200.0)
    _, t, p, flags = rig.collect(1.5, every_s=0.25)
    v_in = quantise(5.0 * (0.009 * (rig.truth(t) + 0.8) + 0.04), 1.0)
    assert flags.any() and not flags.all()
    np.testing.assert_array_equal(flags, v_in >= 1.0 - 2.0 / 2**14)


def test_zero_refuses_a_pressurised_line():
    rig = Rig(lambda t: np.full(np.shape(t), 15.0))
    with pytest.raises(DeviceError, match="open the line to atmosphere"):
        rig.daq.zero(0.2)
    assert rig.daq.offset_kpa == 0.0


def test_zero_during_a_run_leaves_no_gap_in_the_record():
    # Pressurised for 2 s, vented at 2 s: the zero is taken while acquiring.
    rig = Rig(lambda t: np.where(t < 2.0, 30.0, 0.0), sim={"offset_error_kpa": 1.5})
    rig.daq.start(500.0)
    _, t_before, p_before, _ = rig.collect(2.5, every_s=0.5)
    assert np.mean(p_before[t_before < 1.9]) == pytest.approx(31.5, abs=0.05)
    assert rig.daq.zero(0.5) == pytest.approx(1.5, abs=0.02)
    _, t_after, p_after, _ = rig.collect(1.0, every_s=0.5)
    t = np.concatenate([t_before, t_after])
    np.testing.assert_allclose(np.diff(t), 1 / 500.0, rtol=1e-6)  # the zeroing samples too
    assert np.mean(p_after) == pytest.approx(0.0, abs=0.02)


def test_read_timeout_becomes_a_clear_device_error():
    rig = Rig(ramp_after(0, 0), read_timeout_s=0.5)
    rig.daq.start()
    rig.clock.sleep(0.1)
    rig.tasks[-1].inject_read_timeout()
    with pytest.raises(DaqTimeoutError, match=r"-200284.*no samples within 0\.5 s.*USB cable"):
        rig.daq.read()


def test_zero_times_out_when_the_device_delivers_nothing():
    rig = Rig(ramp_after(0, 0), read_timeout_s=0.2)
    original = rig.daq._task_factory

    def silent_task():
        task = original()
        task.inject_read_timeout()
        return task

    rig.daq._task_factory = silent_task
    with pytest.raises(DaqTimeoutError, match="-200284"):
        rig.daq.zero(0.1)
    assert rig.tasks[-1]._closed


def test_overflow_when_read_too_late_becomes_a_clear_device_error():
    rig = Rig(ramp_after(0, 0), buffer_s=2.0)
    rig.daq.start(1000.0)  # DAQmx's smallest buffer at 1 kS/s is 10 000 samples = 10 s
    rig.clock.sleep(12.0)
    with pytest.raises(DaqOverflowError, match=r"-200279.*samples were lost.*buffer_s"):
        rig.daq.read()
    rig.daq.stop()
    rig.daq.start(1000.0)  # a restart recovers
    rig.clock.sleep(0.1)
    assert len(rig.daq.read()) > 0
    rig.tasks[-1].inject_overflow()
    rig.clock.sleep(0.1)  # a read with samples waiting reaches the task
    with pytest.raises(DaqOverflowError):
        rig.daq.read()


@pytest.mark.parametrize(
    ("driver", "code"),
    [
        ({"channel": "Dev1/ai9"}, "-200170"),
        ({"channel": "Dev3/ai0"}, "-200220"),
        ({"channel": "Dev1/ai5", "terminal": "DIFF"}, "-200077"),
        ({"channel": "Dev1/ai0", "min_v": -20.0, "max_v": 20.0}, "-200077"),
        ({"channel": "Dev1/ai0", "rate_hz": 60_000.0}, "-200081"),
    ],
)
def test_bad_configuration_is_a_clear_error_and_releases_the_task(driver, code):
    rig = Rig(ramp_after(0, 0), **driver)
    with pytest.raises(DaqConfigError) as raised:
        rig.daq.start()
    message = str(raised.value)
    assert code in message and "\n" not in message
    assert "USB-6009 takes ai0-ai7 in RSE" in message
    assert rig.tasks[-1]._closed
    assert rig.daq._task is None


def test_bad_parameters_are_input_errors():
    clock = VirtualClock()
    with pytest.raises(InputError, match="RSE or DIFF"):
        NiDaqPressure(clock, terminal="NRSE")
    with pytest.raises(InputError, match="min_v"):
        NiDaqPressure(clock, min_v=5.0, max_v=0.0)
    with pytest.raises(InputError, match="rate_hz"):
        NiDaqPressure(clock, rate_hz=0.0)


def test_missing_ni_daqmx_is_one_line_naming_sim():
    def no_driver():
        raise nidaqmx.errors.DaqNotFoundError("Could not find an installation of NI-DAQmx.")

    daq = NiDaqPressure(VirtualClock(), task_factory=no_driver)
    with pytest.raises(DaqNotInstalledError) as raised:
        daq.start()
    message = str(raised.value)
    assert "--sim" in message and "installdriver" in message and "\n" not in message


@pytest.mark.skipif(
    ctypes.util.find_library("nidaqmx") is not None, reason="NI-DAQmx is installed here"
)
def test_the_real_nidaqmx_task_without_the_driver_gives_that_line():
    with pytest.raises(DaqNotInstalledError, match="--sim"):
        NiDaqPressure(VirtualClock()).zero(0.1)


def test_importing_the_driver_does_not_import_nidaqmx():
    code = "import sys, labrig.drivers.ni_daq; print('nidaqmx' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_the_factories_are_what_differ(monkeypatch):
    """With no factories given, the driver uses nidaqmx's own Task and reader."""
    made = []

    def fake_task(*args):
        task = SimDaqTask(VirtualClock(), ramp_after(0, 0), seed=0)
        made.append(task)
        return task

    monkeypatch.setattr(nidaqmx, "Task", fake_task)
    seen = []
    monkeypatch.setattr(
        nidaqmx.stream_readers,
        "AnalogMultiChannelReader",
        lambda stream: seen.append(stream) or SimAnalogMultiChannelReader(stream),
    )
    daq = NiDaqPressure(VirtualClock())
    daq.start()
    daq.stop()
    assert len(made) == 1 and seen == [made[0].in_stream]


# ---- what the USB-6009 really does ---------------------------------------------------


class TimeRecorder:
    """A truth that keeps the true time of every sample the simulator took."""

    def __init__(self, p_kpa_at=None):
        self.p_kpa_at = p_kpa_at or ramp_after(0, 0)
        self.times = []

    def __call__(self, t_s):
        self.times.append(np.array(t_s))
        return self.p_kpa_at(t_s)

    @property
    def t_s(self):
        return np.concatenate(self.times)


def test_zero_under_the_recommended_wiring_judges_the_range_daqmx_uses():
    # RSE 0-5 V with the sensor's 5.0 V supply on ai1: DAQmx uses ±10 V (the only RSE
    # range), so 5.0 V is far from saturation; judged against 0-5 V it would be flagged.
    rig = Rig(
        ramp_after(0, 0),
        min_v=0.0,
        max_v=5.0,
        supply_channel="Dev1/ai1",
        sim={"supply_v": 5.0, "noise_kpa": 0.05},
    )
    rig.daq.zero(0.2)
    assert rig.daq.adc_ranges_v == [(-10.0, 10.0), (-10.0, 10.0)]
    assert rig.daq.adc_bits == [13, 13]
    rig.daq.start(1000.0)
    _, _, _, flags = rig.collect(0.2, every_s=0.05)
    rig.daq.stop()
    assert not flags.any()
    # The same supply samples against the requested range: most would be flagged.
    task = SimDaqTask(VirtualClock(), ramp_after(0, 0), supply_v=5.0, seed=3)
    task.ai_channels.add_ai_voltage_chan(
        "Dev1/ai1",
        terminal_config=nidaqmx.constants.TerminalConfiguration.RSE,
        min_val=0.0,
        max_val=5.0,
    )
    task.timing.cfg_samp_clk_timing(
        1000.0, sample_mode=nidaqmx.constants.AcquisitionType.CONTINUOUS
    )
    task.start()
    supply = np.empty((1, 200))
    SimAnalogMultiChannelReader(task.in_stream).read_many_sample(supply, 200, timeout=10.0)
    assert np.count_nonzero(mpx5100.beyond_adc_range(supply[0], 0.0, 5.0, 13)) > 50


@pytest.mark.parametrize(
    "code",
    [
        DAQmxErrors.SAMPLES_NO_LONGER_AVAILABLE,
        DAQmxErrors.INPUT_FIFO_OVERFLOW_2,
        DAQmxErrors.ACQ_STOPPED_DRIVER_CANT_XFER_DATA_FAST_ENOUGH,
    ],
)
def test_every_input_overflow_code_is_an_overflow(code):
    assert code.value in (-200279, -200361, -200714)
    rig = Rig(ramp_after(0, 0))
    rig.daq.start(1000.0)
    rig.tasks[-1].inject_overflow(code)
    with pytest.raises(DaqOverflowError, match=rf"DAQmx error {code.value} .*samples were lost"):
        rig.daq.read()
    rig.daq.stop()


def test_the_task_is_committed_before_the_start_time_is_taken():
    calls = []

    class Logged(SimDaqTask):
        def control(self, action):
            calls.append(action)
            super().control(action)

        def start(self):
            calls.append("start")
            super().start()

    clock = VirtualClock()
    daq = NiDaqPressure(
        clock,
        task_factory=lambda: Logged(clock, ramp_after(0, 0)),
        reader_factory=SimAnalogMultiChannelReader,
    )
    daq.start(1000.0)
    daq.stop()
    assert calls == [TaskMode.TASK_COMMIT, "start"]


def test_samples_are_stamped_at_the_rate_daqmx_coerced():
    truth = TimeRecorder()
    rig = Rig(truth)
    rig.daq.start(700.0)
    assert rig.daq.sample_clock_hz == 12e6 / 17_142  # 700.035 S/s, not 700
    _, t, _, _ = rig.collect(20.0, every_s=0.5)
    rig.daq.stop()
    np.testing.assert_allclose(np.diff(t), 17_142 / 12e6, rtol=1e-9)
    # At the requested rate the last stamp would be 1 ms late after 20 s; it is not.
    true_t = truth.t_s[: t.size]
    assert abs((t[-1] - t[0]) - (true_t[-1] - true_t[0])) < 1e-6
    assert (t.size - 1) / 700.0 - (true_t[-1] - true_t[0]) > 9e-4


def test_long_runs_follow_the_host_clock():
    # A sample clock 1000 ppm fast: stamped at the nominal rate, 300 s of samples would
    # end 0.3 s late. The drift check keeps them within the sightings' error.
    truth = TimeRecorder()
    rig = Rig(truth, sim={"clock_error_ppm": 1000.0}, buffer_s=400.0)
    rig.daq.start(100.0)
    _, t, _, _ = rig.collect(300.0, every_s=1.0)
    rig.daq.stop()
    true_t = truth.t_s[: t.size]
    naive_t = t[0] + np.arange(t.size) / rig.daq.sample_clock_hz
    assert np.max(np.abs(naive_t - true_t)) > 0.25  # what it was without the drift check
    assert np.all(np.diff(t) > 0)  # continuous and increasing across every correction
    settled = true_t - true_t[0] > 60.0
    assert np.max(np.abs(t - true_t)[settled]) < 0.03


def test_a_read_that_times_out_part_way_keeps_what_it_returned():
    truth = TimeRecorder()
    rig = Rig(truth, read_timeout_s=0.2)
    rig.daq.start(1000.0)
    rig.clock.sleep(0.5)
    first = rig.daq.read()
    rig.clock.sleep(0.5)
    rig.tasks[-1].inject_read_timeout(n_delivered=120)
    with pytest.raises(DaqTimeoutError):
        rig.daq.read()
    rig.clock.sleep(0.3)
    after = rig.daq.read()
    rig.daq.stop()
    t = np.concatenate([first.t_s, after.t_s])
    # The 120 samples that came with the timeout are in the record, stamped in place.
    np.testing.assert_allclose(np.diff(t), 1e-3, rtol=1e-6)
    assert t.size == truth.t_s.size
    np.testing.assert_allclose(t - truth.t_s, t[0] - truth.t_s[0], atol=1e-9)


def test_a_disagreement_no_crystal_has_is_not_believed(caplog):
    # 1 % is not a drifting crystal (~1e-4): the stamps keep the nominal period.
    rig = Rig(TimeRecorder(), sim={"clock_error_ppm": 10_000.0}, buffer_s=100.0)
    rig.daq.start(100.0)
    with caplog.at_level("WARNING", logger="labrig.drivers.ni_daq"):
        _, t, _, _ = rig.collect(60.0, every_s=1.0)
    rig.daq.stop()
    assert "ppm off the host clock: not believed" in caplog.text
    np.testing.assert_allclose(np.diff(t), 0.01, rtol=1e-9)


def test_an_unplugged_daq_gets_cable_advice_and_its_buffer_is_read_first():
    """-201003 says the device cannot be reached, not that the wiring or rate is wrong;
    what was in the host buffer when it went is still read."""
    rig = Rig(ramp_after(0.0, 1.0), supply_channel="Dev1/ai1")
    rig.daq.start(1000.0)
    rig.clock.sleep(0.5)
    rig.tasks[-1].fail("vanish")
    rig.clock.sleep(0.3)
    block = rig.daq.read()
    assert block.t_s[-1] == pytest.approx(0.5, abs=2e-3)  # every sample up to the unplug
    with pytest.raises(DaqUnreachableError, match=r"-201003.*cannot be reached.*USB cable"):
        rig.daq.read()
    # stop and close fail too, and the task is released all the same
    with pytest.raises(DaqUnreachableError, match="while stopping"):
        rig.daq.stop()
    rig.daq.stop()  # nothing left to release


def test_samples_read_as_the_daq_is_unplugged_are_kept_when_a_drift_check_is_due():
    """The read that finds the device gone also runs the due drift check: that check
    asks DAQmx nothing, so the samples taken before the unplug come back, and the
    -201003 comes with the next read."""
    rig = Rig(ramp_after(0.0, 1.0), buffer_s=20.0)
    rig.daq.start(1000.0)
    rig.clock.sleep(DRIFT_CHECK_S + 0.5)  # no read since the start: the check is due
    rig.tasks[-1].fail("vanish")
    rig.clock.sleep(0.3)
    block = rig.daq.read()
    assert len(block.t_s) == pytest.approx(1000.0 * (DRIFT_CHECK_S + 0.5), abs=2)
    assert block.t_s[-1] == pytest.approx(DRIFT_CHECK_S + 0.5, abs=2e-3)
    with pytest.raises(DaqUnreachableError, match="-201003"):
        rig.daq.read()
    with pytest.raises(DaqUnreachableError):
        rig.daq.stop()


@pytest.mark.parametrize(("failure", "check"), [("vout-cut", "low"), ("supply-cut", "nan")])
def test_a_dead_sensor_wire_reads_as_no_pressure(failure, check):
    """Vout shorted to ground: -4.4 kPa (flagged); supply cut with the supply
    measured: 0/0, converted to NaN, not a number that could pass for a pressure."""
    rig = Rig(ramp_after(0.0, 10.0), supply_channel="Dev1/ai1")
    rig.daq.start(1000.0)
    rig.clock.sleep(0.5)
    rig.tasks[-1].fail(failure)
    rig.clock.sleep(0.5)
    block = rig.daq.read()
    before, after = block.t_s < 0.5, block.t_s >= 0.5
    assert np.all(np.isfinite(block.pressure_kpa[before]))
    assert not block.out_of_range[before].any()
    if check == "low":
        np.testing.assert_allclose(block.pressure_kpa[after], -0.04 / 0.009, atol=0.2)
        assert block.out_of_range[after].all()
    else:
        assert np.isnan(block.pressure_kpa[after]).all()


def read_with_the_wire_cut(rig, *, at_s: float, then_s: float):
    """Acquire, cut the sensor's output wire at ``at_s``, read ``then_s`` later: the
    block and where it is after the cut."""
    rig.daq.start(1000.0)
    rig.clock.sleep(at_s)
    rig.tasks[-1].fail("vout-floating")
    rig.clock.sleep(then_s)
    block = rig.daq.read()
    return block, block.t_s >= at_s


def test_a_cut_output_wire_floats_where_the_usb_6009_input_network_holds_it():
    """An open RSE input reads the Thevenin voltage of the 6009's input network (127 kOhm
    to a node tied to ground by 39.2 kOhm and to +2.5 V by 30.9 kOhm): 1.40 V, 26.6 kPa
    through the MPX5100 on 5 V, in range and not flagged, with mains hum on it."""
    rig = Rig(ramp_after(0.0, 10.0), sim={"noise_kpa": 0.0}, supply_channel="Dev1/ai1")
    block, after = read_with_the_wire_cut(rig, at_s=0.5, then_s=2.0)
    p = block.pressure_kpa[after]
    # the node's voltage with the pin open: no current through the 127 kOhm
    open_v = 2.5 / (1 / 39.2e3 + 1 / 30.9e3) / 30.9e3
    assert open_v == pytest.approx(1.398, abs=1e-3)
    assert np.mean(p) == pytest.approx((open_v / 5.0 - 0.04) / 0.009, abs=0.1)
    assert not block.out_of_range[after].any() and np.all(np.isfinite(p))
    assert 0.1 < np.std(p) < 0.3  # noisy: hum and a few codes of broadband noise
    spectrum = np.abs(np.fft.rfft(p - np.mean(p)))
    assert np.fft.rfftfreq(len(p), 1e-3)[np.argmax(spectrum)] == pytest.approx(50.0, abs=1.0)
    # before the cut: the ramp, as the sensor gave it
    np.testing.assert_allclose(
        block.pressure_kpa[~after], rig.truth(block.t_s[~after]) + 0.8, atol=0.3
    )


def test_with_the_pull_up_a_cut_output_wire_reads_above_the_band_and_is_flagged():
    """A 4.7 kOhm pull-up from the input to the sensor's 5 V: the open pin settles where
    the currents into it balance (Kirchhoff), 4.89 V, above the MPX5100's 4.813 V most;
    every sample is flagged, even after a zero taken at -2.5 kPa (the band is judged
    before the zero is taken off). The connected sensor is unaffected."""
    rig = Rig(ramp_after(0.0, 10.0), sim={"pull_up_kohm": 4.7, "noise_kpa": 0.0})
    rig.daq.offset_kpa = -2.5
    block, after = read_with_the_wire_cut(rig, at_s=0.5, then_s=1.0)
    # KCL at the pin: (5 - V)/4.7k into it, (V - V_th)/R_th out into the input network
    r_th = 127e3 + 1 / (1 / 39.2e3 + 1 / 30.9e3)
    v_th = 2.5 * 39.2 / (39.2 + 30.9)
    open_v = (5.0 / 4.7e3 + v_th / r_th) / (1 / 4.7e3 + 1 / r_th)
    assert open_v > 4.813
    raw_kpa = (open_v / 5.0 - 0.04) / 0.009
    assert np.mean(block.pressure_kpa[after]) == pytest.approx(raw_kpa + 2.5, abs=0.05)
    assert block.out_of_range[after].all()
    assert not block.out_of_range[~after].any()


# What a USB-6009 shows: its count is of the samples that reached the host, a transfer
# of 12-37 ms after they were taken.
USB_LATENCY_S = (0.012, 0.037)


def test_usb_transfer_latency_never_makes_the_stamps_late():
    truth = TimeRecorder()
    rig = Rig(truth, sim={"transfer_latency_s": USB_LATENCY_S})
    rig.daq.start(1000.0)
    _, t, _, _ = rig.collect(120.0, every_s=0.1)
    rig.daq.stop()
    late_s = t - truth.t_s[: t.size]
    # the sample clock anchored at the start: on time to the clock's rounding, however
    # late each block reached the host
    assert np.max(np.abs(late_s)) < 1e-6
    np.testing.assert_allclose(np.diff(t), 1e-3, rtol=1e-9)


def test_a_drifting_sample_clock_is_caught_beyond_what_latency_explains():
    # 1000 ppm fast behind USB latency: stamped at the nominal rate, 300 s of samples
    # would end 0.3 s late; the drift check finds the rate behind the latency.
    truth = TimeRecorder()
    rig = Rig(
        truth, sim={"clock_error_ppm": 1000.0, "transfer_latency_s": USB_LATENCY_S}, buffer_s=400.0
    )
    rig.daq.start(100.0)
    _, t, _, _ = rig.collect(300.0, every_s=0.2)  # as often as a run reads
    rig.daq.stop()
    true_t = truth.t_s[: t.size]
    naive_t = t[0] + np.arange(t.size) / rig.daq.sample_clock_hz
    assert np.max(naive_t - true_t) > 0.25  # what it was without the check
    assert np.all(np.diff(t) > 0)  # continuous and increasing across every correction
    # the rate is first judged over 30 s of sightings (at 40 s) and slewed onto by 50 s
    error_s = t - true_t
    assert np.max(np.abs(error_s[true_t - true_t[0] > 60.0])) < 0.01
    assert np.max(np.abs(error_s[true_t - true_t[0] > 200.0])) < 0.005
