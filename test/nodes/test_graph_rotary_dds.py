"""The node graph with a rotary axis (over real DDS, its own ROS domain): the recorded
topics carry the rotary joints as ``simulate`` does (README topic table, docs/rotary.md)."""
from pathlib import Path
import subprocess
import sys

import must_run
import numpy as np

must_run.import_or_skip('rclpy', 'rclpy')

from feed_axis_energy.gcode.load import load_gcode  # noqa: E402
from feed_axis_energy.machine.file import load_machine  # noqa: E402
from feed_axis_energy.record import bagio  # noqa: E402
from feed_axis_energy.record.recording import simulation_series  # noqa: E402
from feed_axis_energy.sim.simulate import simulate_program  # noqa: E402

FIVE = Path(__file__).resolve().parents[2] / 'config' / 'five_axis_mill.yaml'


def test_graph_records_rotary_axes_as_offline(tmp_path, node_env, domain_id):
    program = tmp_path / 'rotary.nc'
    program.write_text('G21 G90 G94\nG1 X20 C90 F1200\nG1 B20 F1800\nG0 B0 C0\nM2\n')
    bag = tmp_path / 'record.crashsafe'
    out = subprocess.run(
        [sys.executable, '-m', 'feed_axis_energy', 'launch', '--program', str(program),
         '--machine', str(FIVE), '--record', str(bag), '--domain-id', str(domain_id),
         '--timeout', '40'], env=node_env, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stdout + out.stderr
    machine = load_machine(FIVE)
    result = simulate_program(load_gcode(program, **machine.gcode_keywords()), machine)
    for topic, ref in simulation_series(result).items():
        got = bagio.read_series(bag, topic)
        assert got.names == ref.names
        assert 'C' in got.names and 'B' in got.names
        for field in ('positions', 'velocities', 'accelerations', 'effort'):
            a, b = getattr(ref, field), getattr(got, field)
            assert (a is None) == (b is None), (topic, field)
            if a is not None:
                np.testing.assert_allclose(b, a, rtol=1e-9, atol=1e-12)
