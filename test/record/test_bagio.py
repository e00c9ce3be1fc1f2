"""Round trips of time series and block summaries through rosbag2/MCAP bags."""
from pathlib import Path

import numpy as np
from numpy.testing import assert_allclose, assert_array_equal
import pytest

from feed_axis_energy.record import bagio, StreamBagWriter
from feed_axis_energy.errors import DataError


def _series(n: int, names=('X', 'total')) -> bagio.Series:
    rng = np.random.default_rng(3)
    t = np.arange(n) * 1e-3 + 0.5
    return bagio.Series(t=t, names=names, positions=rng.normal(size=(n, len(names))),
                        velocities=rng.normal(size=(n, len(names))))


@pytest.mark.parametrize('n,batch', [(1, 100), (250, 100), (300, 100), (7, 3)])
def test_series_round_trip_is_exact(tmp_path: Path, n: int, batch: int) -> None:
    series = _series(n)
    with StreamBagWriter(tmp_path / 'bag') as writer:
        count = writer.write_series(bagio.TOPIC_POWER, series, batch=batch)
    assert count == -(-n // batch)
    back = bagio.read_series(tmp_path / 'bag', bagio.TOPIC_POWER)
    assert back.names == series.names
    assert back.t0_ns == 500_000_000 and back.t[0] == 0.0     # t counts from the first stamp
    assert_array_equal(back.stamps_ns(), series.stamps_ns())
    assert_allclose(back.t + 0.5, series.t, rtol=0, atol=1e-9)
    assert_array_equal(back.positions, series.positions)
    assert_array_equal(back.velocities, series.velocities)
    assert back.accelerations is None and back.effort is None
    topics = bagio.bag_topics(tmp_path / 'bag')
    assert topics[bagio.TOPIC_POWER] == (bagio.JOINT_TRAJECTORY, count)
    assert list((tmp_path / 'bag').glob('*.mcap'))


def test_block_energy_and_custom_data(tmp_path: Path) -> None:
    blocks = [(3, 12.5, 1.25), (4, -0.125, 0.5)]
    with StreamBagWriter(tmp_path / 'bag') as writer:
        writer.write_block_energy(blocks, stamp_s=2.0, program='p.nc')
        writer.set_custom_data('feed_axis_energy/summary', {'energy_j': 1.5})
    assert bagio.read_block_energy(tmp_path / 'bag') == blocks
    assert bagio.read_custom_data(tmp_path / 'bag', 'feed_axis_energy/summary') == {
        'energy_j': 1.5}


def test_existing_directory_is_not_overwritten(tmp_path: Path) -> None:
    (tmp_path / 'bag').mkdir()
    with pytest.raises(FileExistsError, match='exists already'):
        with StreamBagWriter(tmp_path / 'bag'):
            pass
    assert list((tmp_path / 'bag').iterdir()) == []


def test_missing_topic_and_non_bag_are_clear_errors(tmp_path: Path) -> None:
    with pytest.raises(DataError, match='not a rosbag2 directory'):
        bagio.read_series(tmp_path, bagio.TOPIC_POWER)
    with StreamBagWriter(tmp_path / 'bag') as writer:
        writer.write_series(bagio.TOPIC_POWER, _series(5))
    with pytest.raises(DataError, match="topic '/setpoints' not in bag"):
        bagio.read_series(tmp_path / 'bag', bagio.TOPIC_SETPOINTS)


def test_text_as_message_count_in_metadata_is_a_clear_error(tmp_path: Path) -> None:
    # found by test_hostile_properties: a ValueError of int() escaped bag_topics
    with StreamBagWriter(tmp_path / 'bag') as writer:
        writer.write_series(bagio.TOPIC_POWER, _series(5))
    meta = tmp_path / 'bag' / 'metadata.yaml'
    text = meta.read_text()
    assert '  - message_count: 1\n' in text
    meta.write_text(text.replace('  - message_count: 1\n', '  - message_count: x\n'))
    with pytest.raises(DataError, match='message counts of metadata.yaml'):
        bagio.bag_topics(tmp_path / 'bag')


def test_mcap_file_is_readable_by_plain_mcap_reader(tmp_path: Path) -> None:
    from mcap.reader import make_reader
    with StreamBagWriter(tmp_path / 'bag') as writer:
        writer.write_series(bagio.TOPIC_POWER, _series(250), batch=100)
    (mcap_file,) = (tmp_path / 'bag').glob('*.mcap')
    with open(mcap_file, 'rb') as f:
        reader = make_reader(f)
        topics = [channel.topic for _, channel, _ in reader.iter_messages()]
    assert topics == [bagio.TOPIC_POWER] * 3


# 2026-11-23T14:00:00.000000123Z: a wall-clock stamp (--start-time), about 1.8e18 ns
WALL_START_NS = 1_795_356_000_000_000_123


def _write_stamped(path: Path, t_ns: np.ndarray, values: np.ndarray) -> None:
    """A /power topic whose messages carry exactly the integer stamps ``t_ns``."""
    from feed_axis_energy.record.cdr import joint_trajectory_cdr
    ts = bagio.typestore()
    with StreamBagWriter(path) as writer:
        for stamp, raw in joint_trajectory_cdr(t_ns, ('X', 'total'), [values, None, None, None],
                                               batch=100):
            message = ts.deserialize_cdr(raw, bagio.JOINT_TRAJECTORY)
            writer.write_message(bagio.TOPIC_POWER, bagio.JOINT_TRAJECTORY, stamp, message)


def test_wall_clock_stamps_read_back_to_the_nanosecond(tmp_path: Path) -> None:
    # 1 kHz with an odd nanosecond offset: float seconds since 1970 (resolution ~0.24 us
    # near 1.8e9 s) would round every sample time; t counted from t0_ns keeps them.
    rel = np.arange(250, dtype=np.int64) * 1_000_000 + 7
    values = np.column_stack([np.arange(250.0), -np.arange(250.0)])
    _write_stamped(tmp_path / 'wall', WALL_START_NS + rel, values)
    _write_stamped(tmp_path / 'sim', rel, values)
    wall = bagio.read_series(tmp_path / 'wall', bagio.TOPIC_POWER)
    sim = bagio.read_series(tmp_path / 'sim', bagio.TOPIC_POWER)
    assert_array_equal(np.rint((wall.t - wall.t[0]) * 1e9).astype(np.int64), rel - 7)
    assert wall.t0_ns == WALL_START_NS + 7 and sim.t0_ns == 7
    assert_array_equal(wall.stamps_ns(), WALL_START_NS + rel)
    assert_array_equal(wall.t, sim.t)                    # the same run, bit for bit
    assert_array_equal(wall.positions, values)


def test_series_with_a_start_writes_its_stamps(tmp_path: Path) -> None:
    series = _series(150)
    start = bagio.Series(t=series.t, names=series.names, positions=series.positions,
                         velocities=series.velocities, t0_ns=WALL_START_NS)
    with StreamBagWriter(tmp_path / 'bag') as writer:
        writer.write_series(bagio.TOPIC_POWER, start, batch=100)
    back = bagio.read_series(tmp_path / 'bag', bagio.TOPIC_POWER)
    assert_array_equal(back.stamps_ns(), WALL_START_NS + np.rint(series.t * 1e9).astype(np.int64))
    assert back.t0_ns == WALL_START_NS + 500_000_000
    with pytest.raises(ValueError, match='t0_ns must be an integer'):
        bagio.Series(t=series.t, names=series.names, t0_ns=1.5)
