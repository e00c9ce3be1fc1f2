"""Vectorised JointTrajectory serialisation gives the bytes of rosbags' serializer."""
import numpy as np
import pytest

from feed_axis_energy.record import bagio, StreamBagWriter
from feed_axis_energy.record.cdr import (BLOCK_ENERGY_PER_MESSAGE, block_energy_cdr_array,
                                         diagnostic_array_cdr, joint_trajectory_cdr)


@pytest.mark.parametrize('names', [('X',), ('X', 'total'), ('X', 'Y', 'Z', 'X_screw', 'Y_s')])
@pytest.mark.parametrize('present', [(1, 1, 1, 1), (1, 1, 0, 0), (0, 1, 0, 0), (1, 0, 1, 0)])
@pytest.mark.parametrize('n,batch', [(1, 100), (250, 100), (300, 100), (17, 5), (9, 1)])
def test_bytes_equal_rosbags_serializer(names, present, n, batch):
    rng = np.random.default_rng(n + batch)
    t = np.sort(rng.uniform(0.0, 5e4, n))       # stamps beyond a few hours, ns rounding
    k = len(names)
    arrays = {f: (rng.normal(size=(n, k)) if p else None)
              for f, p in zip(('positions', 'velocities', 'accelerations', 'effort'), present)}
    series = bagio.Series(t=t, names=names, **arrays)
    ref = [(stamp, bytes(bagio.typestore().serialize_cdr(msg, bagio.JOINT_TRAJECTORY)))
           for stamp, msg in bagio.series_to_messages(series, batch=batch)]
    t_ns = np.rint(t * 1e9).astype(np.int64)
    got = joint_trajectory_cdr(t_ns, names, list(arrays.values()), batch=batch)
    assert [s for s, _ in got] == [s for s, _ in ref]
    assert [b for _, b in got] == [b for _, b in ref]


@pytest.mark.parametrize('n', [0, 1, 7, 300])
def test_diagnostic_array_bytes_equal_rosbags_serializer(n):
    ts = bagio.typestore()
    kv = ts.types['diagnostic_msgs/msg/KeyValue']
    status_cls = ts.types['diagnostic_msgs/msg/DiagnosticStatus']
    rows = [(i % 3, f'prog.nc:{i * 17}', 'block energy' if i % 2 else 'é', '' if i else 'hw',
             [('line', str(i)), ('energy_j', repr(i * 0.1))][:i % 3]) for i in range(n)]
    stamp = 12_345 * 1_000_000_000 + 678
    header = ts.types['std_msgs/msg/Header'](
        stamp=ts.types['builtin_interfaces/msg/Time'](sec=12_345, nanosec=678), frame_id='f')
    msg = ts.types[bagio.DIAGNOSTIC_ARRAY](header=header, status=[
        status_cls(level=lv, name=nm, message=ms, hardware_id=hw,
                   values=[kv(key=k, value=v) for k, v in vals])
        for lv, nm, ms, hw, vals in rows])
    ref = bytes(ts.serialize_cdr(msg, bagio.DIAGNOSTIC_ARRAY))
    assert bytes(diagnostic_array_cdr(stamp, n, iter(rows), frame_id='f')) == ref


def test_block_energy_of_many_lines_splits_and_reads_back(tmp_path):
    n = 2 * BLOCK_ENERGY_PER_MESSAGE + 1
    blocks = [(i + 1, 0.5 * i - 7.0, 1e-3 * i) for i in range(n)]
    with StreamBagWriter(tmp_path / 'b') as writer:
        writer.write_block_energy(blocks, stamp_s=12.5, program='p.nc')
    assert bagio.bag_topics(tmp_path / 'b')[bagio.TOPIC_BLOCK_ENERGY][1] == 3
    assert bagio.read_block_energy(tmp_path / 'b') == blocks


@pytest.mark.parametrize('program', ['p.nc', '/tmp/ü/x.nc', ''])
@pytest.mark.parametrize('n', [0, 1, 2, 7, 1000])
def test_block_energy_array_equals_the_status_by_status_bytes(program, n):
    rng = np.random.default_rng(n)
    lines = np.sort(rng.integers(1, 10**7, n))
    energy = rng.normal(size=n) * 10.0 ** rng.integers(-5, 8, n)
    duration = rng.uniform(0, 1e4, n)
    statuses = ((0, f'{program}:{line}', 'block energy', '',
                 (('line', str(line)), ('energy_j', repr(float(e))),
                  ('duration_s', repr(float(d)))))
                for line, e, d in zip(lines.tolist(), energy, duration))
    frame = 'f' if n == 7 else ''
    ref = bytes(diagnostic_array_cdr(123_456_789_012, n, statuses, frame_id=frame))
    assert block_energy_cdr_array(123_456_789_012, program, lines, energy, duration,
                                  frame_id=frame) == ref


def test_rows_do_not_depend_on_memory_order_or_column_blocks():
    # the planner may hand over column-major arrays; a field may come as column blocks
    from feed_axis_energy.record.cdr import joint_trajectory_rows
    rng = np.random.default_rng(5)
    t = np.arange(600, dtype=np.int64) * 1_000_000
    a = rng.normal(size=(600, 3))
    f = np.asfortranarray(a)
    names = ('X', 'Y', 'Z')
    c_order = joint_trajectory_rows(t, names, [a, a, None, a], points=100, lead=31)
    mixed = joint_trajectory_rows(t, names, [f, (f[:, :2], a[:, 2:]), None, (a[:, :1], f[:, 1:])],
                                  points=100, lead=31)
    np.testing.assert_array_equal(mixed.rows, c_order.rows)
    ref = joint_trajectory_cdr(t, names, [a, a, None, a], batch=100)
    stop = c_order.start + c_order.length
    assert [bytes(r[c_order.start:stop]) for r in c_order.rows] == [b for _, b in ref]
