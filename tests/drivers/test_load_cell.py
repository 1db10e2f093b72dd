"""The load cell through the real driver (NiDaqPressureForce) and the nidaqmx API shape
of SimDaqTask: force and pressure on one task, the zero, the range flags, bad config."""

import numpy as np
import pytest

from labrig.drivers import load_cell
from labrig.drivers.ni_daq_force import NiDaqPressureForce
from labrig.errors import DeviceError, InputError
from labrig.sim.daq import SimAnalogMultiChannelReader, SimDaqTask
from labrig.sim.load_cell import LoadCellSignal
from labrig.time.virtual import VirtualClock

N_PER_V = 10.0  # a 100 N cell on a 0-10 V bridge amplifier
OFFSET_V = 0.05
# One ADC step of the USB-6009 in RSE (±10 V, 13 bits), in newtons.
QUANTUM_N = 20.0 / 2**13 * N_PER_V


def force_truth(t):
    return np.where(t > 1.0, 4.0 * (t - 1.0), 0.0)  # unloaded, then 4 N/s


def driver(clock, force_at=force_truth, offset_error_n=0.3, **kwargs):
    signal = LoadCellSignal(
        force_at, n_per_v=N_PER_V, offset_v=OFFSET_V, offset_error_n=offset_error_n, seed=3
    )

    def task_factory():
        return SimDaqTask(
            clock,
            lambda t: np.zeros_like(t),  # the line open to atmosphere
            noise_kpa=0.0,
            seed=1,
            other_signals={"Dev1/ai2": signal},
        )

    return NiDaqPressureForce(
        clock,
        "Dev1/ai0",
        supply_channel="Dev1/ai1",
        force_channel="Dev1/ai2",
        n_per_v=N_PER_V,
        offset_v=OFFSET_V,
        task_factory=task_factory,
        reader_factory=SimAnalogMultiChannelReader,
        **kwargs,
    )


def test_the_transfer_function_round_trips():
    f = np.array([-5.0, 0.0, 37.5, 100.0])
    v = load_cell.output_v(f, N_PER_V, OFFSET_V)
    assert v[1] == OFFSET_V
    np.testing.assert_allclose(load_cell.force_n(v, N_PER_V, OFFSET_V), f)


def test_force_is_read_with_the_pressure_zeroed_at_every_sample():
    clock = VirtualClock()
    daq = driver(clock)
    with clock.participate():
        daq.zero(0.5)  # unloaded: the amplifier's 0.3 N error is taken out
        assert daq.force_offset_n == pytest.approx(0.3, abs=QUANTUM_N)
        daq.start(1000.0)
        clock.sleep(3.0)
        block = daq.read()
        daq.stop()
    assert len(block.force_n) == len(block.t_s) == len(block.pressure_kpa) > 2900
    np.testing.assert_allclose(block.force_n, force_truth(block.t_s), atol=0.1 + QUANTUM_N)
    np.testing.assert_allclose(block.pressure_kpa, 0.0, atol=0.1)  # zeroed with the force
    assert not block.out_of_range.any()


def test_a_loaded_zero_is_refused_and_saturation_flagged():
    clock = VirtualClock()
    daq = driver(clock, force_at=lambda t: np.full_like(t, 12.0))
    with clock.participate(), pytest.raises(DeviceError, match="unload the actuator"):
        daq.zero(0.2)
    clock = VirtualClock()
    daq = driver(clock, force_at=lambda t: np.full_like(t, 150.0), offset_error_n=0.0)
    with clock.participate():
        daq.start(1000.0)
        clock.sleep(0.5)
        block = daq.read()
        daq.stop()
    assert block.out_of_range.all()  # the ADC clips at 10 V = 99.5 N; the cell is 100 N


def test_bad_configuration_is_refused():
    clock = VirtualClock()
    with pytest.raises(InputError, match="already the pressure's"):
        NiDaqPressureForce(clock, "Dev1/ai0", force_channel="Dev1/ai0", n_per_v=10.0)
    with pytest.raises(InputError, match="n_per_v"):
        NiDaqPressureForce(clock, "Dev1/ai0", force_channel="Dev1/ai2", n_per_v=0.0)
