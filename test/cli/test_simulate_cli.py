"""The ``feed-axis-energy simulate`` and ``demo`` commands, run as a user runs them."""
import json
from pathlib import Path
import subprocess
import sys

import numpy as np
from numpy.testing import assert_allclose
import pytest

from feed_axis_energy.cli import main
from feed_axis_energy.record import bagio
from feed_axis_energy.record.recording import SUMMARY_KEY

ROOT = Path(__file__).resolve().parents[2]
PROGRAM = ROOT / 'config' / 'programs' / 'demonstrator_f300.nc'


def _run(*argv: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, '-m', 'feed_axis_energy', *argv], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize('command', ['simulate', 'demo'])
def test_help_exits_zero(command: str) -> None:
    proc = _run(command, '--help')
    assert proc.returncode == 0
    assert 'usage: feed-axis-energy ' + command in proc.stdout


def test_simulate_bag_round_trip_matches_printed_energies(tmp_path: Path, capsys) -> None:
    out = tmp_path / 'run'
    # --method samples: the summary integrated over the recording's own samples
    assert main(['simulate', str(PROGRAM), '--load-kg', '17.336', '--out', str(out),
                 '--json', '--quiet', '--method', 'samples']) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary['method'] == 'samples'
    power = bagio.read_series(out, bagio.TOPIC_POWER)
    assert power.names == ('X', 'total')
    # every sample but those inside a standstill (recorded at 1 Hz: README simulate)
    assert summary['samples'] / 2 < power.t.shape[0] < summary['samples']
    assert_allclose(power.t[[0, -1]], [0.0, summary['duration_s']], atol=1e-9)
    assert np.diff(power.t).max() <= 1.0 + 1.5 / summary['rate_hz']
    # The last cumulative energy in the bag is the printed energy, per axis and in total.
    assert_allclose(power.positions[-1, 0], summary['energy_j']['X'], rtol=1e-12)
    assert_allclose(power.positions[-1, 1], summary['energy_j']['total'], rtol=1e-12)
    assert_allclose(np.max(power.velocities[:, 1]), summary['peak_power_w']['total'],
                    rtol=1e-12)
    blocks = bagio.read_block_energy(out)
    assert_allclose(sum(e for _, e, _ in blocks), summary['energy_j']['total'], rtol=1e-9)
    assert bagio.read_custom_data(out, SUMMARY_KEY)['energy_j'] == summary['energy_j']
    setpoints = bagio.read_series(out, bagio.TOPIC_SETPOINTS)
    np.testing.assert_array_equal(setpoints.t, power.t)
    # The program strokes 400 mm: the commanded position spans exactly that.
    assert_allclose(setpoints.positions[:, 0].max() - setpoints.positions[:, 0].min(), 0.4,
                    atol=1e-9)
    state = bagio.read_series(out, bagio.TOPIC_AXIS_STATE)
    assert state.names == ('X', 'X_screw')


def test_simulate_table_output_has_units() -> None:
    proc = _run('simulate', str(PROGRAM), '--quiet')
    assert proc.returncode == 0, proc.stderr
    for text in ('energy [J]', 'peak power [W]', 'duration', ' s ', 'blocks with the most'):
        assert text in proc.stdout


def test_bad_program_names_file_line_column(tmp_path: Path) -> None:
    bad = tmp_path / 'bad.nc'
    bad.write_text('G21 G90\nG1 X10 Q5 F100\n')
    proc = _run('simulate', str(bad))
    assert proc.returncode == 1
    assert f'{bad}:2:' in proc.stderr
    assert 'Traceback' not in proc.stderr


def test_missing_program_and_existing_out_fail_cleanly(tmp_path: Path) -> None:
    proc = _run('simulate', str(tmp_path / 'nope.nc'))
    assert proc.returncode == 1 and 'nope.nc' in proc.stderr
    (tmp_path / 'out').mkdir()
    proc = _run('simulate', str(PROGRAM), '--out', str(tmp_path / 'out'))
    assert proc.returncode == 1 and 'exists already' in proc.stderr


def test_negative_load_is_rejected() -> None:
    proc = _run('simulate', str(PROGRAM), '--load-kg', '-1')
    assert proc.returncode == 1 and 'load-kg' in proc.stderr


def test_load_changes_peak_power_but_not_regenerative_cycle_energy(capsys) -> None:
    # The paper's loss function depends on feed only, and a regenerative converter returns the
    # kinetic energy of every stroke: the cycle energy must not depend on the clamped mass,
    # while the acceleration peaks must grow with it.
    results = []
    for load in ('0', '22.711'):
        assert main(['simulate', str(PROGRAM), '--load-kg', load, '--json', '--quiet']) == 0
        results.append(json.loads(capsys.readouterr().out))
    assert_allclose(results[1]['energy_j']['total'], results[0]['energy_j']['total'],
                    rtol=1e-3)
    assert results[1]['peak_power_w']['total'] > results[0]['peak_power_w']['total']


def test_simulate_refuses_beyond_max_samples_before_starting(tmp_path: Path) -> None:
    week = tmp_path / 'week.nc'
    week.write_text('G1 X0.01 F600\nG4 P604800\nG1 X0\nM2\n')
    out = tmp_path / 'bag'
    proc = _run('simulate', str(week), '--max-samples', '1000000', '--out', str(out))
    assert proc.returncode == 1
    assert 'Traceback' not in proc.stderr
    assert 'week.nc' in proc.stderr and '--rate-hz' in proc.stderr
    assert '604,8' in proc.stderr           # the sample count from the plan
    assert not out.exists()


def test_simulate_streamed_json_equals_whole_summary(capsys) -> None:
    from feed_axis_energy.gcode.load import load_gcode
    from feed_axis_energy.machine.file import load_machine
    from feed_axis_energy.sim.simulate import simulate_program, summarize
    machine = load_machine(ROOT / 'config' / 'demonstrator.yaml')
    ref = summarize(simulate_program(load_gcode(PROGRAM), machine, load_kg=3.0))
    assert main(['simulate', str(PROGRAM), '--load-kg', '3', '--json', '--quiet',
                 '--method', 'samples']) == 0
    got = json.loads(capsys.readouterr().out)
    assert got['samples'] == ref['samples']
    assert_allclose(got['energy_j']['total'], ref['energy_j']['total'], rtol=1e-12)
    assert_allclose(got['loss_energy_j'], ref['loss_energy_j'], rtol=1e-12)
    # by phase (the default): the same grid, figures within the 1 kHz samples'
    # discretization (observed 2e-10 here: the demonstrator's strokes)
    assert main(['simulate', str(PROGRAM), '--load-kg', '3', '--json', '--quiet']) == 0
    phases = json.loads(capsys.readouterr().out)
    assert phases['method'] == 'phases' and phases['samples'] == ref['samples']
    assert_allclose(phases['energy_j']['total'], ref['energy_j']['total'], rtol=1e-8)
    assert_allclose(phases['loss_energy_j'], ref['loss_energy_j'], rtol=1e-8)
    assert phases['quadrature_error_j']['total'] < 1e-6 * phases['energy_j']['total']


def test_week_long_dwell_without_out(tmp_path: Path, capsys) -> None:
    week = tmp_path / 'week.nc'
    week.write_text('G1 X0.01 F600\nG4 P604800\nG1 X0\nM2\n')
    assert main(['simulate', str(week), '--json', '--quiet']) == 0
    got = json.loads(capsys.readouterr().out)
    assert got['samples'] > 604_800_000 and got['duration_s'] > 604800.0
    assert [b['line'] for b in got['top_blocks']][-1] == 2       # the dwell, 604 800 s
    assert got['top_blocks'][-1]['duration_s'] == pytest.approx(604800.0, abs=2e-3)


def test_simulate_report_with_out_agrees_with_the_summary(tmp_path: Path, capsys) -> None:
    report = tmp_path / 'report'
    contour = ROOT / 'config' / 'programs' / 'three_axis_contour.nc'
    assert main(['simulate', str(contour), '--machine', str(ROOT / 'config' /
                 'three_axis_mill.yaml'), '--load-kg', '50', '--report', str(report),
                 '--out', str(tmp_path / 'bag'), '--json', '--quiet']) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary['report'] == str(report / 'index.html')
    html = (report / 'index.html').read_text()
    for name in ('power.png', 'energy.png', 'path.png', 'blocks.png'):
        assert (report / name).read_bytes()[:4] == b'\x89PNG'
    total = summary['energy_j']['total']
    assert f'{total:.0f} J per part' in html or f'{total / 1e3:.3g} kJ per part' in html
    # the most energetic block is in the table with its source text
    top = summary['top_blocks'][0]['line']
    text = contour.read_text().splitlines()[top - 1].strip()
    assert f'<td class="num">{top}</td>' in html and text in html
    assert (tmp_path / 'bag').is_dir()


def test_simulate_report_refused_before_simulating(tmp_path: Path) -> None:
    (tmp_path / 'r').mkdir()
    (tmp_path / 'r' / 'mine.txt').write_text('keep')
    proc = _run('simulate', str(PROGRAM), '--report', str(tmp_path / 'r'), '--force')
    assert proc.returncode == 1 and '--report' in proc.stderr and 'Traceback' not in proc.stderr
    assert (tmp_path / 'r' / 'mine.txt').read_text() == 'keep'
    proc = _run('simulate', str(PROGRAM), '--quiet', '--report', str(tmp_path / 'new'))
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / 'new' / 'index.html').is_file()


def test_simulate_report_of_a_trajectory_csv(tmp_path: Path) -> None:
    csv = tmp_path / 'traj.csv'
    t = np.arange(0.0, 2.0, 0.001)
    x = 50.0 * (1.0 - np.cos(np.pi * t / 2.0))
    csv.write_text('time [s],X [mm]\n' + ''.join(f'{a:.4f},{b:.6f}\n' for a, b in zip(t, x)))
    proc = _run('simulate', str(csv), '--quiet', '--report', str(tmp_path / 'r'))
    assert proc.returncode == 0, proc.stderr
    html = (tmp_path / 'r' / 'index.html').read_text()
    assert 'No source lines' in html and 'travel range' in html


def test_a_failing_report_leaves_no_bag_behind(tmp_path: Path, monkeypatch, capsys) -> None:
    import feed_axis_energy.report as report
    from feed_axis_energy.errors import OutputError

    def broken(*args, **kwargs):
        raise OutputError('no space left on device', path=str(tmp_path / 'r'))

    monkeypatch.setattr(report, 'write_sim_report', broken)   # as simulate imports it
    assert main(['simulate', str(PROGRAM), '--quiet', '--out', str(tmp_path / 'bag'),
                 '--report', str(tmp_path / 'r')]) == 1
    assert 'no space left' in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_plot_rate_default_is_the_core_constant() -> None:
    from feed_axis_energy.cli.simulate import DEFAULT_PLOT_RATE_HZ
    from feed_axis_energy.record.plottopics import DEFAULT_PLOT_RATE_HZ as CORE
    assert DEFAULT_PLOT_RATE_HZ == CORE


@pytest.mark.parametrize('value', ['-1', 'fast', 'nan', 'inf'])
def test_plot_rate_refused_as_usage_error(value: str, tmp_path: Path) -> None:
    proc = _run('simulate', str(PROGRAM), '--out', str(tmp_path / 'b'), '--plot-rate-hz', value)
    assert proc.returncode == 2
    assert '--plot-rate-hz' in proc.stderr and 'Traceback' not in proc.stderr
    assert not (tmp_path / 'b').exists()


@pytest.mark.parametrize('plot_rate', ['0', '20', '500'])
def test_bag_size_estimate_is_an_upper_bound(plot_rate: str, tmp_path: Path, capsys) -> None:
    from feed_axis_energy.cli.simulate_out import bag_bytes_per_sample
    program = ROOT / 'config' / 'programs' / 'three_axis_contour.nc'
    out = tmp_path / 'b'
    assert main(['simulate', str(program), '--machine',
                 str(ROOT / 'config' / 'three_axis_mill.yaml'), '--out', str(out), '--json',
                 '--quiet', '--compression', 'none', '--plot-rate-hz', plot_rate]) == 0
    samples = json.loads(capsys.readouterr().out)['samples']
    size = sum(f.stat().st_size for f in out.rglob('*') if f.is_file())
    bound = samples * bag_bytes_per_sample(3, plot_rate_hz=float(plot_rate), rate_hz=1000.0)
    assert 0.5 * bound < size <= bound
