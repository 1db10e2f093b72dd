"""SimDaqTask: the real nidaqmx API shape, USB-6009 validation, timing, quantisation, faults."""

import inspect

import numpy as np
import pytest
from nidaqmx.constants import (
    READ_ALL_AVAILABLE,
    AcquisitionType,
    ResolutionType,
    TaskMode,
    TerminalConfiguration,
)
from nidaqmx.errors import DaqError, DaqReadError
from nidaqmx.stream_readers import AnalogMultiChannelReader
from nidaqmx.task import InStream, Task, Timing
from nidaqmx.task.channels import AIChannel
from nidaqmx.task.collections import AIChannelCollection

from labrig.drivers import mpx5100
from labrig.sim.daq import (
    SimAIChannel,
    SimAIChannelCollection,
    SimAnalogMultiChannelReader,
    SimDaqTask,
    SimInStream,
    SimTiming,
    quantise,
)
from labrig.time.virtual import VirtualClock

RSE = TerminalConfiguration.RSE
DIFF = TerminalConfiguration.DIFF
CONTINUOUS = AcquisitionType.CONTINUOUS


class Recorder:
    """A pressure truth that remembers every time it was asked about."""

    def __init__(self, p_kpa_at=lambda t: np.full(np.shape(t), 20.0)):
        self.p_kpa_at = p_kpa_at
        self.times = []

    def __call__(self, t_s):
        self.times.append(np.array(t_s))
        return self.p_kpa_at(t_s)


def make_task(clock=None, truth=None, **kwargs):
    kwargs.setdefault("seed", 1)
    return SimDaqTask(clock or VirtualClock(), truth or Recorder(), **kwargs)


def started(task, rate=1000.0, channels=("Dev1/ai0",), **chan):
    chan = {"terminal_config": RSE, "min_val": -10.0, "max_val": 10.0, **chan}
    for c in channels:
        task.ai_channels.add_ai_voltage_chan(c, **chan)
    task.timing.cfg_samp_clk_timing(rate, sample_mode=CONTINUOUS, samps_per_chan=int(rate))
    task.start()
    return task, SimAnalogMultiChannelReader(task.in_stream)


def read(reader, n_chans, n, timeout=10.0):
    data = np.empty((n_chans, n))
    got = reader.read_many_sample(data, number_of_samples_per_channel=n, timeout=timeout)
    return data[:, :got]


@pytest.mark.parametrize(
    ("sim", "real"),
    [
        (SimAIChannelCollection.add_ai_voltage_chan, AIChannelCollection.add_ai_voltage_chan),
        (SimTiming.cfg_samp_clk_timing, Timing.cfg_samp_clk_timing),
        (SimDaqTask.control, Task.control),
        (
            SimAnalogMultiChannelReader.read_many_sample,
            AnalogMultiChannelReader.read_many_sample,
        ),
    ],
)
def test_signatures_match_nidaqmx(sim, real):
    def shape(f):
        return [(p.name, p.default) for p in inspect.signature(f).parameters.values()]

    assert shape(sim) == shape(real)


@pytest.mark.parametrize(
    ("channel", "terminal", "lo", "hi", "code"),
    [
        ("Dev1/ai4", DIFF, -10.0, 10.0, -200077),  # ai4 is ai0's negative input in DIFF
        ("Dev1/ai5", TerminalConfiguration.DEFAULT, -10.0, 10.0, -200077),  # default is DIFF
        ("Dev1/ai0", RSE, -20.0, 20.0, -200077),  # RSE is ±10 V only
        ("Dev1/ai0", DIFF, -25.0, 25.0, -200077),
        ("Dev1/ai0", TerminalConfiguration.NRSE, -10.0, 10.0, -200077),
        ("Dev1/ai0", RSE, 5.0, 1.0, -200077),
        ("Dev1/ai8", RSE, -10.0, 10.0, -200170),
        ("Dev1/ao0", RSE, -10.0, 10.0, -200170),
        ("Dev2/ai0", RSE, -10.0, 10.0, -200220),
    ],
)
def test_channels_are_validated_like_a_usb_6009(channel, terminal, lo, hi, code):
    task = make_task()
    with pytest.raises(DaqError) as raised:
        task.ai_channels.add_ai_voltage_chan(
            channel, terminal_config=terminal, min_val=lo, max_val=hi
        )
    assert raised.value.error_code == code
    assert str(code) in str(raised.value)


def test_valid_channels_and_ranges_are_accepted():
    task = make_task()
    task.ai_channels.add_ai_voltage_chan("Dev1/ai7", terminal_config=RSE, min_val=0, max_val=5)
    task.ai_channels.add_ai_voltage_chan(
        "/dev1/ai0:3", terminal_config=DIFF, min_val=-20, max_val=20
    )
    assert task.channel_names == ["Dev1/ai7", "Dev1/ai0", "Dev1/ai1", "Dev1/ai2", "Dev1/ai3"]
    assert task.in_stream.num_chans == 5


def test_aggregate_rate_limit_and_empty_task_fail_at_start():
    task = make_task()
    task.ai_channels.add_ai_voltage_chan("Dev1/ai0:1", terminal_config=RSE, min_val=-10, max_val=10)
    task.timing.cfg_samp_clk_timing(30_000, sample_mode=CONTINUOUS)
    with pytest.raises(DaqError) as raised:
        task.start()
    assert raised.value.error_code == -200081
    task.timing.cfg_samp_clk_timing(24_000, sample_mode=CONTINUOUS)
    task.start()  # 2 x 24 kS/s = 48 kS/s is the limit, not beyond it
    with pytest.raises(DaqError) as raised:
        make_task().start()
    assert raised.value.error_code == -200088


def test_closed_task_is_invalid_and_context_manager_closes():
    with make_task() as task:
        pass
    with pytest.raises(DaqError) as raised:
        task.ai_channels.add_ai_voltage_chan(
            "Dev1/ai0", terminal_config=RSE, min_val=-10, max_val=10
        )
    assert raised.value.error_code == -200088


def test_one_sample_per_period_none_lost_however_late_the_reads():
    clock = VirtualClock()
    truth = Recorder()
    task, reader = started(make_task(clock, truth, noise_kpa=0.0), rate=500.0)
    total = 0
    for pause_s in (0.05, 1.3, 0.0, 0.4, 2.5, 0.01):
        clock.sleep(pause_s)
        before_s = clock.now()
        total += read(reader, 1, task.in_stream.avail_samp_per_chan).shape[1]
        after_s = clock.now()
    times = np.concatenate(truth.times)
    assert times.size == total
    np.testing.assert_allclose(np.diff(times), 1 / 500.0, rtol=1e-9)
    # Every sample taken up to the last read was delivered: rate x elapsed of them.
    assert 500.0 * (before_s - times[0]) <= total <= 500.0 * (after_s - times[0]) + 1


def test_voltages_are_the_sensor_output_quantised_to_14_bits():
    _, reader = started(
        make_task(noise_kpa=0.0, offset_error_kpa=0.0, supply_v=5.0),
        channels=("Dev1/ai0",),
        terminal_config=DIFF,
        min_val=0.0,
        max_val=4.0,  # DAQmx picks the smallest range holding 0-4 V: ±4 V
    )
    v = read(reader, 1, 50)[0]
    step = 8.0 / 2**14
    ideal = mpx5100.output_v(20.0, 5.0)
    np.testing.assert_allclose((v + 4.0) / step, np.rint((v + 4.0) / step), atol=1e-9)
    assert np.all(np.abs(v - ideal) <= step / 2 + 1e-12)


def test_supply_and_unwired_channels_and_saturation():
    _, reader = started(
        make_task(
            noise_kpa=0.0, supply_v=5.1, truth=Recorder(lambda t: np.full(np.shape(t), 60.0))
        ),
        channels=("Dev1/ai0", "Dev1/ai1", "Dev1/ai2"),
        terminal_config=DIFF,
        min_val=-1.0,
        max_val=1.0,
    )
    out, supply, unwired = read(reader, 3, 10)
    step = 2.0 / 2**14
    # 60 kPa gives 3.0 V and a 5.1 V supply: both beyond ±1 V, so both sit on the top code.
    np.testing.assert_allclose(out, 1.0 - step)
    np.testing.assert_allclose(supply, 1.0 - step)
    np.testing.assert_allclose(unwired, 0.0)


def test_quantise_saturates_at_both_ends():
    step = 20.0 / 2**14
    np.testing.assert_allclose(
        quantise(np.array([-50.0, 0.0, 50.0]), 10.0), [-10.0, 0.0, 10.0 - step]
    )


def test_buffer_overflows_when_not_read_in_time_and_stays_failed():
    clock = VirtualClock()
    task, reader = started(make_task(clock), rate=100.0)  # buffer: 1000 samples = 10 s
    clock.sleep(11.0)
    for _ in range(2):
        with pytest.raises(DaqReadError) as raised:
            read(reader, 1, 10)
        assert raised.value.error_code == -200279
    task.stop()
    task.start()
    assert read(reader, 1, 1).shape == (1, 1)


def test_injected_overflow_and_timeout():
    clock = VirtualClock()
    task, reader = started(make_task(clock))
    task.inject_overflow()
    with pytest.raises(DaqReadError) as raised:
        read(reader, 1, 1)
    assert raised.value.error_code == -200279
    task.stop()
    task.start()
    task.inject_read_timeout()
    before = clock.now()
    with pytest.raises(DaqReadError) as raised:
        read(reader, 1, 1, timeout=2.0)
    assert raised.value.error_code == -200284
    assert raised.value.samps_per_chan_read == 0
    assert clock.now() - before >= 2.0  # it waited its timeout, like DAQmx
    assert read(reader, 1, 1).shape == (1, 1)  # only the next read was affected


def test_a_read_for_more_than_arrives_times_out_with_what_it_got():
    clock = VirtualClock()
    _, reader = started(make_task(clock), rate=1000.0)
    data = np.empty((1, 100_000))
    with pytest.raises(DaqReadError) as raised:
        reader.read_many_sample(data, number_of_samples_per_channel=100_000, timeout=0.5)
    assert raised.value.error_code == -200284
    assert 400 <= raised.value.samps_per_chan_read < 100_000


def test_read_all_available_and_array_shape_check():
    clock = VirtualClock()
    task, reader = started(make_task(clock), channels=("Dev1/ai0", "Dev1/ai1"))
    clock.sleep(0.2)
    n = task.in_stream.avail_samp_per_chan
    assert n >= 150
    data = np.empty((2, n))
    assert reader.read_many_sample(data, READ_ALL_AVAILABLE) == n
    with pytest.raises(DaqError, match="not shaped correctly"):
        reader.read_many_sample(np.empty((1, 5)), 5)


def test_read_starts_a_task_that_was_not_started():
    task = make_task()
    task.ai_channels.add_ai_voltage_chan("Dev1/ai0", terminal_config=RSE, min_val=-10, max_val=10)
    task.timing.cfg_samp_clk_timing(1000.0, sample_mode=CONTINUOUS)
    reader = SimAnalogMultiChannelReader(task.in_stream)
    assert task.in_stream.avail_samp_per_chan == 0
    assert read(reader, 1, 3).shape == (1, 3)


# ---- what the device really does ------------------------------------------------------


def test_the_properties_the_driver_reads_exist_in_nidaqmx():
    for sim, real, name in [
        (SimAIChannel, AIChannel, "ai_rng_low"),
        (SimAIChannel, AIChannel, "ai_rng_high"),
        (SimAIChannel, AIChannel, "ai_resolution"),
        (SimAIChannel, AIChannel, "ai_resolution_units"),
        (SimAIChannel, AIChannel, "ai_term_cfg"),
        (SimInStream, InStream, "total_samp_per_chan_acquired"),
        (SimInStream, InStream, "avail_samp_per_chan"),
        (SimTiming, Timing, "samp_clk_rate"),
    ]:
        assert isinstance(getattr(real, name), property), name
        assert hasattr(sim, name) or name == "samp_clk_rate", name


@pytest.mark.parametrize(
    ("terminal", "lo", "hi", "rng", "bits"),
    [(RSE, 0.0, 5.0, 10.0, 13), (RSE, -1.0, 1.0, 10.0, 13), (DIFF, 0.0, 4.0, 4.0, 14)],
)
def test_the_channel_reports_the_range_and_resolution_it_really_uses(terminal, lo, hi, rng, bits):
    task = make_task()
    channel = task.ai_channels.add_ai_voltage_chan(
        "Dev1/ai0", terminal_config=terminal, min_val=lo, max_val=hi
    )
    assert (channel.ai_rng_low, channel.ai_rng_high) == (-rng, rng)
    assert (channel.ai_resolution, channel.ai_resolution_units) == (bits, ResolutionType.BITS)
    assert channel.ai_term_cfg == terminal


def test_rse_is_quantised_to_13_bits():
    _, reader = started(make_task(noise_kpa=0.0, offset_error_kpa=0.0, supply_v=5.0))
    v = read(reader, 1, 50)[0]
    step = 20.0 / 2**13  # 2.44 mV: twice the 14-bit step
    # 1.1 V is 9093.1 steps of 14 bits: the 14-bit code 9093 would be off this grid.
    np.testing.assert_allclose((v + 10.0) / step, np.rint((v + 10.0) / step), atol=1e-9)
    assert np.all(np.abs(v - mpx5100.output_v(20.0, 5.0)) <= step / 2 + 1e-12)


@pytest.mark.parametrize(
    ("requested", "divisor"), [(1000.0, 12_000), (700.0, 17_142), (48_000.0, 250)]
)
def test_the_sample_clock_rate_is_coerced_to_the_timebase(requested, divisor):
    clock = VirtualClock()
    truth = Recorder()
    task, reader = started(make_task(clock, truth), rate=requested)
    rate = 12e6 / divisor  # by hand: the timebase over a whole number, at or above
    assert task.timing.samp_clk_rate == rate and rate >= requested
    clock.sleep(0.5)
    read(reader, 1, task.in_stream.avail_samp_per_chan)
    np.testing.assert_allclose(np.diff(np.concatenate(truth.times)), 1 / rate, rtol=1e-9)


def test_commit_checks_what_start_checks_and_counts_nothing_yet():
    task = make_task()
    for c in ("Dev1/ai0", "Dev1/ai1"):
        task.ai_channels.add_ai_voltage_chan(c, terminal_config=RSE, min_val=-10, max_val=10)
    task.timing.cfg_samp_clk_timing(30_000.0, sample_mode=CONTINUOUS)
    with pytest.raises(DaqError) as raised:
        task.control(TaskMode.TASK_COMMIT)  # 60 kS/s over two channels
    assert raised.value.error_code == -200081  # SAMPLE_RATE_NUM_CHANS_CONVERT_PERIOD_COMBO
    task.timing.cfg_samp_clk_timing(1000.0, sample_mode=CONTINUOUS)
    task.control(TaskMode.TASK_COMMIT)
    assert task.in_stream.total_samp_per_chan_acquired == 0
    task.control(TaskMode.TASK_START)
    task.clock.sleep(0.25)
    assert 250 <= task.in_stream.total_samp_per_chan_acquired <= 260
    task.control(TaskMode.TASK_STOP)
    assert task.in_stream.avail_samp_per_chan == 0


def test_a_read_of_what_is_available_never_waits_or_times_out():
    clock = VirtualClock()
    task, reader = started(make_task(clock), rate=1000.0)
    clock.sleep(0.2)
    task.inject_read_timeout()  # a fault for a read that waits, not for this one
    reader.verify_array_shape = False  # the count grows while the clock runs
    before_s = clock.now()
    got = reader.read_many_sample(np.empty((1, 10_000)), READ_ALL_AVAILABLE, timeout=0.0)
    assert got >= 200 and clock.now() - before_s < 0.2  # no timeout was waited
    with pytest.raises(DaqReadError) as raised:  # the next read that waits gets it
        read(reader, 1, 100_000, timeout=0.1)
    assert raised.value.samps_per_chan_read == 0


def test_a_sample_clock_off_the_host_clock():
    clock = VirtualClock()
    truth = Recorder()
    task, reader = started(make_task(clock, truth, clock_error_ppm=1000.0), rate=100.0)
    clock.sleep(1.0)
    read(reader, 1, task.in_stream.avail_samp_per_chan)
    np.testing.assert_allclose(np.diff(np.concatenate(truth.times)), 1 / 100.1, rtol=1e-9)


def test_samples_reach_the_host_a_jittered_transfer_after_they_are_taken():
    """The count a USB-6009 reports is of the samples a USB transfer brought: taken
    12-37 ms before the query, never fewer than the query before."""
    clock = VirtualClock()
    task, _ = started(make_task(clock, transfer_latency_s=(0.012, 0.037)))
    counts, lags_s = [], []
    for _ in range(200):
        clock.sleep(0.0137)
        n = task.in_stream.total_samp_per_chan_acquired
        counts.append(n)
        lags_s.append(clock.now() - (n - 1) / 1000.0)  # sample n - 1 was taken then
    assert np.all(np.diff(counts) >= 0)
    assert min(lags_s) >= 0.012 - 1e-9 and max(lags_s) <= 0.037 + 0.001 + 1e-9
    assert max(lags_s) - min(lags_s) > 0.015  # jittered, not a fixed delay
