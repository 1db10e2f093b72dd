"""MPX5100 pressure through an NI USB-6009: the labrig PressureSource on nidaqmx.

One analog-input voltage channel on the sensor's output (and optionally a second on
its supply, since the sensor is ratiometric), hardware-timed continuous acquisition,
blocks read into numpy through the stream reader and converted to kPa by
``labrig.drivers.mpx5100``.

The transport is a parameter: ``task_factory`` makes the task (default
``nidaqmx.Task``) and ``reader_factory`` wraps its ``in_stream`` (default
``nidaqmx.stream_readers.AnalogMultiChannelReader``). ``labrig.sim.daq`` supplies both
for a simulated rig; nothing else differs. nidaqmx is imported only when a task is
made, so importing this module is cheap and works without it.

What DAQmx really does is read back after the task is committed
(``TaskMode.TASK_COMMIT``: the configuration is checked and the device programmed, so
``start`` only starts it): the sample clock rate it coerced the requested one to
(``timing.samp_clk_rate``), and the hardware range and resolution of each channel
(``ai_rng_low``/``ai_rng_high``/``ai_resolution``: RSE on the USB-6009 is always ±10 V
at 13 bits, whatever was asked). Saturation is judged against that range.

Timestamps: the sample clock is the device's, so sample k of an acquisition is taken at
t_start + k/rate with the coerced rate. t_start is read on the shared clock around
``task.start()`` (the midpoint of the clock just before and just after the call): it is
uncertain by half the call's duration, a few ms on USB, the same for every sample. The
stamps never follow when a block reached the host: the USB-6009 counts a sample
(``avail_samp_per_chan``, ``total_samp_per_chan_acquired``) only once a USB transfer
brought it, 12-37 ms after it was taken, so a stamp taken from the newest counted
sample would be late by that. What the host clock can tell is the rate: the device's
crystal and the host's clock disagree by up to ~100 ppm (0.36 s an hour). Each read
notes the time its newest counted sample was seen; every ``DRIFT_CHECK_S`` the least
delayed of those sightings (the transfer latency at its smallest, nearly constant)
joins a line through the acquisition, whose slope is the sample period on the host
clock. Where it differs from the nominal period by more than the sightings' scatter
(and by less than any crystal can, ``MAX_CLOCK_DISAGREEMENT``), the stamps take that
period from t_start, slewed onto it over the next interval so they stay continuous
and increasing.
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Callable
from typing import Any

import numpy as np

from labrig.drivers import mpx5100
from labrig.errors import DeviceError, InputError
from labrig.rig.devices import PressureBlock
from labrig.time.clock import Clock

# DAQmx error codes the driver explains (nidaqmx.error_codes.DAQmxErrors).
SAMPLES_NOT_YET_AVAILABLE = -200284  # read timeout
OVERFLOW_CODES = {
    -200279: "SAMPLES_NO_LONGER_AVAILABLE",  # the host buffer was overwritten
    -200010: "INPUT_FIFO_OVERFLOW",  # the device's own FIFO
    -200361: "INPUT_FIFO_OVERFLOW_2",  # onboard memory overflow: USB did not keep up
    -200714: "ACQ_STOPPED_DRIVER_CANT_XFER_DATA_FAST_ENOUGH",
}
# The device is gone (unplugged, powered off, reset): DEV_CANNOT_BE_ACCESSED,
# DEV_ABSENT_OR_UNAVAILABLE, and a transfer the driver aborted because of it.
UNREACHABLE_CODES = (-201003, -200324, -50405)
TERMINALS = ("RSE", "DIFF")
log = logging.getLogger(__name__)
# How often (in clock seconds) the sample clock is checked against the host clock, how
# long a stretch of acquisition its rate is first judged over, and the largest
# disagreement believed: a crystal is off by ~1e-4, the host by less; a larger one
# means the sightings were delayed (a stalled host), not a drifting clock.
DRIFT_CHECK_S = 10.0
DRIFT_FIT_S = 30.0
MAX_CLOCK_DISAGREEMENT = 2e-3


class DaqNotInstalledError(DeviceError):
    """The NI-DAQmx driver (the C library nidaqmx calls) is missing on this machine."""


class DaqConfigError(DeviceError):
    """The device refused the channel, terminal configuration, range or rate."""


class DaqTimeoutError(DeviceError):
    """No samples arrived within the read timeout (DAQmx -200284)."""


class DaqOverflowError(DeviceError):
    """Samples were overwritten before they were read: the data has a gap."""


class DaqUnreachableError(DeviceError):
    """The device cannot be reached (DAQmx -201003 and kin): unplugged or unpowered."""


class DaqDeviceError(DeviceError):
    """Any other error DAQmx reported."""


def _daq_error() -> type[Exception]:
    """nidaqmx's DaqError, imported on first use."""
    from nidaqmx.errors import DaqError

    return DaqError


def _first_line(exc: Exception) -> str:
    return str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__


class NiDaqPressure:
    """An MPX5100 on a USB-6009 analog input, read as hardware-timed blocks in kPa.

    ``terminal`` is "RSE" (ai0-ai7, ±10 V only on this device) or "DIFF" (ai0-ai3,
    ±1 to ±20 V); it is always passed to DAQmx explicitly, with ``min_v``/``max_v``,
    because DAQmx's default on the USB-6009 is differential. ``supply_channel``, when
    given, measures the sensor's supply for the ratiometric conversion; otherwise
    ``supply_v`` is assumed.
    """

    def __init__(
        self,
        clock: Clock,
        channel: str = "Dev1/ai0",
        *,
        terminal: str = "RSE",
        min_v: float = -10.0,
        max_v: float = 10.0,
        supply_channel: str | None = None,
        supply_v: float = mpx5100.NOMINAL_SUPPLY_V,
        rate_hz: float = 1000.0,
        buffer_s: float = 10.0,
        read_timeout_s: float = 2.0,
        task_factory: Callable[[], Any] | None = None,
        reader_factory: Callable[[Any], Any] | None = None,
    ) -> None:
        terminal = str(terminal).upper()
        if terminal not in TERMINALS:
            raise InputError(f"pressure terminal: must be RSE or DIFF, got {terminal!r}")
        if not min_v < max_v:
            raise InputError(f"pressure input range: min_v {min_v} must be below max_v {max_v}")
        if not supply_v > 0:
            raise InputError(f"pressure supply_v: must be > 0 V, got {supply_v}")
        if not buffer_s > 0 or not read_timeout_s > 0:
            raise InputError("pressure buffer_s and read_timeout_s must be > 0 s")
        self.clock = clock
        self.channels = [channel] if supply_channel is None else [channel, supply_channel]
        self.supply_channel = supply_channel
        self.terminal = terminal
        self.min_v = float(min_v)
        self.max_v = float(max_v)
        self.supply_v = float(supply_v)
        self.rate_hz = self._check_rate(rate_hz)
        self.buffer_s = float(buffer_s)
        self.read_timeout_s = float(read_timeout_s)
        self.offset_kpa = 0.0
        self._task_factory = task_factory
        self._reader_factory = reader_factory
        self._task: Any = None
        self._reader: Any = None
        self.sample_clock_hz: float | None = None  # the coerced rate, once committed
        self.adc_ranges_v: list[tuple[float, float]] = []  # per channel, as DAQmx uses them
        self.adc_bits: list[int] = []
        self._t_start_s = 0.0
        self._start_slack_s = 0.0
        self._n_read = 0  # samples per channel read since the acquisition started
        self._unread: list[np.ndarray] = []  # read by zero() during a run, for read()
        # Stamps: sample k is at _anchor_t_s + (k - _anchor_k) * _s_per_sample, slewing
        # onto t_start + k * _period_s (the sample period on the host clock).
        self._anchor_k = 0
        self._anchor_t_s = 0.0
        self._s_per_sample = 0.0
        self._period_s = 0.0
        self._next_check_s = float("inf")
        # (k, host time) of the least delayed sighting of a newest counted sample: this
        # interval's, and each earlier interval's
        self._sighting: tuple[int, float] | None = None
        self._sightings: list[tuple[int, float]] = []

    # -- PressureSource ------------------------------------------------------------------

    def zero(self, duration_s: float = 1.0) -> float:
        """Average the next ``duration_s`` of readings, taken at atmospheric pressure, into
        the offset every later reading subtracts; returns it in kPa.

        Before ``start`` it runs its own short acquisition. During one it uses the running
        stream and keeps those samples for the next ``read``, so the record has no gap.
        """
        if not duration_s > 0:
            raise InputError(f"zero duration_s: must be > 0 s, got {duration_s}")
        n = max(1, round(duration_s * self.rate_hz))
        timeout_s = duration_s + self.read_timeout_s
        if self._task is not None:
            data = self._read_samples(n, timeout_s)
            self._unread.append(data)
        else:
            self._open(self.rate_hz)
            try:
                data = self._read_samples(n, timeout_s)
            finally:
                self.stop()
        self._take_zero(data)
        return self.offset_kpa

    def _take_zero(self, data: np.ndarray) -> None:
        """Set the offsets from ``data`` (channels x n volts) taken at atmosphere."""
        p_raw_kpa, adc_flags = self._to_raw_kpa(data)
        self.offset_kpa = mpx5100.zero_offset(p_raw_kpa, adc_flags).offset_kpa

    def start(self, rate_hz: float | None = None) -> None:
        """Start continuous acquisition at ``rate_hz`` (default: the configured rate)."""
        if self._task is not None:
            raise RuntimeError("acquisition already running: stop() it first")
        if rate_hz is not None:
            self.rate_hz = self._check_rate(rate_hz)
        self._open(self.rate_hz)

    def read(self) -> PressureBlock:
        """Every sample acquired since the last read, timestamped on the shared clock."""
        if self._task is None:
            raise RuntimeError("read() needs a running acquisition: call start() first")
        try:
            n = self._task.in_stream.avail_samp_per_chan
            seen_s = self.clock.now()
        except _daq_error() as exc:
            raise self._translate(exc, "reading the number of available samples") from exc
        if n > 0:
            self._sighted(self._n_read + n - 1, seen_s)
        blocks, self._unread = self._unread, []
        if n > 0:
            # n samples are in the buffer already: the read returns at once
            blocks.append(self._read_samples(n, timeout_s=self.read_timeout_s))
        if not blocks:
            block = self._block(np.empty((len(self.channels), 0)))
        else:
            block = self._block(np.concatenate(blocks, axis=1))
        if seen_s >= self._next_check_s:
            self._check_drift(seen_s)
        return block

    def stop(self) -> None:
        """Stop and release the task; safe to call at any time. A device that is gone
        fails both calls: the task is released all the same and the first error raised
        as a DeviceError."""
        task, self._task, self._reader = self._task, None, None
        if task is None:
            return
        failures = []
        for doing, call in (
            ("stopping the acquisition", task.stop),
            ("closing the task", task.close),
        ):
            try:
                call()
            except _daq_error() as exc:
                failures.append(self._translate(exc, doing))
        if failures:
            raise failures[0]

    # -- internals -----------------------------------------------------------------------

    @staticmethod
    def _check_rate(rate_hz: float) -> float:
        if not rate_hz > 0:
            raise InputError(f"pressure rate_hz: must be > 0 S/s, got {rate_hz}")
        return float(rate_hz)

    def _open(self, rate_hz: float) -> None:
        """Make, configure, commit and start the task, reading back what DAQmx coerced;
        every DAQmx error becomes a DeviceError."""
        import nidaqmx
        from nidaqmx.constants import AcquisitionType, TaskMode, TerminalConfiguration
        from nidaqmx.errors import DaqError, DaqNotFoundError, DaqNotSupportedError
        from nidaqmx.stream_readers import AnalogMultiChannelReader

        task_factory = self._task_factory or nidaqmx.Task
        reader_factory = self._reader_factory or AnalogMultiChannelReader
        try:
            task = task_factory()
        except (DaqNotFoundError, DaqNotSupportedError) as exc:
            raise DaqNotInstalledError(
                f"NI-DAQmx is not available ({_first_line(exc)}); install it with "
                "`python -m nidaqmx installdriver`, or run without hardware with --sim"
            ) from exc
        started = False
        try:
            added = [
                task.ai_channels.add_ai_voltage_chan(
                    channel,
                    terminal_config=TerminalConfiguration[self.terminal],
                    min_val=self.min_v,
                    max_val=self.max_v,
                )
                for channel in self.channels
            ]
            task.timing.cfg_samp_clk_timing(
                rate_hz,
                sample_mode=AcquisitionType.CONTINUOUS,
                samps_per_chan=max(2, round(rate_hz * self.buffer_s)),
            )
            # Everything slow happens here, so start() below is short and t_start sharp.
            task.control(TaskMode.TASK_COMMIT)
            sample_clock_hz = float(task.timing.samp_clk_rate)
            ranges_v = [(float(c.ai_rng_low), float(c.ai_rng_high)) for c in added]
            bits = [round(c.ai_resolution) for c in added]
            reader = reader_factory(task.in_stream)
            before_s = self.clock.now()
            task.start()
            after_s = self.clock.now()
            started = True
        except DaqError as exc:
            raise self._translate(exc, "configuring the acquisition", rate_hz) from exc
        finally:
            if not started:
                # a device that is gone fails this too: the first error says why
                with contextlib.suppress(DaqError):
                    task.close()
        self._task, self._reader = task, reader
        self.sample_clock_hz, self.adc_ranges_v, self.adc_bits = sample_clock_hz, ranges_v, bits
        self._t_start_s = 0.5 * (before_s + after_s)
        self._start_slack_s = 0.5 * (after_s - before_s)
        self._anchor_k, self._anchor_t_s = 0, self._t_start_s
        self._s_per_sample = self._period_s = 1.0 / sample_clock_hz
        self._next_check_s = self._t_start_s + DRIFT_CHECK_S
        self._sighting, self._sightings = None, []
        self._n_read = 0
        self._unread = []

    def _sighted(self, k: int, seen_s: float) -> None:
        """Sample ``k`` was counted by ``seen_s``: kept if it is this interval's least
        delayed sighting (its stamp closest to, or past, the moment it was seen)."""
        lead_s = self._stamp(k) - seen_s
        if self._sighting is None or lead_s > self._lead_s(self._sighting):
            self._sighting = (k, seen_s)

    def _lead_s(self, sighting: tuple[int, float]) -> float:
        return self._stamp(sighting[0]) - sighting[1]

    def _check_drift(self, now_s: float) -> None:
        """Judge the sample period on the host clock from the intervals' least delayed
        sightings, and slew the stamps onto t_start + k * period over the next interval."""
        self._next_check_s = now_s + DRIFT_CHECK_S
        if self._sighting is not None:
            self._sightings.append(self._sighting)
            self._sighting = None
        self._period_s = self._fitted_period_s()
        k_next = self._n_read
        t_next_s = self._stamp(k_next)
        error_s = self._t_start_s + k_next * self._period_s - t_next_s
        # below a nanosecond it is the rounding of the anchors, not time
        error_s = 0.0 if abs(error_s) < 1e-9 else error_s
        error_s = float(np.clip(error_s, -0.5 * DRIFT_CHECK_S, 0.5 * DRIFT_CHECK_S))
        self._anchor_k, self._anchor_t_s = k_next, t_next_s
        self._s_per_sample = self._period_s + error_s / (DRIFT_CHECK_S * self.sample_clock_hz)

    def _fitted_period_s(self) -> float:
        """The sample period on the host clock: the slope of the line through the
        intervals' sightings, once they span ``DRIFT_FIT_S``, where it differs from the
        nominal period by more than their scatter allows; else the period so far."""
        k = np.array([k for k, _ in self._sightings], dtype=float)
        seen_s = np.array([t for _, t in self._sightings])
        nominal_s = 1.0 / self.sample_clock_hz
        if len(k) < 3 or (k[-1] - k[0]) * nominal_s < DRIFT_FIT_S:
            return self._period_s
        period_s, intercept_s = np.polyfit(k, seen_s, 1)
        residual_s = seen_s - (intercept_s + period_s * k)
        # the line is known to the sightings' scatter, and each sighting to one sample
        # period (the newest counted sample was taken up to a period before), over the
        # span it covers
        known_s = (np.max(residual_s) - np.min(residual_s) + nominal_s) / (k[-1] - k[0])
        if abs(period_s - nominal_s) > MAX_CLOCK_DISAGREEMENT * nominal_s:
            log.warning(
                "the DAQ's sample clock seems %.0f ppm off the host clock: not believed",
                1e6 * (period_s / nominal_s - 1.0),
            )
            return self._period_s
        return nominal_s if abs(period_s - nominal_s) <= known_s else float(period_s)

    def _stamp(self, k):
        """The times of samples ``k`` (an array, or one number: the same arithmetic on
        Python floats, without a numpy call's cost for one sample)."""
        return self._anchor_t_s + (k - self._anchor_k) * self._s_per_sample

    def _read_samples(self, n: int, timeout_s: float) -> np.ndarray:
        """The next n samples per channel (channels x n volts), counted in ``_n_read``.
        A read that times out part-way has still taken what it returned from the
        buffer: those are counted and kept for the next ``read``, so later stamps
        stay right."""
        data = np.empty((len(self.channels), n))
        try:
            n_got = self._reader.read_many_sample(
                data, number_of_samples_per_channel=n, timeout=timeout_s
            )
        except _daq_error() as exc:
            n_partial = getattr(exc, "samps_per_chan_read", 0) or 0
            if n_partial > 0:
                self._n_read += n_partial
                self._unread.append(data[:, :n_partial])
            raise self._translate(exc, "reading samples") from exc
        data = data[:, :n_got]
        self._n_read += n_got
        return data

    def _to_raw_kpa(self, data: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Un-zeroed pressure from the volts, and where any channel was beyond the ADC's
        range as DAQmx set it up (not the narrower range asked for)."""
        sensor_rows = 2 if self.supply_channel is not None else 1
        v_supply = data[1] if sensor_rows == 2 else self.supply_v
        adc_flags = None  # the first row's flags are the start: no array of zeros
        for row in range(sensor_rows):
            (low_v, high_v), bits = self.adc_ranges_v[row], self.adc_bits[row]
            beyond = mpx5100.beyond_adc_range(data[row], low_v, high_v, bits)
            adc_flags = beyond if adc_flags is None else adc_flags | beyond
        return mpx5100.pressure_kpa(data[0], v_supply), adc_flags

    def _block(self, data: np.ndarray) -> PressureBlock:
        n = data.shape[1]
        k = np.arange(self._n_read - n, self._n_read)
        p_raw_kpa, adc_flags = self._to_raw_kpa(data)
        p_kpa = p_raw_kpa - self.offset_kpa
        # the output band is the sensor's own, before the zero is taken off
        wire_open = p_raw_kpa > mpx5100.BAND_TOP_KPA
        beyond = mpx5100.beyond_sensor_range(p_kpa) | wire_open
        return PressureBlock(
            t_s=self._stamp(k),
            pressure_kpa=p_kpa,
            out_of_range=adc_flags | beyond,
            wire_open=wire_open,
        )

    def _translate(self, exc: Exception, doing: str, rate_hz: float | None = None) -> DeviceError:
        """A DAQmx error as a DeviceError that says what happened and what to do."""
        code = exc.error_code
        what = f"DAQmx error {code} while {doing}: {_first_line(exc)}"
        if code in UNREACHABLE_CODES:
            return DaqUnreachableError(
                f"{what}; the DAQ cannot be reached: check that its USB cable is in and its "
                "light is on, and that it is listed (nilsdev, or NI MAX); then start again"
            )
        if code == SAMPLES_NOT_YET_AVAILABLE:
            return DaqTimeoutError(
                f"{what}; no samples within {self.read_timeout_s:g} s: check the USB cable "
                "and that no other program uses the device"
            )
        if code in OVERFLOW_CODES:
            return DaqOverflowError(
                f"{what}; samples were lost because they were not read in time: read more "
                "often or enlarge buffer_s, then restart the acquisition"
            )
        if rate_hz is not None:
            return DaqConfigError(
                f"{what}; asked for {', '.join(self.channels)} in {self.terminal} at "
                f"{self.min_v:g} to {self.max_v:g} V, {rate_hz:g} S/s: a USB-6009 takes "
                "ai0-ai7 in RSE (±10 V only) or ai0-ai3 in DIFF (±1 to ±20 V), at most "
                "48 kS/s in total"
            )
        return DaqDeviceError(what)
