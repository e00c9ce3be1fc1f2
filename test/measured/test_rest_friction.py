"""A drive trace at rest: static friction, not the kinetic friction of a velocity's noise.

Velocities derived from measured positions are never exactly zero at rest; the kinetic
Coulomb friction ``F_c·sgn(v)`` of that noise would jump between ``±F_c`` from sample to
sample. On an axis with a declared standstill hold (``physics/standstill.py``), at rest
(``|v| <= REST_SPEED_M_S``) the predicted current holds the weight of an inclined axis and the
held force only; while moving it is unchanged. Without a declared hold the model is as it was
(a jerk-limited start from a plan passes below the rest speed and is motion). Checked by
hand: ``I = (m·g·sin(incl) + F_c·sgn(v))·lead/(2·pi)/kt`` moving, the weight plus the held
force at rest.
"""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.measured.quantity import predicted_signal
from feed_axis_energy.physics import REST_SPEED_M_S
from feed_axis_energy.plan import motion_from_samples
from feed_axis_energy.sim.simulate import simulate_motion

MACHINE = """\
name: rest
braking: regenerative
load_axis: X
planner: {profile: jerk, corner_tolerance_m: 1.0e-4, rate_hz: 100.0}
axes:
  X:
    table_mass_kg: 20.0
    rides_on: null
    inclination_deg: INCL
    screw: {diameter_m: 0.020, lead_m: 0.010, length_m: 0.6, starts: 1, efficiency: 1.0}
    inertias: {motor_kg_m2: 1.0e-4, coupling_kg_m2: 0.0, screw_kg_m2: 0.0}
    limits: {velocity_m_s: 0.5, acceleration_m_s2: 2.5, jerk_m_s3: 50.0}
    loss: {model: coulomb_viscous, coulomb_n: 50.0, viscous_n_s_m: 0.0}
"""
KT = 0.5
G0 = 9.80665


def _predict(tmp_path: Path, incl: float, v: np.ndarray, hold: float = 0.0) -> np.ndarray:
    file = tmp_path / 'm.yaml'
    file.write_text(MACHINE.replace('INCL', f'{incl:g}'), encoding='utf-8')
    machine = load_machine(file)
    if hold:
        axis = dataclasses.replace(machine.axis('X'), standstill_hold_n=hold)
        machine = dataclasses.replace(machine, axes=(axis,))
    t = np.arange(v.size) * 0.01
    pos = np.cumsum(v) * 0.01
    motion = motion_from_samples(t, pos[:, None], axes=('X',), vel=v[:, None],
                                 acc=np.zeros((v.size, 1)))
    sim = simulate_motion(motion, machine)
    return predicted_signal('current', sim, machine, ['X'], gains=[KT])[:, 0]


@pytest.mark.parametrize('incl', [0.0, 90.0])
def test_noise_at_rest_carries_no_coulomb_friction(tmp_path, incl):
    rng = np.random.default_rng(5)
    noise = rng.uniform(-0.5, 0.5, 400) * REST_SPEED_M_S      # at rest: below the rest speed
    moving = np.full(100, 0.02)                                  # 20 mm/s, steady
    v = np.concatenate([noise, moving])
    current = _predict(tmp_path, incl, v, hold=10.0)
    r = 0.010 / (2.0 * math.pi)
    weight = 20.0 * G0 * math.sin(math.radians(incl))
    # before the first move there is no last direction: the weight only
    np.testing.assert_allclose(current[:400], weight * r / KT, rtol=1e-9, atol=1e-12)
    # moving: the kinetic friction is there, as before
    np.testing.assert_allclose(current[400:], (weight + 50.0) * r / KT, rtol=1e-9)


def test_the_declared_hold_replaces_friction_at_rest(tmp_path):
    v = np.concatenate([np.full(50, -0.02), np.full(50, 3e-5), np.full(50, -3e-5)])
    current = _predict(tmp_path, 0.0, v, hold=30.0)
    r = 0.010 / (2.0 * math.pi)
    np.testing.assert_allclose(current[:50], -50.0 * r / KT, rtol=1e-9)
    # after moving in -, the drive holds 30 N in - whatever the sign of the noise
    np.testing.assert_allclose(current[50:], -30.0 * r / KT, rtol=1e-9)
