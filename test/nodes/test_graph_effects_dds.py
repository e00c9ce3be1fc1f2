"""The graph accepts an augmented machine (declared effects) unchanged and matches offline."""
import subprocess
import sys

import must_run
import numpy as np
import yaml

must_run.import_or_skip('rclpy', 'rclpy')

from feed_axis_energy.record import bagio  # noqa: E402
from feed_axis_energy.gcode.load import load_gcode  # noqa: E402
from feed_axis_energy.machine.file import load_machine, machine_to_dict  # noqa: E402
from feed_axis_energy.sim.simulate import simulate_program  # noqa: E402
from feed_axis_energy.paths import default_machine  # noqa: E402


def test_launch_with_declared_effects_equals_offline(tmp_path, short_program, node_env,
                                                     domain_id):
    d = machine_to_dict(load_machine(default_machine()))
    d['effects'] = [{'id': 'load_friction', 'axis': 'X', 'params': {'mu': 0.1}},
                    {'id': 'standby', 'params': {'p0_w': 12.0}}]
    machine_file = tmp_path / 'augmented.yaml'
    machine_file.write_text(yaml.safe_dump(d))
    bag = tmp_path / 'bag'
    out = subprocess.run(
        [sys.executable, '-m', 'feed_axis_energy', 'launch', '--program', str(short_program),
         '--machine', str(machine_file), '--load-kg', '17.336', '--record', str(bag),
         '--domain-id', str(domain_id), '--timeout', '40'],
        env=node_env, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stdout + out.stderr
    machine = load_machine(machine_file)
    offline = simulate_program(load_gcode(short_program), machine, load_kg=17.336).power
    plain = simulate_program(load_gcode(short_program), load_machine(default_machine()),
                             load_kg=17.336).power
    got = bagio.read_series(bag, bagio.TOPIC_POWER)
    assert got.t.shape == offline.t.shape
    np.testing.assert_allclose(got.velocities[:, 0], offline.power_w[:, 0], rtol=1e-9,
                               atol=1e-12)
    np.testing.assert_allclose(got.positions[-1, -1], offline.total_energy_j[-1], rtol=1e-9)
    # ... and the effects are really in it: standby alone adds 12 W over the whole run.
    assert got.positions[-1, -1] > plain.total_energy_j[-1] + 12.0 * offline.t[-1] * 0.99
