"""The runs' simulations within a memory budget (identify/design/statestore.py), and analyze
on it."""
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
from feed_axis_energy.identify.design import columns as columns_module
from feed_axis_energy.identify.design import statestore
from feed_axis_energy.identify.design import StateStore
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
    real = statestore._open_new

    def full(path):
        calls.append(path)
        if len(calls) == 3:
            raise OSError(28, 'No space left on device')
        return real(path)

    monkeypatch.setattr(statestore, '_open_new', full)
    with pytest.raises(OutputError, match='No space left on device'):
        store.put(_state(2000, 7))
    folder = store._dir
    assert folder is not None and folder.parent == tmp_path
    assert len(list(folder.iterdir())) == 2         # the two files made before the third
    assert len(store) == 0
    store.close()
    assert not folder.exists()


SAMPLE_FIELDS = EffectState.SAMPLE_FIELDS


def _pieces(state: EffectState, cuts: list[int]) -> list[EffectState]:
    edges = [0, *cuts, state.t.shape[0]]
    return [dataclasses.replace(state, **{name: getattr(state, name)[a:b]
                                          for name in SAMPLE_FIELDS})
            for a, b in zip(edges[:-1], edges[1:])]


def test_sample_fields_are_the_per_sample_arrays() -> None:
    s = _state(7, 1)        # 7 samples, 2 axes: a per-axis array has 2 rows
    per_sample = {f.name for f in dataclasses.fields(EffectState)
                  if isinstance(getattr(s, f.name), np.ndarray)
                  and getattr(s, f.name).shape[0] == 7}
    assert per_sample == set(SAMPLE_FIELDS)


@pytest.mark.parametrize('budget_states', [10.0, 0.0, 0.5, 1.2])
def test_a_state_written_in_pieces_is_the_state_joined(budget_states) -> None:
    # a state of a third of the size held first, then one of four pieces (one of them
    # empty): in memory (room for 10), spilled from its first piece (0), from its second
    # piece (0.5: the piece before goes to the files first), from its last (1.2)
    first, whole = _state(1000, 2), _state(3000, 3)
    size = sum(getattr(whole, n).nbytes for n in SAMPLE_FIELDS)
    with StateStore(int(budget_states * size)) as store:
        keys = []
        for state, cuts in ((first, [400]), (whole, [1, 1200, 1200, 2999])):
            writer = store.writer()
            for piece in _pieces(state, cuts):
                writer.add(piece)
            keys.append(writer.finish())
        back = store.get(keys[1])
        _equal(whole, back)
        _equal(first, store.get(keys[0]))
        assert isinstance(back.t, np.memmap) == (budget_states < 2.0)
        assert store.spilled == {10.0: 0, 0.0: 2, 0.5: 1, 1.2: 1}[budget_states]


def test_writers_open_at_once_keep_their_states_apart() -> None:
    a, b = _state(600, 8), _state(900, 9)
    with StateStore(0) as store:
        wa, wb = store.writer(), store.writer()
        for pa, pb in zip(_pieces(a, [300]), _pieces(b, [450])):
            wa.add(pa)
            wb.add(pb)
        kb, ka = wb.finish(), wa.finish()
        assert ka != kb
        _equal(a, store.get(ka))
        _equal(b, store.get(kb))


def test_a_writer_refuses_misuse() -> None:
    s = _state(100, 4)
    with StateStore(0) as store:
        writer = store.writer()
        with pytest.raises(ValueError, match='at least one piece'):
            writer.finish()
        writer.add(s)
        bad = dataclasses.replace(s, power_w=s.power_w[:, :1])      # another run's shape
        with pytest.raises(ValueError, match='power_w'):
            writer.add(bad)


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
    real = statestore.StateWriter.finish

    def finish(self):
        before = self._store.spilled
        key = real(self)
        spilled.append(self._store.spilled > before)
        return key

    monkeypatch.setattr(statestore.StateWriter, 'finish', finish)
    held = analyze_campaign(campaign)
    assert spilled and not any(spilled)
    spilled.clear()
    # and the other memory savers at their extremes: the simulation in chunks of 500
    # samples (each run in several pieces), the candidates' bases computed 300 samples at a
    # time and their columns aligned one at a time
    pieces = []

    def chunks(*args, **kwargs):
        kwargs['chunk_samples'] = 500
        return real_chunks(*args, **kwargs)

    def counted(writer, piece):
        pieces.append(piece.t.shape[0])
        return real_add(writer, piece)

    real_chunks, real_add = columns_module.simulate_declared_chunks, statestore.StateWriter.add
    monkeypatch.setattr(columns_module, 'simulate_declared_chunks', chunks)
    monkeypatch.setattr(statestore.StateWriter, 'add', counted)
    monkeypatch.setattr(columns_module, 'ALIGN_CHUNK_BYTES', 1)
    monkeypatch.setattr(columns_module, 'BASIS_CHUNK_SAMPLES', 300)
    held_arrays = []
    real_hold = statestore.StateStore.hold

    def hold(store, array):
        out = real_hold(store, array)
        held_arrays.append(out)
        return out

    monkeypatch.setattr(statestore.StateStore, 'hold', hold)
    mapped = analyze_campaign(campaign, options=AnalyzeOptions(state_memory_bytes=0))
    assert spilled and all(spilled)
    # every run's record (stamps, power, file rows) memory-mapped as well
    assert len(held_arrays) >= 3 * len(campaign.runs)
    assert all(statestore._map_of(a) is not None for a in held_arrays if a.size)
    assert len(pieces) > 3 * len(spilled) and max(pieces) <= 500
    assert 'thermal_drift' in {e.id for e in held.effects}, held.message
    assert (json.dumps(mapped.to_dict(), sort_keys=True)
            == json.dumps(held.to_dict(), sort_keys=True))


def test_held_arrays_beyond_the_budget_are_maps_of_gone_files(tmp_path, monkeypatch) -> None:
    monkeypatch.setattr('tempfile.tempdir', str(tmp_path))
    small, big = np.arange(10.0), np.arange(3000.0).reshape(1000, 3)
    with StateStore(small.nbytes) as store:
        assert store.hold(small) is small                   # within the budget: itself
        assert store.hold(small) is small and store.held_bytes == small.nbytes  # counted once
        mapped = store.hold(big)
        assert statestore._map_of(mapped) is not None and not mapped.flags.writeable
        assert_array_equal(mapped, big)
        assert store.hold(mapped) is mapped                 # a map is not copied again
        view = mapped[10:20, 1:]
        assert store.hold(view) is view                     # nor a view of one
        store.drop_pages()                                  # the pages go, the data stay
        assert_array_equal(mapped, big)
        labels = np.array(['a', None], dtype=object)
        assert store.hold(labels) is labels                 # references stay in memory
        assert store.hold(np.asarray(mapped)[::2].copy()) is not mapped
        folder = store._dir
        assert folder is not None and list(folder.iterdir()) == []   # unlinked at once
    assert not folder.exists()
    assert_array_equal(mapped, big)                         # the map outlives the store
    # a directory that cannot be made, or a disk that fails: our error, nothing left
    monkeypatch.setattr('tempfile.tempdir', str(tmp_path / 'no-such-dir'))
    with StateStore(0) as store:
        with pytest.raises(OutputError, match='no-such-dir') as err:
            store.hold(big)
        assert 'TMPDIR' in str(err.value)
    monkeypatch.setattr('tempfile.tempdir', str(tmp_path))

    class Full:
        def __init__(self, path):
            self.fh = open(path, 'xb')

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.fh.close()

        def write(self, data):
            raise OSError(28, 'No space left on device')

    monkeypatch.setattr(statestore, '_open_new', Full)
    with StateStore(0) as store:
        with pytest.raises(OutputError, match='No space left on device'):
            store.hold(big)
        assert store._dir is not None and list(store._dir.iterdir()) == []
