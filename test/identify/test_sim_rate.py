"""How finely ``analyze`` simulates: the planner's rate, raised where the data resolve what
the simulation's own sampling changes in the meter's readings (docs/analyze.md, "The
simulation's own sampling")."""
from types import SimpleNamespace

import numpy as np
import pytest

from feed_axis_energy.identify.simrate import (MAX_OVERSAMPLING, MAX_SIM_SAMPLES,
                                               sampling_left, sim_rate, STEP_MAX_CHI2)
from feed_axis_energy.machine import load_machine
from feed_axis_energy.paths import config_dir


def _runs(sigma_w: float, step_w: float, *, n: int = 3000, count: int = 15,
          duration_s: float = 30.0) -> list[SimpleNamespace]:
    rng = np.random.default_rng(7)
    out = []
    for _ in range(count):
        sim = np.zeros((n, 1))
        meas = sim + rng.normal(0.0, sigma_w, size=(n, 1)) if sigma_w else sim.copy()
        out.append(SimpleNamespace(axes=('X',), power_meas_w=meas, power_sim_w=sim,
                                   signal_meas=meas, signal_sim=sim,
                                   step_error={'X': step_w}, sim_duration_s=duration_s))
    return out


@pytest.fixture(scope='module')
def machine():
    return load_machine(config_dir() / 'demonstrator.yaml')


def test_a_power_meter_s_noise_hides_the_sampling(machine):
    # 1.5 W of noise, 5 mW of sampling error over 45 000 stamps: chi2 0.5
    factor, chi2 = sim_rate(_runs(1.5, 0.005), machine)
    assert factor == 1 and chi2 == pytest.approx(15 * 3000 * (0.005 / 1.5) ** 2, rel=0.05)


def test_precise_data_get_the_smallest_factor_that_hides_it(machine):
    # 0.05 W: chi2 about 450; a factor f divides it by f^4: 2 leaves 28, 4 leaves 1.8
    factor, chi2 = sim_rate(_runs(0.05, 0.005), machine)
    assert chi2 == pytest.approx(450.0, rel=0.05)
    assert factor == 4 and chi2 / 4 ** 4 <= STEP_MAX_CHI2 < chi2 / 2 ** 4


def test_the_factor_is_capped_and_a_noiseless_trace_gives_no_nan(machine):
    factor, chi2 = sim_rate(_runs(0.0, 0.005), machine)
    assert factor == MAX_OVERSAMPLING and np.isfinite(chi2)
    # long records keep the planner's rate: 10 minutes at 2 kHz would exceed the budget
    long = _runs(0.05, 0.005, duration_s=600.0)
    assert 2 * machine.planner.rate_hz * 600.0 > MAX_SIM_SAMPLES
    assert sim_rate(long, machine)[0] == 1
    # nothing estimated: nothing raised
    assert sim_rate(_runs(0.05, 0.0), machine) == (1, 0.0)


def test_one_filter_step_takes_a_time_constant_most_of_the_way():
    # a meter that smooths with 5 ms reads strokes through a 10 ms window; compared through
    # a filter 30 us off, Gauss-Newton steps on the residual converge on it (docs/analyze.md,
    # "Starts, and a meter that smooths")
    from feed_axis_energy.identify.timing import filter_step
    from feed_axis_energy.measured import align_simulated
    t_sim = np.arange(0.0, 8.0, 1e-4)
    speed = np.clip(np.sin(2 * np.pi * 0.4 * t_sim) * 3.0, -1.0, 1.0)
    p_sim = 300.0 * speed ** 2 + 40.0 * np.gradient(speed, t_sim) * speed
    t_meas = np.arange(0.5, 7.5, 0.01)
    truth = 0.005

    def runs_at(guess):
        out = []
        for k in range(3):
            meas = align_simulated(t_sim, p_sim, t_meas, offset_s=0.0, window_s=0.01,
                                   filter_s=truth) + 2.0 * k
            sim = align_simulated(t_sim, p_sim, t_meas, offset_s=0.0, window_s=0.01,
                                  filter_s=guess)
            out.append(SimpleNamespace(offset=SimpleNamespace(anchor='motion'), t=t_meas,
                                       total_sim_w=sim, total_meas_w=meas))
        return out
    guess = truth + 30e-6
    step = filter_step(runs_at(guess), guess)
    # the derivative is taken on the 10 ms stamps: one step lands within 15 % of the error,
    # the next within a microsecond
    assert step is not None and abs(guess + step - truth) < 0.15 * 30e-6, step
    guess += step
    assert abs(guess + filter_step(runs_at(guess), guess) - truth) < 1e-6
    last = runs_at(guess)[0]
    meas, sim = last.total_meas_w, last.total_sim_w
    # runs aligned on the power only: nothing to step on
    power = [SimpleNamespace(offset=SimpleNamespace(anchor='power'), t=t_meas,
                             total_sim_w=sim, total_meas_w=meas)]
    assert filter_step(power, guess) is None


def test_filter_steps_that_converge_by_turns_are_extrapolated_to_their_limit():
    # the filter and the effects fitted with it converge by turns: each round's plain step
    # leaves rho of the error (about -0.2 on the smooth class); two plain steps give rho,
    # and the extrapolated step lands on the limit
    from feed_axis_energy.identify.timing import filter_next, FILTER_MAX_RATIO
    limit, tau, rho = 0.005, 0.0027, -0.23
    error = tau - limit
    first = -(1.0 - rho) * error                     # the round's step: to rho * error
    step, last = filter_next(first, None)
    assert step == first and last == first           # nothing to extrapolate from yet
    tau += step
    error = tau - limit
    second = -(1.0 - rho) * error
    step, last = filter_next(second, last)
    assert last is None and tau + step == pytest.approx(limit, abs=1e-12)
    # after an extrapolated step the next one is taken as it is
    assert filter_next(1e-6, None) == (1e-6, 1e-6)
    # steps that do not shrink, or shrink too slowly to extrapolate safely: as they are
    assert filter_next(2e-6, 1e-6) == (2e-6, 2e-6)
    assert filter_next(-1e-6, 1e-6) == (-1e-6, -1e-6)
    slow = (FILTER_MAX_RATIO + 0.1) * 1e-6
    assert filter_next(slow, 1e-6) == (slow, slow)


def test_sampling_left_falls_with_the_fourth_power_and_counts_only_above_the_limit() -> None:
    assert sampling_left(1.03e5, 4) == pytest.approx(1.03e5 / 256)
    assert sampling_left(STEP_MAX_CHI2 * 16, 2) == 0.0          # exactly at the limit
    assert sampling_left(29.0, 2) == 0.0
    assert sampling_left(float('nan'), 1) == 0.0
