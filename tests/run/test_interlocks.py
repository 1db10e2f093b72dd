"""Each interlock trips on its own condition; the monitor stops the pump once, from the
thread that saw the problem, and refuses a start that is already tripped."""

import threading

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from support.sensor_runs import infuse_judged, shipped_infusions

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


def samples(p_kpa, t0_s=0.0, out_of_range=None, wire_open=None):
    p = np.asarray(p_kpa, dtype=float)
    flags = np.zeros(len(p), bool) if out_of_range is None else np.asarray(out_of_range)
    if wire_open is not None:  # a cut wire's samples are beyond the band too
        wire_open = np.asarray(wire_open, bool)
        flags = flags | wire_open
    return PressureBlock(t0_s + np.arange(len(p)) * 0.001, p, flags, wire_open)


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


def test_a_cut_wire_reads_above_the_band_and_is_named_a_wire_not_a_high_pressure():
    """With the pull-up a cut output wire leaps from a pressure to above the sensor's
    band in one sample: the ceiling leaves it to the signal interlock, which names it."""
    # the driver flags both: beyond the band, and (raw, before the zero) a cut wire
    leap = samples([40.0, 40.1, 103.4, 103.3], t0_s=2.0, wire_open=[0, 0, 1, 1])
    assert PressureCeiling(95.0).check_pressure(leap) is None
    reason = interlocks.PressureSignal().check_pressure(leap)
    assert reason.startswith("pressure sensor wire open at t = 2.00 s: the reading 103.4 kPa")
    assert "pressure" in reason and "above the limit" not in reason
    # a pressure that rises through the limit is the ceiling's
    rising = samples([94.0, 95.5, 99.0, 103.4], out_of_range=[0, 0, 0, 1])
    assert PressureCeiling(95.0).check_pressure(rising).startswith("pressure 95.5 kPa above")
    # above the band after zeroing, but not before it (a zero taken 2 kPa low): a
    # pressure at the top of the sensor's range, which the driver does not call a wire
    high = samples([99.0, 101.0], out_of_range=[0, 1], wire_open=[0, 0])
    assert PressureCeiling(95.0).check_pressure(high).startswith("pressure 99.0 kPa above")
    named = interlocks.PressureSignal().check_pressure(high)
    assert named.startswith("pressure reading 101.0 kPa at t = 0.00 s is outside the sensor")


def test_a_frozen_reading_trips_only_after_a_dithering_one():
    rng = np.random.default_rng(5)
    live = np.round(20.0 + rng.normal(0.0, 0.05, 1000), 2)  # noise of about a step
    frozen = interlocks.PressureFrozen()
    assert frozen.check_pressure(samples(live)) is None
    reason = frozen.check_pressure(samples(np.full(400, live[-1]), t0_s=1.0))
    assert reason.startswith(f"pressure reading frozen at {live[-1]:.2f} kPa from t = 1.00 s")
    # a quiet sensor repeats its code on a flat pressure: never judged
    quiet = interlocks.PressureFrozen()
    steps = np.repeat(np.round(20.0 + np.arange(20) * 0.05, 2), 100)  # one step every 0.1 s
    assert quiet.check_pressure(samples(steps)) is None
    assert quiet.check_pressure(samples(np.full(2000, steps[-1]), t0_s=2.0)) is None


def frozen_verdict(t, p):
    """The frozen check's rule on the whole history at once (the samples of its last
    2.3 s): the run of one number that ends it, at least 0.3 s and 30 samples long, after
    a second of at least 30 samples whose noise (std of second differences over sqrt 6)
    is at least 0.035 kPa. The reason's first words, or None."""
    keep = t >= t[-1] - 2.3
    t, p = t[keep], p[keep]
    start = len(p) - 1
    while start > 0 and p[start - 1] == p[-1]:
        start -= 1
    if t[-1] - t[start] < 0.3 or len(p) - start < 30:
        return None
    arming = (t >= t[start] - 1.0) & (np.arange(len(t)) < start)
    if arming.sum() < 30:
        return None
    second = p[np.flatnonzero(arming)[0] : start]
    if np.std(np.diff(second, 2)) / np.sqrt(6) < 0.035:
        return None
    return f"pressure reading frozen at {p[-1]:.2f} kPa from t = {t[start]:.2f} s"


@settings(max_examples=60, deadline=None)
# frozen after a dithering second (and past the window, 2.3 s), with a gap, after too
# short a second, after a quiet one; then the drawn ones
@example(stretches=[("noisy", 1500), ("still", 3000)], cuts=[200], seed=1)
@example(stretches=[("noisy", 900), ("lost", 50), ("still", 600)], cuts=[37, 200], seed=2)
@example(stretches=[("still", 500), ("noisy", 29), ("still", 700)], cuts=[150], seed=3)
@example(
    stretches=[("quiet", 1500), ("still", 800), ("noisy", 60), ("still", 400)], cuts=[7], seed=4
)
@given(
    stretches=st.lists(
        st.tuples(st.sampled_from(["noisy", "still", "quiet", "lost"]), st.integers(1, 1500)),
        min_size=1,
        max_size=8,
    ),
    cuts=st.lists(st.integers(1, 400), min_size=1, max_size=30),
    seed=st.integers(0, 2**16),
)
def test_the_frozen_check_judges_every_block_as_the_whole_history(stretches, cuts, seed):
    """However the samples come in blocks, each block's verdict is the rule's on
    everything so far: the check keeps its run and its window from block to block."""
    rng = np.random.default_rng(seed)
    parts, level = [], 20.0
    for kind, n in stretches:
        if kind == "noisy":
            part = np.round(level + rng.normal(0.0, 0.06, n), 2)
        elif kind == "quiet":
            part = np.round(level + rng.normal(0.0, 0.004, n), 2)
        elif kind == "lost":
            part = np.full(n, np.nan)
        else:  # the last reading repeated, or a level of its own
            part = np.full(n, parts[-1][-1] if parts and rng.random() < 0.5 else round(level, 2))
        parts.append(part)
        level += rng.normal(0.0, 1.0)
    p = np.concatenate(parts)
    t = np.arange(len(p)) * 0.001
    frozen = interlocks.PressureFrozen()
    edges = np.cumsum(cuts * (len(p) // sum(cuts) + 1))
    start = 0
    for end in [*edges[edges < len(p)], len(p)]:
        flags = np.zeros(end - start, bool)
        reason = frozen.check_pressure(PressureBlock(t[start:end], p[start:end], flags))
        seen = np.isfinite(p[:end])
        expected = frozen_verdict(t[:end][seen], p[:end][seen]) if seen.any() else None
        assert (reason is None) == (expected is None)
        assert reason is None or reason.startswith(expected)
        start = end


def feed(interlock, pressure_at, legs, period_s=0.2):
    """Feed ``interlock`` as a run's loops do: a block of 1 kHz samples and a pump
    status every ``period_s`` along ``legs`` ((state, seconds, mL/min) one after the
    other); the specimen volume and the reason at the first trip, or None."""
    t, volume_ml = 0.0, 0.0
    for state, seconds, rate_ml_min in legs:
        end = t + seconds
        while t < end - 1e-9:
            t_block = t + np.arange(1, round(period_s * 1000) + 1) * 1e-3
            volume_at = volume_ml + (t_block - t) * rate_ml_min / 60
            block = PressureBlock(t_block, pressure_at(volume_at), np.zeros(len(t_block), bool))
            reason = interlock.check_pressure(block)
            t, volume_ml = float(t_block[-1]), float(volume_at[-1])
            reason = reason or interlock.check_pump(PumpStatus(t, state, 0.0, 0.0), volume_ml)
            if reason:
                return volume_ml, reason
    return None


INFUSING, WITHDRAWING = PumpState.INFUSING, PumpState.WITHDRAWING


def test_a_burst_trips_within_half_a_millilitre_and_a_snap_does_not():
    rng = np.random.default_rng(6)

    def burst(v):  # rises 5 kPa/mL, bursts at 12 mL
        return np.where(v < 12.0, 5.0 * v, 0.0) + rng.normal(0.0, 0.05, len(v))

    volume, reason = feed(interlocks.SpecimenPressure(), burst, [(INFUSING, 40.0, 30.0)])
    assert 12.3 <= volume <= 12.6
    assert reason.startswith("the specimen lost pressure: it fell from 59.9 kPa to ")
    assert " kPa at 12.00 mL and stayed below 12.0 kPa over 0.3" in reason

    def snap(v):  # at 12 mL the pressure falls to 40 % and rises again 2 kPa/mL
        return np.where(v < 12.0, 5.0 * v, 24.0 + 2.0 * (v - 12.0))

    assert feed(interlocks.SpecimenPressure(), snap, [(INFUSING, 40.0, 30.0)]) is None

    def deflating(v):  # withdrawn to nothing: the pressure falls to 0
        return np.maximum(5.0 * v, 0.0)

    legs = [(INFUSING, 20.0, 30.0), (WITHDRAWING, 20.0, -30.0)]
    assert feed(interlocks.SpecimenPressure(), deflating, legs) is None


def test_a_leak_shows_as_suction_while_volume_is_still_counted():
    """10 % of 10 mL lost: withdrawn, the specimen is empty with 1 mL still counted and
    the pump draws on it (20 kPa/mL below empty); a closed one reads 0 at the end."""
    legs = [(INFUSING, 20.0, 30.0), (WITHDRAWING, 20.0, -30.0)]

    def leaking(share):
        filled = []

        def pressure(v):  # what the specimen holds: the share lost once it is filled
            filled.append(bool(filled and filled[-1]) or v[-1] >= 9.99)
            held = v - share * 10.0 * filled[-1]
            return np.where(held > 0, 3.0 * held, 20.0 * held)

        return pressure

    volume, reason = feed(interlocks.SpecimenPressure(), leaking(0.1), legs)
    assert reason.startswith("the specimen leaks: withdrawing, the pressure fell to -")
    assert 0.8 <= volume <= 0.95
    assert feed(interlocks.SpecimenPressure(), leaking(0.0), legs) is None


def test_no_module_of_a_run_imports_the_model():
    """Nothing that runs or judges a run needs the specimen's model; only the dry run
    prints the model's peak before it, where the specimen has one."""
    import ast
    from pathlib import Path

    run_dir = Path(interlocks.__file__).parent
    for path in sorted(run_dir.glob("*.py")):
        if path.name == "dry_run.py":
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                names = [node.module or ""]
            else:
                continue
            assert not any(n.startswith("labrig.model") for n in names), (path.name, names)


@pytest.mark.parametrize(
    "seed", [0, pytest.param(1, marks=pytest.mark.soak), pytest.param(2, marks=pytest.mark.soak)]
)
def test_the_shipped_protocols_never_trip_the_run_interlocks_and_a_cut_wire_does(seed):
    infusions = shipped_infusions()
    assert {name for name, *_ in infusions} >= {"demo", "segment_characterization"}
    for name, protocol, step in infusions:
        assert infuse_judged(protocol, step, seed) is None, name
        # the wire cut at 3 mL: the pull-up holds the input above the band at once
        tripped_ml = infuse_judged(protocol, step, seed, floating_from_ml=3.0)
        assert tripped_ml is not None and 3.0 <= tripped_ml <= 3.0 + 0.4, (name, tripped_ml)


def test_a_cut_wire_on_the_simulated_rig_faults_the_run_with_the_pump_stopped(tmp_path):
    """The whole simulated rig: the runner's loops feed the interlocks, the wire is cut
    at 0.3 mL of the first infusion (60 mL/min), the run ends faulted as a wire fault
    within the next read with the plunger standing still."""
    from support.simrig import short_protocol, when_volume_exceeds

    from labrig.config.protocol import load_protocol
    from labrig.config.rig_file import sim_rig_config
    from labrig.rig.assembly import build_rig
    from labrig.run.runner import Runner

    path = tmp_path / "protocol.yaml"
    path.write_text(short_protocol())
    loaded = load_protocol(path)
    rig = build_rig(loaded.protocol, sim_rig_config(None, 0))
    runner = Runner(loaded, rig, tmp_path / "run.h5")
    emulator = rig.simulation.emulator
    cut_s = []

    def cut_the_wire():
        if when_volume_exceeds(rig, 0.3):
            cut_s.append(rig.clock.now())
            rig.simulation.daq_tasks[-1].fail("vout-floating")

    with rig.clock.participate():
        rig.clock.start_thread(cut_the_wire, "cut")
        result = runner.run()
    assert result.status == "faulted"
    assert result.reason.startswith("pressure sensor wire open")
    end_s = rig.clock.now()
    stopped_ml = emulator.net_volume_ml(end_s)
    assert emulator.net_volume_ml(end_s + 30.0) == stopped_ml  # the plunger stands still
    assert stopped_ml - emulator.net_volume_ml(cut_s[0]) <= 0.5


def suction_reference(blocks, counted_ml):
    """The leak's rule sample by sample, as written down: while withdrawing with more than
    LEAK_COUNTED_ML counted, LEAK_SUCTION_SAMPLES samples in a row below
    -LEAK_SUCTION_KPA, the first of them come down from atmosphere without a leap. The
    index (block, sample) of the sample that completes the run, or None."""
    if counted_ml <= interlocks.LEAK_COUNTED_ML:
        return None
    run, previous = 0, 0.0
    for b, p in enumerate(blocks):
        for i, p_kpa in enumerate(p):
            low = p_kpa < -interlocks.LEAK_SUCTION_KPA
            crossing = (
                previous >= -interlocks.LEAK_SUCTION_KPA
                and previous - p_kpa < interlocks.LEAK_MAX_STEP_KPA
            )
            run = 0 if not low else run + 1 if run or crossing else 0
            previous = p_kpa
            if run >= interlocks.LEAK_SUCTION_SAMPLES:
                return b, i
    return None


@settings(max_examples=300, deadline=None)
@given(
    blocks=st.lists(
        st.lists(
            # mostly below the threshold, in small steps and in leaps: runs of every length
            st.sampled_from([0.5, -0.99, -1.0, -1.01, -1.2, -1.5, -2.0, -2.9, -3.2, -4.4]),
            min_size=0,
            max_size=24,
        ),
        min_size=1,
        max_size=8,
    ),
    counted_ml=st.sampled_from([0.1, 0.2, 0.21, 3.0]),
)
def test_the_leak_trips_on_the_same_sample_as_judged_one_sample_at_a_time(blocks, counted_ml):
    """The suction rule, judged a block at a time (the samples before a block's first
    one below the threshold at once), trips at the sample the rule taken one sample at a
    time names, or not at all with it, across blocks of any length (empty ones too)."""
    interlock = interlocks.SpecimenPressure()
    interlock.check_pump(PumpStatus(0.0, WITHDRAWING, 0.0, 0.0), counted_ml)
    expected = suction_reference(blocks, counted_ml)
    tripped = None
    for b, p in enumerate(blocks):
        t_s = (b + np.arange(len(p)) / 100) * 1000  # names block and sample in the reason
        reason = interlock.check_pressure(PressureBlock(t_s, np.array(p), np.zeros(len(p), bool)))
        if reason is not None:
            tripped = divmod(round(float(reason.split("at t = ")[1].split(" s")[0]) / 10), 100)
            break
    assert tripped == expected
