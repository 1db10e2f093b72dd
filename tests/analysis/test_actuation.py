"""The 10-90 % actuation time against first-order responses, where it is tau ln 9."""

import numpy as np
import pytest

from labrig.analysis.actuation import step_response


def first_order(t, t_step, tau, before, after):
    return np.where(t < t_step, before, after + (before - after) * np.exp(-(t - t_step) / tau))


@pytest.mark.parametrize("tau", [0.05, 0.3, 1.0])
def test_a_first_order_step_takes_tau_ln_9(tau):
    t = np.arange(0.0, 4.0 + 10 * tau, 0.001)
    x = first_order(t, 2.0, tau, 39.0, 37.0)
    x += np.random.default_rng(0).normal(0, 0.05, t.size)  # the sensor's noise
    r = step_response(t, x, 2.0, t[-1], noise=0.2)
    assert r.change == pytest.approx(-2.0, abs=0.02)
    assert r.actuation_time_s == pytest.approx(tau * np.log(9), rel=0.05, abs=0.005)


def test_a_surge_and_ringing_before_the_change_do_not_count():
    t = np.arange(0.0, 6.0, 0.001)
    x = first_order(t, 2.3, 0.5, 39.0, 37.0)
    surge = (t > 2.0) & (t < 2.1)
    x[surge] += 4.0  # the push itself
    x += np.where(t > 2.1, 1.5 * np.exp(-(t - 2.1) / 0.05) * np.sin(60 * (t - 2.1)), 0)
    r = step_response(t, x, 2.0, t[-1], noise=0.2)
    assert r.actuation_time_s == pytest.approx(0.5 * np.log(9), rel=0.08)


def test_no_change_beyond_the_noise_has_no_time():
    t = np.arange(0.0, 4.0, 0.001)
    r = step_response(t, np.full_like(t, 39.0), 2.0, 4.0, noise=0.2)
    assert np.isnan(r.actuation_time_s)
