"""What ``analyze`` writes into the augmented machine config."""
from types import SimpleNamespace

from feed_axis_energy.machine.calibrated import CalibratedRange
from feed_axis_energy.effects.catalog import EFFECTS, get_effect
from feed_axis_energy.identify.results import AnalysisResult, FittedEffect, ParamEstimate
from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.paths import default_machine


def _fitted(effect_id: str, name: str, value: float, unit: str) -> FittedEffect:
    return FittedEffect(id=effect_id, axis='X',
                        params=(ParamEstimate(name, value, unit, 0.001, 'jackknife'),),
                        share_of_residual=0.5, share_of_structured=0.9,
                        heldout_gain_w2=1.0, heldout_gain_rel=0.5, heterogeneity=0.0)


def test_time_offset_is_reported_but_not_written_into_the_machine():
    machine = load_machine(default_machine())
    seen = CalibratedRange(feed_mm_s=(100.0, 500.0), load_kg=(0.0, 22.7),
                           position_m=(0.0, 0.4))
    fake = SimpleNamespace(machine=machine,
                           effects=(_fitted('load_friction', 'mu', 0.1, '-'),
                                    _fitted('time_offset', 'delta_s', 0.002, 's')),
                           offered=(), calibrated={'X': seen})
    augmented = AnalysisResult.augmented_machine(fake)
    assert [(e.id, e.axis, dict(e.params)) for e in augmented.effects] == [
        ('load_friction', 'X', {'mu': 0.1})]
    # the range the effect was identified on travels with it
    assert augmented.effects[0].calibrated == seen


def test_an_offered_loss_is_written_beside_the_named_effects():
    # an improvement the data do not attribute (issue 24, section 2) is a loss of that shape
    # in the machine file: never dropped
    machine = load_machine(default_machine())
    fake = SimpleNamespace(machine=machine, effects=(_fitted('load_friction', 'mu', 0.1, '-'),),
                           offered=(_fitted('viscous', 'c_n_s_m', 120.0, 'N*s/m'),),
                           calibrated={})
    augmented = AnalysisResult.augmented_machine(fake)
    assert [(e.id, dict(e.params)) for e in augmented.effects] == [
        ('load_friction', {'mu': 0.1}), ('viscous', {'c_n_s_m': 120.0})]


def test_only_the_alignment_effect_is_not_a_machine_property_nor_sample_local():
    # The node graph applies effects batch by batch; that is exact only for sample-local ones.
    assert {i for i, cls in EFFECTS.items() if not cls.machine_property} == {'time_offset'}
    assert {i for i, cls in EFFECTS.items() if not cls.sample_local} == {'time_offset'}
    assert get_effect('load_friction').sample_local


def test_a_machine_cannot_declare_an_alignment_effect(tmp_path):
    import pytest
    import yaml

    from feed_axis_energy.errors import ConfigError
    from feed_axis_energy.machine.file import machine_to_dict

    d = machine_to_dict(load_machine(default_machine()))
    d['effects'] = [{'id': 'time_offset', 'axis': 'X', 'params': {'delta_s': 0.01}}]
    path = tmp_path / 'm.yaml'
    path.write_text(yaml.safe_dump(d))
    with pytest.raises(ConfigError, match='line up') as err:
        load_machine(path)
    assert err.value.key == 'effects[0].id' and err.value.file == str(path)


def test_fresh_comparisons_come_one_run_at_a_time(monkeypatch):
    # analyze holds each fresh comparison as it is made: the next run is compared only when
    # the caller asks for it, and a comparison already made with the same machine is reused
    from feed_axis_energy.identify import realign
    made = []

    def compare(spec, machine, cache, **kwargs):
        made.append(spec)
        return SimpleNamespace(name=spec)

    monkeypatch.setattr(realign, 'compare_one_run', compare)
    monkeypatch.setattr(realign, 'MotionCache', lambda machine: None)
    campaign = SimpleNamespace(run=lambda name: name)
    known = SimpleNamespace(name='b')
    runs = realign.iter_realigned(campaign, None, ['a', 'b', 'c'], baseline=[known])
    assert made == []
    assert next(runs).name == 'a' and made == ['a']
    assert next(runs) is known and made == ['a']
    assert next(runs).name == 'c' and made == ['a', 'c']
    assert next(runs, None) is None
