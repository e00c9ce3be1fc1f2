"""The runs' simulations within a memory budget (identify/statestore.py), and analyze on it."""
import dataclasses
import json
from pathlib import Path
import stat

import numpy as np
from numpy.testing import assert_array_equal
import pytest

from feed_axis_energy.effects import EffectState
from feed_axis_energy.errors import ConfigError, OutputError
from feed_axis_energy.identify.analyze import analyze_campaign
from feed_axis_energy.identify.results import AnalyzeOptions
from feed_axis_energy.identify.rig import Instrument, make_campaign, parse_effects, RigConfig
from feed_axis_energy.identify.statestore import StateStore
from feed_axis_energy.measured.manifest import load_campaign

ROOT = Path(__file__).resolve().parents[2]
MACHINE = ROOT / 'config' / 'demonstrator.yaml'


def _state(n: int, seed: int) -> EffectState:
    rng = np.random.default_rng(seed)
    k = 2

    def a() -> np.ndarray:
        return rng.normal(size=(n, k))

    return EffectState(t=np.arange(n) * 1e-3, axes=('X', 'Y'), position_m=a(),
                       velocity_m_s=np.asfortranarray(a()), acceleration_m_s2=a(),
                       angle_rad=a(), omega_rad_s=a(), force_n=a(), torque_nm=a(),
                       mass_kg=np.array([100.0, 80.0]), load_kg=5.0,
                       normal_force_n=np.array([981.0, 784.8]), lead_m=np.array([0.01, 0.01]),
                       mechanical_w=a(), power_w=a()[:, :1].repeat(2, axis=1),
                       load_normal_force_n=None)


def _equal(a: EffectState, b: EffectState) -> None:
    for f in dataclasses.fields(EffectState):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray):
            assert_array_equal(np.asarray(y), x, err_msg=f.name)
            assert np.asarray(y).dtype == x.dtype
        else:
            assert y == x, f.name


def test_states_within_the_budget_stay_in_memory() -> None:
    s = _state(100, 1)
    with StateStore(10 ** 9) as store:
        key = store.put(s)
        assert store.get(key) is s
        assert store.spilled == 0
        assert store.held_bytes > 0


def test_states_beyond_the_budget_come_back_equal_and_read_only() -> None:
    states = [_state(3000, seed) for seed in range(3)]
    size = sum(v.nbytes for v in vars(states[0]).values() if isinstance(v, np.ndarray))
    with StateStore(size) as store:          # room for the first state only
        keys = [store.put(s) for s in states]
        assert store.spilled == 2
        assert store.get(keys[0]) is states[0]
        for key, s in zip(keys[1:], states[1:]):
            back = store.get(key)
            _equal(s, back)
            assert isinstance(back.position_m, np.memmap)
            assert not isinstance(back.mass_kg, np.memmap)     # small arrays stay in memory
            with pytest.raises(ValueError):
                back.power_w[0, 0] = 1.0                        # nothing can change a state
            _equal(s, store.get(key))


def test_the_spill_folder_is_private_and_gone_after_close_and_after_an_error() -> None:
    store = StateStore(0)
    store.put(_state(2000, 4))
    folder = store._dir
    assert folder is not None and folder.is_dir()
    assert stat.S_IMODE(folder.stat().st_mode) == 0o700
    for f in folder.iterdir():
        assert stat.S_IMODE(f.stat().st_mode) == 0o600
        assert not f.is_symlink()
    store.close()
    assert not folder.exists()
    with pytest.raises(RuntimeError, match='boom'):
        with StateStore(0) as other:
            other.put(_state(2000, 5))
            folder = other._dir
            raise RuntimeError('boom')
    assert folder is not None and not folder.exists()


def test_a_temporary_directory_that_cannot_be_used_is_named(tmp_path, monkeypatch) -> None:
    missing = tmp_path / 'no-such-dir'
    monkeypatch.setattr('tempfile.tempdir', str(missing))     # what TMPDIR would give
    with StateStore(0) as store:
        with pytest.raises(OutputError, match='no-such-dir') as err:
            store.put(_state(2000, 6))
        assert 'TMPDIR' in str(err.value) and '--state-memory' in str(err.value)
        assert len(store) == 0
    # a full disk while writing: the partial files are gone with the store
    monkeypatch.setattr('tempfile.tempdir', str(tmp_path))
    store = StateStore(0)
    calls = []

    def full(path, value):
        calls.append(path)
        if len(calls) == 3:
            raise OSError(28, 'No space left on device')
        with open(path, 'wb') as fh:
            np.save(fh, value)

    monkeypatch.setattr('feed_axis_energy.identify.statestore._write_new', full)
    with pytest.raises(OutputError, match='No space left on device'):
        store.put(_state(2000, 7))
    folder = store._dir
    assert folder is not None and folder.parent == tmp_path
    store.close()
    assert not folder.exists()


def test_a_negative_budget_is_refused() -> None:
    with pytest.raises(ValueError, match='budget_bytes'):
        StateStore(-1)
    with pytest.raises(ConfigError, match='state_memory_bytes'):
        AnalyzeOptions(state_memory_bytes=-1)


def test_analyze_with_every_state_spilled_gives_the_same_result(tmp_path, monkeypatch) -> None:
    # a shape to refine (thermal_drift's time constant) and the alternatives' check: every
    # path that computes columns from the states
    cfg = RigConfig(machine=MACHINE, loads_kg=(0.0, 22.711), feeds_mm_s=(150.0, 300.0, 450.0),
                    cycles=3, effects=parse_effects('thermal_drift=rate_n_s:2.0,tau_s:20'),
                    instrument=Instrument(noise_w=1.0), seed=1)
    campaign = load_campaign(make_campaign(tmp_path / 'rig', cfg))
    spilled = []
    real = StateStore.put

    def put(self, state):
        before = self.spilled
        key = real(self, state)
        spilled.append(self.spilled > before)
        return key

    monkeypatch.setattr(StateStore, 'put', put)
    held = analyze_campaign(campaign)
    assert spilled and not any(spilled)
    spilled.clear()
    mapped = analyze_campaign(campaign, options=AnalyzeOptions(state_memory_bytes=0))
    assert spilled and all(spilled)
    assert 'thermal_drift' in {e.id for e in held.effects}, held.message
    assert (json.dumps(mapped.to_dict(), sort_keys=True)
            == json.dumps(held.to_dict(), sort_keys=True))
