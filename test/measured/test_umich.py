"""The real UMich SMART lab data through the shipped manifest (skipped without ../shared)."""
from dataclasses import replace
from pathlib import Path

import must_run
import numpy as np
import pytest

from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.measured.manifest import load_campaign
from feed_axis_energy.measured.csvload import load_run

REPO = Path(__file__).resolve().parents[2]
MANIFEST = REPO / 'config' / 'campaigns' / 'umich_mill.yaml'
DATA = (REPO.parent / 'shared' / 'data' / 'umich-cnc-mill').resolve()

pytestmark = must_run.skipif(
    'shared', not (DATA / 'experiment_01.csv').exists(),
    f'UMich CNC mill data not found at {DATA} (clone the repository next to shared/)')

# data rows per file (lines minus the header, counted with the csv module); the program
# filter drops none of them in these experiments
EXPECTED_ROWS = {'exp01': 1055, 'exp08': 605, 'exp09': 740, 'exp03': 1521, 'exp06': 1296}


def test_manifest_resolves_to_the_shared_data():
    c = load_campaign(MANIFEST)
    assert c.machine == (REPO / 'config' / 'umich_mill.yaml').resolve()
    assert [r.name for r in c.runs] == list(EXPECTED_ROWS)
    assert all(r.data.parent == DATA for r in c.runs)
    assert {r.name for r in c.runs_with_role('calibrate')} == {'exp01', 'exp08', 'exp09'}
    assert {r.name for r in c.runs_with_role('validate')} == {'exp03', 'exp06'}
    assert all(r.load_kg == 0.0 for r in c.runs)


@pytest.mark.parametrize('name', ['exp01', 'exp06'])
def test_runs_load_with_expected_rows_and_units(name):
    run = load_run(load_campaign(MANIFEST).run(name))
    n = EXPECTED_ROWS[name]
    assert run.t.shape == (n,) and run.extra['excluded_rows'] == 0
    np.testing.assert_allclose(np.diff(run.t), 0.1)
    assert run.axes == ('X', 'Y', 'Z') and run.power_axes == ('X', 'Y')
    assert run.power_w.shape == (n, 2) and run.command_position_m.shape == (n, 3)
    # published in kW, tens of watts at most; positions in mm, inside the travels seen
    assert 5.0 < np.abs(run.power_w).max() < 100.0
    assert 0.0 < run.position_m.min() and run.position_m.max() < 0.25


def test_exp01_peak_x_power_in_watts():
    run = load_run(load_campaign(MANIFEST).run('exp01'))
    assert run.power_w[:, 0].max() == pytest.approx(17.5)       # file: 1.75E-02 kW


def test_program_filter_on_the_interleaved_experiment_02():
    # experiment 02 mixes rows of programs 0, 1 and 4; keeping program 1 leaves 699 of 1668
    spec = load_campaign(MANIFEST).run('exp01')
    spec = replace(spec, name='exp02', data=DATA / 'experiment_02.csv', allow_gaps=True)
    run = load_run(spec)
    assert run.t.size == 699 and run.extra['excluded_rows'] == 1668 - 699
    assert run.extra['rows'][0] == 1 and run.extra['rows'][1] == 7   # rows 2-6 dropped


def test_machine_config_loads():
    m = load_machine(REPO / 'config' / 'umich_mill.yaml')
    assert [a.name for a in m.axes] == ['X', 'Y', 'Z']
