"""A built wheel installed into a fresh venv works as the README says (issue 12, section 1).

Builds the wheel from a copy of the tracked sources (offline: the project venv's setuptools,
no build isolation), installs it with the ``ros`` extra into a fresh venv (pins from
constraints.txt; pip needs the package registries or its cache, the test skips with pip's
message when it cannot install), and runs from a directory outside the clone, with no
PYTHONPATH: ``simulate`` on the default machine (package data), ``compare --report`` on the
sample bags and a node ``--help``. About 2.5 minutes with a warm pip cache.
"""
from __future__ import annotations

import os
from pathlib import Path
import subprocess
import sys

import pytest

ROOT = Path(__file__).resolve().parents[2]
SOURCES = ['setup.py', 'setup.cfg', 'package.xml', 'resource', 'config', 'launch',
           'feed_axis_energy']
NETWORK_HINTS = ('Could not find a version', 'No matching distribution', 'connection',
                 'Connection', 'Temporary failure', 'Max retries', 'NewConnectionError')


def _run(cmd, *, cwd, timeout=600, env=None):
    return subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=timeout, check=False)


def _clean_env(venv: Path) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items()
           if k not in ('PYTHONPATH', 'VIRTUAL_ENV', 'PYTHONHOME')}
    env['PATH'] = f'{venv / "bin"}{os.pathsep}{env.get("PATH", "")}'
    return env


def _copy_tracked(dest: Path) -> None:
    listed = _run(['git', 'ls-files', '-z', *SOURCES], cwd=ROOT)
    if listed.returncode != 0 or not listed.stdout:
        pytest.skip(f'not a git checkout: {listed.stderr.strip()[:200]}')
    for name in listed.stdout.split('\0'):
        if not name:
            continue
        target = dest / name
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes((ROOT / name).read_bytes())


@pytest.fixture(scope='module')
def fresh_venv(tmp_path_factory) -> Path:
    """The wheel installed into a new venv; the venv's directory."""
    base = tmp_path_factory.mktemp('wheel')
    src, dist, venv = base / 'src', base / 'dist', base / 'venv'
    _copy_tracked(src)
    built = _run([sys.executable, '-m', 'pip', 'wheel', '--no-deps', '--no-build-isolation',
                  '--use-pep517', '--disable-pip-version-check', '-w', str(dist), str(src)],
                 cwd=base)
    if built.returncode != 0:
        pytest.skip(f'cannot build the wheel offline: {built.stderr.strip()[-400:]}')
    wheels = sorted(dist.glob('feed_axis_energy-*.whl'))
    assert len(wheels) == 1, built.stdout
    base_python = getattr(sys, '_base_executable', None) or 'python3'
    # no PYTHONPATH: with the clone on it, pip would take a feed_axis_energy.egg-info there
    # (left by an earlier build) for an installed copy and install nothing
    env = _clean_env(venv)
    made = _run([base_python, '-m', 'venv', str(venv)], cwd=base, env=env)
    assert made.returncode == 0, made.stderr
    installed = _run([str(venv / 'bin' / 'python'), '-m', 'pip', 'install', '--quiet',
                      '--disable-pip-version-check', f'{wheels[0]}[ros]',
                      '-c', str(ROOT / 'constraints.txt')], cwd=base, timeout=1200, env=env)
    if installed.returncode != 0:
        tail = installed.stderr.strip()[-400:]
        if any(hint in installed.stderr for hint in NETWORK_HINTS):
            pytest.skip(f'pip cannot reach the package registries: {tail}')
        pytest.fail(f'pip install of the wheel failed: {tail}')
    return venv


def test_wheel_holds_package_data_and_share(fresh_venv):
    env = _clean_env(fresh_venv)
    probe = _run([str(fresh_venv / 'bin' / 'python'), '-c',
                  'import feed_axis_energy, feed_axis_energy.paths as p; '
                  'print(feed_axis_energy.__file__); print(p.config_dir())'],
                 cwd=fresh_venv.parent, env=env)
    assert probe.returncode == 0, probe.stderr
    module, config = probe.stdout.split()
    site = fresh_venv / 'lib'
    # the installed copy, not the clone, and its configs are the wheel's package data
    assert Path(module).is_relative_to(site), module
    assert Path(config) == Path(module).parent / 'config'
    for name in ('graph.yaml', 'demonstrator.yaml', 'programs/demonstrator_f100.nc'):
        assert (Path(config) / name).is_file(), name
    share = fresh_venv / 'share' / 'feed_axis_energy'
    assert (share / 'package.xml').is_file()
    assert (share / 'launch' / 'feed_axis_energy.launch.py').is_file()


def test_wheel_simulate_default_machine(fresh_venv, tmp_path):
    env = _clean_env(fresh_venv)
    program = tmp_path / 'stroke.nc'
    # one 100 mm stroke and back at 100 mm/s on the default (demonstrator) machine
    program.write_text('G21 G90 G1 X100 F6000\nX0\nM2\n', encoding='utf-8')
    done = _run([str(fresh_venv / 'bin' / 'feed-axis-energy'), 'simulate', str(program),
                 '--json'], cwd=tmp_path, env=env)
    assert done.returncode == 0, done.stderr
    assert '"machine": "demonstrator"' in done.stdout
    assert '"energy_j"' in done.stdout


def test_wheel_compare_report(fresh_venv, tmp_path):
    env = _clean_env(fresh_venv)
    report = tmp_path / 'report'
    done = _run([str(fresh_venv / 'bin' / 'feed-axis-energy'), 'compare',
                 str(ROOT / 'bags' / 'umich_samples.yaml'), '--report', str(report),
                 '--quiet'], cwd=tmp_path, env=env)
    assert done.returncode == 0, done.stderr
    # one self-contained page: the plots are embedded PNGs (matplotlib works in the wheel)
    html = (report / 'index.html').read_text(encoding='utf-8')
    assert html.count('src="data:image/png;base64,') >= 3, sorted(report.iterdir())


@pytest.mark.parametrize('node', ['gcode_trajectory', 'mcap_recorder'])
def test_wheel_node_help(fresh_venv, tmp_path, node):
    env = _clean_env(fresh_venv)
    done = _run([str(fresh_venv / 'bin' / node), '--help'], cwd=tmp_path, env=env, timeout=120)
    assert done.returncode == 0, done.stderr
    assert f'ros2 run feed_axis_energy {node}' in done.stdout
    assert 'parameters (defaults from' in done.stdout
