"""Pure graph helpers (no ROS): flow window, line run-lengths, streaming power, chunked bag."""
import numpy as np
import pytest

from feed_axis_energy.record import bagio
from feed_axis_energy.graph import flow as graph
from feed_axis_energy.graph.end import EndTracker
from feed_axis_energy.record.crashsafe import ChunkedBagWriter
from feed_axis_energy.physics.energy import energy_by_line, EnergyIntegrator, PowerResult


def test_flow_window_waits_for_every_source():
    w = graph.FlowWindow(2, ['power', 'recorder'])
    w.sent(10)
    w.sent(20)
    assert not w.can_send()
    assert w.ack('power', 20) == 0          # the recorder has not caught up yet
    assert w.ack('recorder', 10) == 1
    assert w.can_send() and w.in_flight == 1
    assert w.ack('recorder', 25) == 1
    assert w.in_flight == 0
    with pytest.raises(ValueError):
        w.sent(5)


def test_batch_bounds_cover_everything():
    assert graph.batch_bounds(7, 3) == [(0, 3), (3, 6), (6, 7)]
    assert graph.batch_bounds(0, 3) == []


def test_lines_at_inverts_block_starts():
    t_ns = np.arange(10) * 1000
    line = np.array([0, 2, 2, 2, 3, 3, 2, 2, 7, 7])
    starts, lines = graph.block_starts(t_ns, line)
    np.testing.assert_array_equal(graph.lines_at(t_ns, starts, lines), line)


def test_streaming_power_equals_offline_by_hand():
    rng = np.random.default_rng(1)
    t = np.arange(50) * 0.01
    torque, omega = rng.normal(size=(50, 2)), rng.normal(size=(50, 2))
    sp = graph.StreamingPower(('X', 'Y'), braking='dissipated')
    for i0, i1 in graph.batch_bounds(50, 7):
        sp.update(t[i0:i1], torque[i0:i1], omega[i0:i1])
    p = np.maximum(torque * omega, 0.0)
    # trapezoid by hand, total = sum of axes
    e_hand = np.concatenate(([0.0], np.cumsum(0.5 * (p[1:] + p[:-1]).sum(axis=1) * 0.01)))
    assert sp.energy_j[-1] == pytest.approx(e_hand[-1], rel=1e-12)
    whole = EnergyIntegrator(3).update(t, np.column_stack((p, p.sum(axis=1))))
    np.testing.assert_array_equal(sp.energy_j, whole[-1])
    assert sp.n_samples == 50
    # Per line: the offline rule on the whole record (lines change inside a batch, at 25).
    line = np.repeat([1, 2], 25)
    starts, lines = graph.block_starts(graph.seconds_to_ns(t), line)
    blocks = sp.block_energy(starts, lines)
    ref = energy_by_line(PowerResult(
        t=t, axes=('X', 'Y'), power_w=p, total_w=p.sum(axis=1), energy_j=whole[:, :2],
        total_energy_j=whole[:, 2], mechanical_w=torque * omega,
        loss_power_w=np.zeros_like(p), line=line, braking='dissipated'))
    assert [b[0] for b in blocks] == [b[0] for b in ref] == [1, 2]
    np.testing.assert_allclose([b[1:] for b in blocks], [b[1:] for b in ref], rtol=1e-12)
    assert sum(b[1] for b in blocks) == pytest.approx(sp.energy_j[-1], rel=1e-12)


def test_streaming_power_lines_may_come_before_or_after_batches():
    rng = np.random.default_rng(2)
    t = np.arange(40) * 0.01
    torque, omega = rng.normal(size=(40, 1)), rng.normal(size=(40, 1))
    line = np.repeat([3, 5, 4, 3], 10)
    table = graph.block_starts(graph.seconds_to_ns(t), line)
    early = graph.StreamingPower(('X',), braking='regenerative')
    early.set_lines(*table)
    late = graph.StreamingPower(('X',), braking='regenerative')
    for i0, i1 in graph.batch_bounds(40, 6):
        early.update(t[i0:i1], torque[i0:i1], omega[i0:i1])
        late.update(t[i0:i1], torque[i0:i1], omega[i0:i1])
    with pytest.raises(ValueError, match='line table'):
        late.block_energy()
    got_late = late.block_energy(*table)
    got_early = early.block_energy()
    assert [b[0] for b in got_early] == [3, 4, 5]
    np.testing.assert_allclose(got_late, got_early, rtol=1e-12)
    # line 3 has two runs: its time is 9 + 10 intervals (the first sample has none)
    assert got_early[0][2] == pytest.approx(0.19, rel=1e-9)


def test_header_stamp_from_cdr():
    s = bagio.Series(t=np.array([12.345678901]), names=('X',), positions=np.zeros((1, 1)))
    ((stamp, msg),) = bagio.series_to_messages(s)
    cdr = bagio.typestore().serialize_cdr(msg, bagio.JOINT_TRAJECTORY)
    assert graph.header_stamp_ns(cdr) == stamp == 12_345_678_901


def test_end_tracker():
    tr = EndTracker(['a', 'b'], ['blocks'])
    tr.seen('a', 100)
    tr.seen('b', 100)
    assert not tr.done
    tr.end = graph.ProgramEnd('p', 2, 2, 0, 100)
    assert not tr.done
    tr.seen('blocks', 0)
    assert tr.done


def _series(t0, n):
    return bagio.Series(t=t0 + np.arange(n) * 1e-3, names=('X',),
                        positions=np.arange(n, dtype=float)[:, None])


def test_chunked_writer_readable_after_each_flush(tmp_path):
    bag = ChunkedBagWriter(tmp_path / 'bag', typestore=bagio.typestore())
    bag.add_topic('/power', bagio.JOINT_TRAJECTORY)
    ts = bagio.typestore()
    for chunk in range(3):
        for stamp, msg in bagio.series_to_messages(_series(chunk * 0.1, 100), batch=10):
            bag.write('/power', stamp, bytes(ts.serialize_cdr(msg, bagio.JOINT_TRAJECTORY)))
        bag.flush()
        got = bagio.read_series(tmp_path / 'bag', '/power')
        assert got.t.shape[0] == 100 * (chunk + 1)   # readable without close()
    bag.write('/power', 0, b'')  # buffered, never flushed: lost like after a SIGKILL
    assert bagio.bag_topics(tmp_path / 'bag') == {'/power': (bagio.JOINT_TRAJECTORY, 30)}
    assert bag.files == 4   # the empty first file (metadata from the start) + 3 flushes


def test_chunked_writer_empty_bag(tmp_path):
    bag = ChunkedBagWriter(tmp_path / 'bag', typestore=bagio.typestore())
    bag.add_topic('/power', bagio.JOINT_TRAJECTORY)
    bag.close()
    assert bagio.bag_topics(tmp_path / 'bag') == {'/power': (bagio.JOINT_TRAJECTORY, 0)}


def test_end_tracker_per_topic_last_stamps():
    """A replay whose topics end at different stamps: each must reach only its own end."""
    per_topic = {'measured/power': 300, 'measured/kinematics': 200}
    end = graph.ProgramEnd('p', 5, 5, 0, 300, topic_last_ns=per_topic)
    back = graph.ProgramEnd.from_pairs(end.to_pairs())
    assert back == end
    assert back.last_ns_of('/measured/kinematics') == 200
    assert back.last_ns_of('measured/other') == -1   # listed topics only: nothing to wait for
    tr = EndTracker(['measured/power', 'measured/kinematics'])
    tr.end = back
    tr.seen('measured/power', 300)
    tr.seen('measured/kinematics', 100)
    assert not tr.done
    tr.seen('measured/kinematics', 200)   # never reaches 300, and need not
    assert tr.done
    old = graph.ProgramEnd('p', 2, 2, 0, 100)   # gcode_trajectory's marker: one last stamp
    assert graph.ProgramEnd.from_pairs(old.to_pairs()).last_ns_of('power') == 100
