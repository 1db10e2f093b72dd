"""Each interlock trips on its own condition; the monitor stops the pump once, from the
thread that saw the problem, and refuses a start that is already tripped."""

import threading

import numpy as np
import pytest

from labrig.rig.devices import PressureBlock, PumpState, PumpStatus
from labrig.run import interlocks
from labrig.run.interlocks import InterlockMonitor, PressureCeiling, PumpStall, VolumeCeiling


class RecordingPump:
    """Records stop() calls and the thread they came from (the monitor's only use)."""

    def __init__(self, fail=False):
        self.stops = []
        self.fail = fail

    def stop(self):
        self.stops.append(threading.current_thread().name)
        if self.fail:
            raise OSError("port lost")


def block(*pressures_kpa):
    p = np.array(pressures_kpa, dtype=float)
    return PressureBlock(np.arange(len(p)) * 0.001, p, np.zeros(len(p), bool))


def samples(p_kpa, t0_s=0.0, out_of_range=None):
    p = np.asarray(p_kpa, dtype=float)
    flags = np.zeros(len(p), bool) if out_of_range is None else np.asarray(out_of_range)
    return PressureBlock(t0_s + np.arange(len(p)) * 0.001, p, flags)


def status(infused=0.0, withdrawn=0.0, state=PumpState.INFUSING):
    return PumpStatus(12.5, state, infused, withdrawn)


def test_pressure_ceiling():
    ceiling = PressureCeiling(95.0)
    assert ceiling.check_pressure(block(10, 94.9, 95.0)) is None
    reason = ceiling.check_pressure(block(10, 96.25, 95.5))
    assert reason == "pressure 96.2 kPa above the limit 95 kPa at t = 0.00 s"
    assert ceiling.check_pressure(block()) is None


def test_volume_ceiling_counts_the_volume_before_the_last_clear():
    monitor = InterlockMonitor(RecordingPump(), [VolumeCeiling(50.0)])
    monitor.check_pump(status(infused=30.0))
    assert monitor.tripped is None
    monitor.volume_offset_ml = 25.0
    monitor.check_pump(status(infused=30.0, withdrawn=4.0))
    assert monitor.tripped.reason.startswith("volume 51.00 mL above the limit 50 mL")
    assert monitor.tripped.kind == "aborted"


def test_stall_is_a_fault():
    monitor = InterlockMonitor(RecordingPump(), [PumpStall()])
    monitor.check_pump(status(state=PumpState.INFUSING))
    assert monitor.tripped is None
    monitor.check_pump(status(state=PumpState.STALLED))
    assert monitor.tripped.kind == "faulted"
    assert "stalled" in monitor.tripped.reason


def test_first_trip_stops_the_pump_once_in_the_calling_thread():
    pump = RecordingPump()
    monitor = InterlockMonitor(pump, [PressureCeiling(50.0)])
    results = []

    def acquisition():
        monitor.check_pressure(block(80.0))
        results.append(monitor.trip("Ctrl-C", "aborted"))

    thread = threading.Thread(target=acquisition, name="acquisition")
    thread.start()
    thread.join()
    assert pump.stops == ["acquisition"]
    assert results == [False]
    assert monitor.tripped.reason.startswith("pressure 80.0 kPa")
    assert monitor.wait(0.0)


def test_a_failing_stop_is_kept_not_raised():
    monitor = InterlockMonitor(RecordingPump(fail=True), [])
    assert monitor.trip("serial port lost", "faulted")
    assert isinstance(monitor.stop_error, OSError)
    assert monitor.tripped.kind == "faulted"


@pytest.mark.parametrize(
    ("pump_status", "pressure", "expected"),
    [
        (status(state=PumpState.IDLE), block(1.0), None),
        (status(state=PumpState.STALLED), block(1.0), "pump stalled"),
        (status(infused=60.0, state=PumpState.IDLE), block(1.0), "volume 60.00 mL"),
        (status(state=PumpState.IDLE), block(99.0), "pressure 99.0 kPa"),
    ],
)
def test_start_is_refused_when_an_interlock_is_already_tripped(pump_status, pressure, expected):
    pump = RecordingPump()
    monitor = InterlockMonitor(pump, [PressureCeiling(95.0), VolumeCeiling(50.0), PumpStall()])
    reason = monitor.check_start(pump_status, pressure)
    if expected is None:
        assert reason is None
    else:
        assert expected in reason
    assert monitor.tripped is None and pump.stops == []


def test_a_reading_that_is_no_pressure_trips_the_signal_interlock():
    signal = interlocks.PressureSignal()
    assert signal.outcome == "faulted"
    assert signal.check_pressure(samples([0.3, 12.0, 40.0])) is None
    nan = signal.check_pressure(samples([12.0, 12.1, np.nan, 12.2], t0_s=3.0))
    assert nan.startswith("pressure signal lost at t = 3.00 s: the reading is not a number")
    # a cut output wire: -4.4 kPa less the zero offset, flagged by the driver
    low = signal.check_pressure(samples([12.0, -5.2], out_of_range=[False, True]))
    assert low.startswith("pressure reading -5.2 kPa at t = 0.00 s is outside the sensor's range")


def test_a_frozen_signal_trips_after_its_allowance_across_blocks():
    stuck = interlocks.PressureStuck(0.5, min_samples=50)
    rng = np.random.default_rng(0)
    live = np.round(20.0 + rng.normal(0.0, 0.05, 2000), 2)  # noise moves the last digits
    assert stuck.check_pressure(samples(live)) is None
    # frozen from 2.0 s on, read in 0.2 s blocks: trips in the block reaching 0.5 s
    tripped_at = None
    for k in range(5):
        reason = stuck.check_pressure(samples(np.full(200, 20.37), t0_s=2.0 + 0.2 * k))
        if reason and tripped_at is None:
            tripped_at = k
    assert tripped_at == 2  # samples 2.000 .. 2.599 s: 0.599 s of one number
    assert "stuck at 20.37 kPa" in reason and "since t = 2.00 s" in reason
    # too few samples to call it stuck (a slow acquisition): no trip
    slow = interlocks.PressureStuck(0.5, min_samples=50)
    few = PressureBlock(np.arange(10) * 0.1, np.full(10, 20.0), np.zeros(10, bool))
    assert slow.check_pressure(few) is None
