"""A simulated NI USB-6009 running an analog-input task, wired to an MPX5100.

``SimDaqTask`` implements the part of ``nidaqmx.Task`` that ``labrig.drivers.ni_daq``
uses (``ai_channels.add_ai_voltage_chan``, ``timing.cfg_samp_clk_timing``, ``in_stream``,
``start``/``stop``/``close``/``control``, the context manager, the channel's coerced
range and resolution, the coerced sample clock rate, the acquired-sample count) with
the real signatures, enums and
exceptions (``nidaqmx.errors.DaqError``/``DaqReadError`` with the real error codes), so
the driver's own code runs unchanged against it. ``SimAnalogMultiChannelReader`` stands
in for ``nidaqmx.stream_readers.AnalogMultiChannelReader``, whose real implementation
talks to the DAQmx C library through private handles a simulator should not imitate.

Behaviour copied from the device rather than replayed:
- validation like the USB-6009: ai0-ai7 in RSE (±10 V only), ai0-ai3 in DIFF (±20 to
  ±1 V), the default terminal configuration is DIFF, 48 kS/s in total over all channels;
- the range DAQmx really uses: the smallest hardware range holding the requested one
  (``ai_rng_low``/``ai_rng_high``; always ±10 V in RSE), and the sample clock rate it
  really uses: the timebase divided by a whole number (``timing.samp_clk_rate`` reads
  the coerced rate, not the requested one);
- a sample clock that may be off by ``clock_error_ppm`` against the host clock (a
  crystal's error), so a driver that never checks its rate drifts as on the bench;
- samples that reach the host a USB transfer after they are taken
  (``transfer_latency_s``, a range each query draws from): the acquired count
  (``total_samp_per_chan_acquired``) and what a read can take lag the sample clock by
  it, as on a USB-6009, whose count is of the samples that have reached the host;
- hardware timing on the shared clock: sample k is taken at t_start + k/rate however late
  it is read, so nothing is lost while the buffer has room, and like DAQmx the buffer
  overflows (error -200279) when it is not read in time;
- a read of samples already acquired returns at once whatever its timeout, and a read of
  ``READ_ALL_AVAILABLE`` never waits; DAQmx's own error codes for everything else;
- the MPX5100's output (ratiometric, with an offset error and noise) and the
  quantisation of the hardware range, 13 bits in RSE and 14 differential (the usual
  datasheet split, unverified against NI), saturating at the range's ends;
- the ways the bench dies, from a clock time on (``fail``, ``FAILURES``): the sensor's
  Vout wire cut (the open input floats, ``floating_input_v``, where the wiring holds it:
  the input network alone, or a pull-up to the sensor's supply), its Vout shorted to
  ground (the input reads 0 V), its supply wire cut (no output, and a measured
  supply of 0 V), its output frozen (every later sample the same code), the device
  stalling (no sample acquired after it: reads wait and time out, -200284) or vanishing
  (unplugged: the samples already in the host buffer are read, then every call,
  ``stop`` and ``close`` too, raises -201003, as DAQmx reports a device it cannot reach).

This module imports nidaqmx (constants and exceptions only; no driver needed): it is
loaded only when a simulated rig is built.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from nidaqmx.constants import (
    READ_ALL_AVAILABLE,
    AcquisitionType,
    Edge,
    ResolutionType,
    TaskMode,
    TerminalConfiguration,
    VoltageUnits,
)
from nidaqmx.error_codes import DAQmxErrors
from nidaqmx.errors import DaqError, DaqReadError

from labrig.drivers import mpx5100
from labrig.time.clock import Clock

ADC_BITS = 14  # differential
RSE_ADC_BITS = 13
# The AI sample clock timebase the rate is divided from (a model: NI does not state
# the USB-6009's in the documents found; the coercion, not the number, is the point).
TIMEBASE_HZ = 12e6
N_AI_RSE = 8  # ai0-ai7 single-ended
N_AI_DIFF = 4  # ai0/ai4 ... ai3/ai7
RSE_RANGES_V = (10.0,)
DIFF_RANGES_V = (1.0, 1.25, 2.0, 2.5, 4.0, 5.0, 10.0, 20.0)
MAX_AGGREGATE_RATE_HZ = 48_000.0
MIN_RATE_HZ = 0.1

FAILURES = ("vout-floating", "vout-cut", "supply-cut", "frozen", "stall", "vanish")
# An open input does not read 0 V. Each analog input of the USB-6008/6009 reaches the
# multiplexer through 127 kOhm to a node tied to ground by 39.2 kOhm and to the +2.5 V
# reference by 30.9 kOhm (NI USB-6008/6009 User Guide and Specifications, "Analog Input
# Circuitry"). Seen from the pin that is a source of 2.5 V x 39.2 / (39.2 + 30.9) =
# 1.398 V behind 127 + 39.2 || 30.9 = 144 kOhm, the spec's input impedance: a cut wire
# reads 1.40 V, 26.6 kPa through an MPX5100 on 5 V.
FLOATING_INPUT_V = 2.5 * 39.2 / (39.2 + 30.9)
INPUT_IMPEDANCE_KOHM = 127 + 39.2 * 30.9 / (39.2 + 30.9)
# What a dangling wire behind 144 kOhm picks up (a model: it depends on the wire and the
# room): mains hum, and broadband noise a few codes wide (one RSE code is 2.44 mV).
FLOATING_HUM_V = 0.010  # amplitude
FLOATING_NOISE_V = 0.003  # standard deviation
MAINS_HZ = 50.0
_CHANNEL_RE = re.compile(r"^/?(?P<dev>[A-Za-z]\w*)/ai(?P<first>\d+)(?::(?P<last>\d+))?$")


def default_buffer_size(rate_hz: float) -> int:
    """DAQmx's default continuous input buffer per channel for a sample rate (NI's
    "How is buffer size determined" table); a larger ``samps_per_chan`` wins."""
    if rate_hz <= 100:
        return 1_000
    if rate_hz <= 10_000:
        return 10_000
    if rate_hz <= 1_000_000:
        return 100_000
    return 1_000_000


@dataclass(frozen=True)
class _Channel:
    """One configured input: where it is wired and the range the ADC digitises."""

    physical: str
    range_v: float  # the hardware range is ±range_v
    bits: int
    terminal: TerminalConfiguration


class SimAIChannel:
    """What ``add_ai_voltage_chan`` returns (``nidaqmx.task.channels.AIChannel``): the
    properties DAQmx coerces, read back as the device really uses them."""

    def __init__(self, task: SimDaqTask, channels: list[_Channel]) -> None:
        self._task = task
        self._channels = channels
        self.name = ",".join(c.physical for c in channels)

    def _one(self) -> _Channel:
        self._task._check_open()
        return self._channels[0]

    @property
    def ai_rng_high(self) -> float:
        return self._one().range_v

    @property
    def ai_rng_low(self) -> float:
        return -self._one().range_v

    @property
    def ai_resolution(self) -> float:
        return float(self._one().bits)

    @property
    def ai_resolution_units(self) -> ResolutionType:
        return ResolutionType.BITS

    @property
    def ai_term_cfg(self) -> TerminalConfiguration:
        return self._one().terminal


class SimAIChannelCollection:
    """``task.ai_channels``: adds voltage channels, validated as the USB-6009 would."""

    def __init__(self, task: SimDaqTask) -> None:
        self._task = task
        self._channels: list[_Channel] = []

    def __len__(self) -> int:
        return len(self._channels)

    def add_ai_voltage_chan(
        self,
        physical_channel,
        name_to_assign_to_channel="",
        terminal_config=TerminalConfiguration.DEFAULT,
        min_val=-5.0,
        max_val=5.0,
        units=VoltageUnits.VOLTS,
        custom_scale_name="",
    ):
        task = self._task
        task._check_open()
        # On the USB-6009 DAQmx's default terminal configuration is differential.
        terminal = (
            TerminalConfiguration.DIFF
            if terminal_config == TerminalConfiguration.DEFAULT
            else terminal_config
        )
        indices = self._parse(physical_channel)
        if terminal == TerminalConfiguration.RSE:
            n_allowed, ranges = N_AI_RSE, RSE_RANGES_V
        elif terminal == TerminalConfiguration.DIFF:
            n_allowed, ranges = N_AI_DIFF, DIFF_RANGES_V
        else:
            raise task._error(
                "Requested value is not a supported value for this property.\n"
                f"Property: DAQmx_AI_TermCfg\nRequested Value: {terminal.name}\n"
                "Possible Values: DAQmx_Val_RSE, DAQmx_Val_Diff",
                DAQmxErrors.INVALID_ATTRIBUTE_VALUE,
            )
        if any(i >= n_allowed for i in indices):
            raise task._error(
                "Requested value is not a supported value for this property.\n"
                f"Property: DAQmx_AI_TermCfg\nRequested Value: {terminal.name}\n"
                f"Channel Name: {physical_channel}\n"
                "In differential mode ai0-ai3 pair with ai4-ai7.",
                DAQmxErrors.INVALID_ATTRIBUTE_VALUE,
            )
        # DAQmx picks the smallest hardware range holding [min_val, max_val].
        fitting = [r for r in ranges if -r <= min_val and max_val <= r]
        if not fitting or not min_val < max_val:
            prop, value = (
                ("DAQmx_AI_Min", min_val) if min_val < -ranges[-1] else ("DAQmx_AI_Max", max_val)
            )
            raise task._error(
                "Requested value is not a supported value for this property.\n"
                f"Property: {prop}\nRequested Value: {value}\n"
                f"Possible Values: -{ranges[-1]} to {ranges[-1]} ({terminal.name})",
                DAQmxErrors.INVALID_ATTRIBUTE_VALUE,
            )
        if units != VoltageUnits.VOLTS or custom_scale_name:
            raise ValueError("SimDaqTask simulates voltage channels in volts only")
        bits = RSE_ADC_BITS if terminal == TerminalConfiguration.RSE else ADC_BITS
        added = [_Channel(f"{task.device}/ai{i}", min(fitting), bits, terminal) for i in indices]
        self._channels.extend(added)
        return SimAIChannel(task, added)

    def _parse(self, physical_channel: str) -> list[int]:
        task = self._task
        match = _CHANNEL_RE.match(str(physical_channel).strip())
        if match is None:
            raise task._error(
                "Physical channel name is invalid.\n"
                f"Physical Channel Name: {physical_channel}\n"
                f"Use names like {task.device}/ai0 or {task.device}/ai0:1.",
                DAQmxErrors.PHYSICAL_CHAN_DOES_NOT_EXIST,
            )
        if match["dev"].lower() != task.device.lower():
            raise task._error(
                f"Device identifier is invalid.\nDevice Specified: {match['dev']}\n"
                f"Suggested Device(s): {task.device}",
                DAQmxErrors.INVALID_DEVICE_ID,
            )
        first = int(match["first"])
        last = int(match["last"]) if match["last"] is not None else first
        step = 1 if last >= first else -1
        indices = list(range(first, last + step, step))
        if any(i >= N_AI_RSE for i in indices):
            raise task._error(
                "Physical channel specified does not exist on this device.\n"
                f"Physical Channel Name: {physical_channel}\n"
                f"Device: {task.device}\nAvailable: ai0 to ai{N_AI_RSE - 1}",
                DAQmxErrors.PHYSICAL_CHAN_DOES_NOT_EXIST,
            )
        return indices


class SimTiming:
    """``task.timing``: the sample clock."""

    def __init__(self, task: SimDaqTask) -> None:
        self._task = task
        self.samp_clk_rate = 1000.0
        self.samp_quant_samp_per_chan = 1000

    def cfg_samp_clk_timing(
        self,
        rate,
        source="",
        active_edge=Edge.RISING,
        sample_mode=AcquisitionType.FINITE,
        samps_per_chan=1000,
    ):
        self._task._check_open()
        if sample_mode != AcquisitionType.CONTINUOUS or source:
            raise ValueError(
                "SimDaqTask simulates continuous acquisition on the internal sample clock only"
            )
        self.samp_clk_rate = coerced_rate_hz(float(rate))
        self.samp_quant_samp_per_chan = int(samps_per_chan)


class SimInStream:
    """``task.in_stream``: what a read can see."""

    def __init__(self, task: SimDaqTask) -> None:
        self._task = task

    @property
    def num_chans(self) -> int:
        return len(self._task.ai_channels)

    @property
    def avail_samp_per_chan(self) -> int:
        task = self._task
        task._check_open()
        if not task._running:
            return 0
        available = min(task._delivered() - task._read_pos, task._buffer_size)
        if available == 0:
            task._check_reachable()
        return available

    @property
    def total_samp_per_chan_acquired(self) -> int:
        task = self._task
        task._check_open()
        task._check_reachable()
        return task._delivered() if task._running else 0


class SimAnalogMultiChannelReader:
    """``AnalogMultiChannelReader`` over a ``SimDaqTask``'s in_stream, same signatures."""

    def __init__(self, task_in_stream: SimInStream) -> None:
        self._task = task_in_stream._task
        self.verify_array_shape = True

    def read_many_sample(
        self, data, number_of_samples_per_channel=READ_ALL_AVAILABLE, timeout=10.0
    ):
        return self._task._read_into(data, number_of_samples_per_channel, timeout, self)


class SimDaqTask:
    """A USB-6009 analog-input task whose MPX5100 sees ``pressure_kpa_at(t_s)``.

    ``pressure_kpa_at`` takes an array of sample times on ``clock`` (increasing from call
    to call, never later than ``clock.now()``) and returns the true gauge pressure in kPa
    at each. The sensor's output is wired to ``output_channel`` and its supply (measured
    for ratiometric conversion) to ``supply_channel``; any other input reads 0 V plus
    noise. ``noise_kpa`` is the electrical noise at the input, expressed in kPa of the
    sensor's output; ``offset_error_kpa`` is the sensor's zero error that zeroing removes.
    ``other_signals`` wires more instruments (a load cell's amplifier) to other inputs:
    channel name -> the volts at an array of sample times.
    """

    def __init__(
        self,
        clock: Clock,
        pressure_kpa_at: Callable[[np.ndarray], np.ndarray],
        *,
        supply_v: float = 5.0,
        noise_kpa: float = 0.05,
        offset_error_kpa: float = 0.8,
        seed: int | None = None,
        device: str = "Dev1",
        output_channel: str = "Dev1/ai0",
        supply_channel: str | None = "Dev1/ai1",
        new_task_name: str = "",
        clock_error_ppm: float = 0.0,
        other_signals: dict[str, Callable[[np.ndarray], np.ndarray]] | None = None,
        transfer_latency_s: tuple[float, float] = (0.0, 0.0),
        pull_up_kohm: float | None = None,
    ) -> None:
        self.clock = clock
        self.pull_up_kohm = pull_up_kohm
        self.pressure_kpa_at = pressure_kpa_at
        self.supply_v = float(supply_v)
        self.noise_kpa = float(noise_kpa)
        self.offset_error_kpa = float(offset_error_kpa)
        self.device = device
        self.output_channel = output_channel.strip("/").lower()
        self.supply_channel = supply_channel.strip("/").lower() if supply_channel else None
        self.clock_error_ppm = float(clock_error_ppm)
        self.transfer_latency_s = (float(transfer_latency_s[0]), float(transfer_latency_s[1]))
        self._latency_rng = np.random.default_rng(None if seed is None else [seed, 6008])
        self._delivered_n = 0
        # more instruments on other inputs: channel -> volts at the sample times
        self.other_signals = {
            name.strip("/").lower(): signal for name, signal in (other_signals or {}).items()
        }
        self._name = new_task_name or "_unnamedTask<0>"
        self._rng = np.random.default_rng(seed)
        self.ai_channels = SimAIChannelCollection(self)
        self.timing = SimTiming(self)
        self.in_stream = SimInStream(self)
        self._closed = False
        self._running = False
        self._t_start_s = 0.0
        self._read_pos = 0
        self._buffer_size = 0
        self._overflowed = False
        self._overflow_code = DAQmxErrors.SAMPLES_NO_LONGER_AVAILABLE
        self._timeout_pending = False
        self._timeout_delivers = 0
        self._failure: str | None = None
        self._failed_at_s = float("inf")
        self._frozen_v: np.ndarray | None = None  # per channel, once frozen
        # the open input's own noise, drawn apart so a healthy run's samples do not change
        self._floating_rng = np.random.default_rng(None if seed is None else [seed, 6009])
        self._hum_phase = float(self._floating_rng.uniform(0.0, 2 * np.pi))

    # -- the nidaqmx.Task surface -------------------------------------------------------

    @property
    def name(self) -> str:
        return self._name

    @property
    def channel_names(self) -> list[str]:
        return [c.physical for c in self.ai_channels._channels]

    def control(self, action: TaskMode) -> None:
        """``Task.control``: verify/commit/reserve check the configuration as start does
        (DAQmx's errors), start/stop/abort run or stop the task."""
        self._check_open()
        if action == TaskMode.TASK_START:
            self.start()
        elif action in (TaskMode.TASK_STOP, TaskMode.TASK_ABORT):
            self._running = False
        elif action in (TaskMode.TASK_VERIFY, TaskMode.TASK_COMMIT, TaskMode.TASK_RESERVE):
            self._verify()

    def start(self) -> None:
        self._check_open()
        self._check_reachable()
        if self._running:
            return
        self._verify()
        rate = self.timing.samp_clk_rate
        self._buffer_size = max(self.timing.samp_quant_samp_per_chan, default_buffer_size(rate))
        self._read_pos = 0
        self._delivered_n = 0
        self._overflowed = False
        self._running = True
        self._t_start_s = self.clock.now()

    def _verify(self) -> None:
        n_chans = len(self.ai_channels)
        if n_chans == 0:
            raise self._error(
                "Task contains no channels: add a channel before starting.",
                DAQmxErrors.INVALID_TASK,
            )
        rate = self.timing.samp_clk_rate
        if rate < MIN_RATE_HZ:
            raise self._error(
                "Requested value is not a supported value for this property.\n"
                f"Property: DAQmx_SampClk_Rate\nRequested Value: {rate}\n"
                f"Minimum: {MIN_RATE_HZ}",
                DAQmxErrors.INVALID_ATTRIBUTE_VALUE,
            )
        if rate * n_chans > MAX_AGGREGATE_RATE_HZ:
            raise self._error(
                "Sample rate is too high for the number of channels specified.\n"
                f"Sample Rate: {rate}\nNumber of Channels: {n_chans}\n"
                f"Maximum Aggregate Rate: {MAX_AGGREGATE_RATE_HZ:g}",
                DAQmxErrors.SAMPLE_RATE_NUM_CHANS_CONVERT_PERIOD_COMBO,
            )

    def stop(self) -> None:
        self._check_open()
        self._running = False
        self._check_reachable()

    def close(self) -> None:
        self._running = False
        self._closed = True
        self._check_reachable()

    def __enter__(self) -> SimDaqTask:
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()

    # -- fault injection ---------------------------------------------------------------

    def inject_overflow(self, code: DAQmxErrors = DAQmxErrors.SAMPLES_NO_LONGER_AVAILABLE) -> None:
        """The next read fails as if samples were lost: the host buffer overwritten
        (-200279, the default) or, with ``INPUT_FIFO_OVERFLOW_2`` (-200361), the
        device's FIFO overflowed because USB did not take its data in time."""
        self._overflowed = True
        self._overflow_code = code

    def inject_read_timeout(self, n_delivered: int = 0) -> None:
        """The next read that asks for samples gets at most ``n_delivered`` of them (of
        those acquired): it waits its timeout, then fails (-200284) saying how many it
        returned, as DAQmx does."""
        self._timeout_pending = True
        self._timeout_delivers = int(n_delivered)

    def fail(self, failure: str, at_s: float | None = None) -> None:
        """One of ``FAILURES`` from clock time ``at_s`` (default now) on."""
        if failure not in FAILURES:
            raise ValueError(f"unknown DAQ failure {failure!r}: one of {FAILURES}")
        self._failure = failure
        self._failed_at_s = self.clock.now() if at_s is None else float(at_s)

    def _check_reachable(self) -> None:
        """After a vanish: everything but reading the host buffer fails."""
        if self._failure == "vanish" and self.clock.now() >= self._failed_at_s:
            raise self._error(
                "Device cannot be accessed.\nPossible causes:\nDevice is no longer present "
                f"in the system.\nDevice is not powered.\nDevice: {self.device}",
                DAQmxErrors.DEV_CANNOT_BE_ACCESSED,
            )

    # -- the simulation -----------------------------------------------------------------

    def _device_rate_hz(self) -> float:
        """The rate the sample clock really runs at, measured on the host clock."""
        return self.timing.samp_clk_rate * (1.0 + 1e-6 * self.clock_error_ppm)

    def _acquired(self, at_s: float | None = None) -> int:
        """Samples taken from the start to ``at_s`` (default now): sample k is taken at
        t_start + k/rate (none after a stall or a vanish)."""
        now_s = self.clock.now() if at_s is None else at_s
        if self._failure in ("stall", "vanish"):
            now_s = min(now_s, self._failed_at_s)
        elapsed_s = now_s - self._t_start_s
        return max(0, int(np.floor(elapsed_s * self._device_rate_hz())) + 1)

    def _delivered(self) -> int:
        """Samples that have reached the host: those taken a transfer latency ago (drawn
        anew at each query, never fewer than before)."""
        low_s, high_s = self.transfer_latency_s
        if high_s <= 0:
            return self._acquired()
        latency_s = self._latency_rng.uniform(low_s, high_s)
        self._delivered_n = max(self._delivered_n, self._acquired(self.clock.now() - latency_s))
        return self._delivered_n

    def _read_into(self, data, n_requested, timeout, reader) -> int:
        self._check_open()
        if not self._running:
            self.start()  # DAQmx Read starts a task that was not started
        n_chans = len(self.ai_channels)
        read_available = n_requested == READ_ALL_AVAILABLE
        if read_available:
            n_requested = self.in_stream.avail_samp_per_chan
        if reader.verify_array_shape and data.shape != (n_chans, n_requested):
            raise self._error(
                "Read cannot be performed because the NumPy array passed into this function "
                "is not shaped correctly.\n\n"
                f"Shape of NumPy Array provided: {data.shape}\n"
                f"Shape of NumPy Array required: {(n_chans, n_requested)}",
                DAQmxErrors.UNKNOWN,
            )
        if self._timeout_pending and not read_available:
            self._timeout_pending = False
            n_got = min(self._timeout_delivers, n_requested, self._delivered() - self._read_pos)
            self._generate(data[:, :n_got], n_got)
            self.clock.sleep(timeout)
            raise self._read_timeout(timeout, n_got)
        self._check_overflow()
        deadline_s = self.clock.now() + timeout
        rate = self._device_rate_hz()
        while self._delivered() - self._read_pos < n_requested:
            wait_s = (self._read_pos + n_requested) / rate - (self.clock.now() - self._t_start_s)
            wait_s += self.transfer_latency_s[0]
            remaining_s = deadline_s - self.clock.now()
            if remaining_s <= 0:
                n_got = self._delivered() - self._read_pos
                self._generate(data[:, :n_got], n_got)
                raise self._read_timeout(timeout, n_got)
            self.clock.sleep(min(max(wait_s, 1e-4), remaining_s))
        self._check_overflow()
        self._generate(data, n_requested)
        return n_requested

    def _check_overflow(self) -> None:
        if self._overflowed or self._delivered() - self._read_pos > self._buffer_size:
            self._overflowed = True  # like DAQmx, the task stays in error until restarted
            code = self._overflow_code
            if code == DAQmxErrors.SAMPLES_NO_LONGER_AVAILABLE:
                message = (
                    "Attempted to read samples that are no longer available. The requested "
                    "sample was previously available, but has since been overwritten.\n"
                    "Increasing the buffer size, reading the data more frequently, or "
                    "specifying a fixed number of samples to read instead of reading all "
                    "available samples might correct the problem."
                )
            elif code == DAQmxErrors.ACQ_STOPPED_DRIVER_CANT_XFER_DATA_FAST_ENOUGH:
                message = (
                    "Acquisition has stopped because the driver could not transfer the data "
                    "from the device to the computer memory fast enough."
                )
            else:
                message = (
                    "Onboard device memory overflow. Because of system and/or bus-bandwidth "
                    "limitations, the driver could not read data from the device fast "
                    "enough to keep up with the device throughput.\n"
                    "Reduce your sample rate. If your data transfer method is interrupts, "
                    "try using DMA or USB Bulk."
                )
            raise DaqReadError(message, code.value, 0, task_name=self._name)

    def _read_timeout(self, timeout: float, n_read: int) -> DaqReadError:
        return DaqReadError(
            "Some or all of the samples requested have not yet been acquired.\n"
            "To wait for the samples to become available use a longer read timeout or read "
            f"later in your program.\nTimeout: {timeout}",
            DAQmxErrors.SAMPLES_NOT_YET_AVAILABLE,
            n_read,
            task_name=self._name,
        )

    def _generate(self, out: np.ndarray, n: int) -> None:
        """Fill ``out`` (channels x n) with the next n samples and advance the read position."""
        if n == 0:
            return
        k = np.arange(self._read_pos, self._read_pos + n)
        t_s = self._t_start_s + k / self._device_rate_hz()
        p_kpa = np.asarray(self.pressure_kpa_at(t_s), dtype=float) + self.offset_error_kpa
        noise_v = self.noise_kpa * mpx5100.SENSITIVITY_PER_KPA * self.supply_v
        failed = t_s >= self._failed_at_s
        for row, channel in enumerate(self.ai_channels._channels):
            name = channel.physical.lower()
            if name == self.output_channel:
                v = mpx5100.output_v(p_kpa, self.supply_v)
                cut = failed if self._failure in ("vout-cut", "supply-cut") else False
                if self._failure == "vout-floating":
                    v = np.where(failed, self.floating_input_v(t_s), v)
            elif name == self.supply_channel:
                v = np.full(n, self.supply_v)
                cut = failed if self._failure == "supply-cut" else False
            elif name in self.other_signals:
                v = np.asarray(self.other_signals[name](t_s), dtype=float)
                cut = False
            else:
                v = np.zeros(n)
                cut = False
            if cut is not False:  # shorted to ground, or a sensor without supply
                v = np.where(cut, 0.0, v)
            v = v + self._rng.normal(0.0, noise_v, n) if noise_v > 0 else v
            out[row, :n] = quantise(v, channel.range_v, channel.bits)
        if self._failure == "frozen" and failed.any():
            first = int(np.argmax(failed))
            if self._frozen_v is None:
                self._frozen_v = out[:, max(first - 1, 0)].copy()  # the last good codes
            out[:, first:n] = self._frozen_v[:, None]
        self._read_pos += n

    def floating_input_v(self, t_s: np.ndarray) -> np.ndarray:
        """What an open input reads at the sample times ``t_s``: the input network's
        1.40 V, mains hum and broadband noise (``FLOATING_*``); with a pull-up to the
        sensor's supply (``pull_up_kohm``), the divider of the two, and the pick-up
        smaller in the ratio of the node's impedance to the bare input's."""
        level_v, pickup = FLOATING_INPUT_V, 1.0
        if self.pull_up_kohm is not None:
            level_v, node_kohm = open_input_v(self.supply_v, self.pull_up_kohm)
            pickup = node_kohm / INPUT_IMPEDANCE_KOHM
        hum_v = FLOATING_HUM_V * np.sin(2 * np.pi * MAINS_HZ * t_s + self._hum_phase)
        noise_v = self._floating_rng.normal(0.0, FLOATING_NOISE_V, len(t_s))
        return level_v + pickup * (hum_v + noise_v)

    # -- helpers ------------------------------------------------------------------------

    def _check_open(self) -> None:
        if self._closed:
            raise self._error(
                "Task specified is invalid or does not exist.", DAQmxErrors.INVALID_TASK
            )

    def _error(self, message: str, code: DAQmxErrors) -> DaqError:
        return DaqError(message, code.value, task_name=self._name)


def open_input_v(supply_v: float, pull_up_kohm: float) -> tuple[float, float]:
    """An open input pulled up to ``supply_v``: its Thevenin voltage (the pull-up and the
    input network's 1.40 V behind 144 kOhm) and the node's impedance (kOhm)."""
    r_in, r_up = INPUT_IMPEDANCE_KOHM, float(pull_up_kohm)
    level_v = (supply_v * r_in + FLOATING_INPUT_V * r_up) / (r_in + r_up)
    return level_v, r_in * r_up / (r_in + r_up)


def coerced_rate_hz(rate_hz: float) -> float:
    """The sample clock rate DAQmx uses for a requested one: the timebase divided by
    the whole number that gives the nearest rate at or above it (DAQmx "coerces the
    Sample Clock rate to one that is valid"); rates it cannot coerce are left for
    ``start`` to refuse."""
    if not rate_hz > 0 or rate_hz > TIMEBASE_HZ:
        return rate_hz
    return TIMEBASE_HZ / max(1, int(TIMEBASE_HZ // rate_hz))


def quantise(v: np.ndarray, range_v: float, bits: int = ADC_BITS) -> np.ndarray:
    """What an n-bit ADC over ±range_v returns: the nearest code, saturating at the ends."""
    step_v = 2 * range_v / 2**bits
    # np.clip's steps, in place on one new array: a block's 200 samples cost what each
    # numpy call costs, whatever its length
    codes = v + range_v
    codes /= step_v
    np.rint(codes, out=codes)
    np.maximum(codes, 0, out=codes)
    np.minimum(codes, 2**bits - 1, out=codes)
    codes *= step_v
    codes -= range_v
    return codes
