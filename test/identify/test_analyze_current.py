"""analyze on a current trace: the undeclared weight of a vertical axis is found and named.

A truth whose Y is vertical (test_torquefit's rig: current traces of X and Y with their
frictions) is analysed against a machine file that declares Y horizontal but knows the
frictions and the torque constants: the residual is the weight's holding current,
``m·g·lead/(2·pi)/kt`` at rest and while moving, which only ``gravity`` on Y explains
(``sin(theta) = 1``). The candidates are in their current form (identify/driveforms.py);
effects without one (standby, copper, iron, braking, time offset) are not tried. With the
KIT DMC 60H data (skipped without ../shared): a machine with Y declared horizontal, fitted by
fit-loss, and analyze names gravity on Y.
"""
from __future__ import annotations

import json
from pathlib import Path

import must_run
import numpy as np
import pytest
import yaml

import test_torquefit as rig
from feed_axis_energy.cli import main
from feed_axis_energy.identify import analyze_campaign, AnalyzeOptions
from feed_axis_energy.identify.driveforms import current_basis, has_current_form
from feed_axis_energy.measured import load_campaign

REPO = Path(__file__).resolve().parents[2]
KIT = (REPO.parent / 'shared' / 'data' / 'kit-dmc60h').resolve()


def _flat_y_campaign(tmp_path: Path, *, measures: str = 'current',
                     noise: float = 0.005) -> Path:
    manifest, _ = rig.write_fit_campaign(tmp_path, measures=measures, noise=noise)
    # the machine analysed: the truth's frictions, Y declared horizontal
    flat = rig._machine_text(rig.LOSS).replace('inclination_deg: 90.0', 'inclination_deg: 0.0')
    (tmp_path / 'machine.yaml').write_text(flat, encoding='utf-8')
    doc = yaml.safe_load(manifest.read_text(encoding='utf-8'))
    run = doc['runs'][0]
    # one record, two runs: its halves in time, each held out in turn
    first = dict(run, name='first', window={'end_fraction': 0.5})
    second = dict(run, name='second', window={'start_fraction': 0.5})
    doc['runs'] = [first, second]
    manifest.write_text(yaml.safe_dump(doc, sort_keys=False), encoding='utf-8')
    return manifest


def test_undeclared_weight_of_y_is_found_as_gravity(tmp_path):
    result = analyze_campaign(load_campaign(_flat_y_campaign(tmp_path)),
                              options=AnalyzeOptions(effects=('gravity', 'coulomb', 'viscous',
                                                              'mass_error', 'standby')))
    assert result.residual_unit == 'A'
    found = {(e.id, e.axis): e for e in result.effects}
    assert ('gravity', 'Y') in found, result.message
    sin_theta = {p.name: p.value for p in found[('gravity', 'Y')].params}['sin_theta']
    assert sin_theta == pytest.approx(1.0, abs=0.02)
    assert ('gravity', 'X') not in found
    assert 'gravity on Y' in result.message
    # standby has no current form: never a candidate
    assert all(f.effect != 'standby' for f in result.candidates)


@pytest.mark.parametrize('measures, noise, unit', [('torque', 5e-4, 'N·m'), ('force', 0.3, 'N')])
def test_undeclared_weight_is_found_on_torque_and_force_traces(tmp_path, measures, noise, unit):
    # the same truth as a torque or a force trace: the residual in that unit, the candidates
    # in their force form scaled by the trace's torque per unit (1, lead/(2·pi))
    result = analyze_campaign(load_campaign(_flat_y_campaign(tmp_path, measures=measures,
                                                             noise=noise)),
                              options=AnalyzeOptions(effects=('gravity', 'coulomb', 'viscous',
                                                              'mass_error', 'standby')))
    assert result.residual_unit == unit
    found = {(e.id, e.axis): e for e in result.effects}
    assert ('gravity', 'Y') in found, result.message
    sin_theta = {p.name: p.value for p in found[('gravity', 'Y')].params}['sin_theta']
    assert sin_theta == pytest.approx(1.0, abs=0.02)
    assert ('gravity', 'X') not in found


def test_current_form_by_hand():
    class State:
        velocity_m_s = np.array([[0.0], [0.02], [-0.01]])
        mass_kg = np.array([8.0])
        lead_m = np.array([0.005])
    r = 0.005 / (2.0 * np.pi)
    v = State.velocity_m_s[:, 0]
    # gravity: P = m·g·v per unit of sin(theta) -> m·g at rest and moving
    basis = (v * 8.0 * 9.80665)[:, None]
    got = current_basis('gravity', basis, State, 0, 0.08)[:, 0]
    np.testing.assert_allclose(got, 8.0 * 9.80665 * r / 0.08)
    # viscous: P = v² -> F = v, nothing at rest
    got = current_basis('viscous', (v * v)[:, None], State, 0, 0.08)[:, 0]
    np.testing.assert_allclose(got, v * r / 0.08)
    assert not has_current_form('standby') and has_current_form('coulomb')
    # offset_force: a constant force, held at rest as in motion; on a force trace (torque
    # per newton = lead/(2·pi)) the basis is the force itself, 1 N per newton of F0
    got = current_basis('offset_force', v[:, None], State, 0, r)[:, 0]
    np.testing.assert_allclose(got, 1.0)
    # a friction holds nothing at rest
    got = current_basis('coulomb', np.maximum(v, 0.0)[:, None], State, 0, r)[:, 0]
    np.testing.assert_allclose(got, [0.0, 1.0, 0.0])


@must_run.skipif('shared', not (KIT / 'I40_St_Val_Air_1_alldata_allcurrent.csv').exists(),
                 f'KIT DMC 60H data not found at {KIT}')
def test_kit_y_declared_horizontal_gravity_is_named(tmp_path, capsys):
    flat = (REPO / 'config' / 'kit_dmc60h.yaml').read_text(encoding='utf-8').replace(
        'inclination_deg: 90.0', 'inclination_deg: 0.0')
    machine = tmp_path / 'kit_flat.yaml'
    machine.write_text(flat, encoding='utf-8')
    manifest = (REPO / 'config' / 'campaigns' / 'kit_dmc60h.yaml').read_text(encoding='utf-8')
    manifest = manifest.replace('machine: ../kit_dmc60h.yaml', f'machine: {machine}').replace(
        'data: ../../../shared', f'data: {REPO.parent / "shared"}')
    campaign = tmp_path / 'kit.yaml'
    campaign.write_text(manifest, encoding='utf-8')
    fitted = tmp_path / 'fitted.yaml'
    assert main(['fit-loss', str(campaign), '--method', 'samples', '--fit-kt', '--json',
                 '--out-machine', str(fitted)]) == 0
    capsys.readouterr()
    assert main(['analyze', str(campaign), '--machine', str(fitted), '--json', '--quiet',
                 '--runs', 'val_air_1_first,val_air_1_second']) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc['residual_unit'] == 'A'
    added = {(e['id'], e['axis']) for e in doc['effects']}
    # the weight, or a constant force held at rest as in motion: one shape on runs that all
    # move the same mass (effects/aliases.py), named alone or as that group
    grouped = {m for g in doc['ambiguous'] for m in g['members']}
    assert ('gravity', 'Y') in added or {'gravity@Y', 'offset_force@Y'} <= grouped, \
        doc['message']
    assert 'gravity' in doc['message']
    assert not {('gravity', 'X'), ('offset_force', 'X')} & added
