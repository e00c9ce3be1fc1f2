"""The numpy CDR codec against rosbags' serializer and rclpy's deserializer."""
import must_run
import numpy as np
import pytest

from feed_axis_energy.record import bagio
from feed_axis_energy.errors import DataError
from feed_axis_energy.graph.end import ProgramEnd

rclpy = must_run.import_or_skip('rclpy', 'rclpy')
from feed_axis_energy.nodes import convert  # noqa: E402
from rclpy.serialization import deserialize_message  # noqa: E402
from trajectory_msgs.msg import JointTrajectory  # noqa: E402

LAYOUTS = [
    (('X', 'Y', 'Z'), ('positions', 'velocities', 'accelerations')),
    (('X', 'Y', 'X_screw', 'Y_screw'), convert.FIELDS),
    (('X', 'total'), ('positions', 'velocities')),
    (('Xa',), ('velocities',)),
    (('abc', 'de'), ('effort',)),
]


@pytest.mark.parametrize('names,fields', LAYOUTS)
@pytest.mark.parametrize('n', [1, 7, 100])
@pytest.mark.parametrize('frame_id', ['', 'a', 'abcde'])
def test_bytes_equal_rosbags_and_roundtrip(names, fields, n, frame_id):
    rng = np.random.default_rng(n)
    s = bagio.Series(t=np.arange(n) * 1e-3 + 2.5, names=names,
                     **{f: rng.normal(size=(n, len(names))) for f in fields})
    ts = bagio.typestore()
    ref = [(st, bytes(ts.serialize_cdr(m, bagio.JOINT_TRAJECTORY)))
           for st, m in bagio.series_to_messages(s, batch=30, frame_id=frame_id)]
    mine = convert.series_to_cdr(s, batch=30, frame_id=frame_id)
    assert ref == mine
    back = [convert.cdr_to_series(c) for _, c in mine]
    np.testing.assert_array_equal(np.concatenate([b.t for b in back]), s.t)
    for f in convert.FIELDS:
        if getattr(s, f) is None:
            assert all(getattr(b, f) is None for b in back)
        else:
            np.testing.assert_array_equal(np.vstack([getattr(b, f) for b in back]),
                                          getattr(s, f))
    msg = deserialize_message(mine[0][1], JointTrajectory)
    assert tuple(msg.joint_names) == names
    assert msg.header.frame_id == frame_id
    np.testing.assert_array_equal(convert.msg_to_series(msg).t, back[0].t)


def test_object_path_matches_codec():
    s = bagio.Series(t=np.array([0.0, 0.001, 0.002]), names=('X',),
                     positions=np.array([[1.0], [2.0], [3.0]]),
                     velocities=np.array([[0.5], [0.25], [0.0]]))
    back = convert.msg_to_series(convert.series_to_msg(s))
    np.testing.assert_array_equal(back.positions, s.positions)
    assert back.accelerations is None


def test_truncated_is_a_data_error():
    s = bagio.Series(t=np.arange(5) * 1e-3, names=('X',), positions=np.ones((5, 1)))
    ((_, cdr),) = convert.series_to_cdr(s, batch=10)
    with pytest.raises(DataError):
        convert.decode_trajectory(cdr[:-20])


def test_block_energy_and_end_marker_roundtrip():
    blocks = [(3, 97.5, 2.0), (5, -1.25, 0.5)]
    msg = convert.block_energy_msg(blocks, stamp_ns=3_000_000_000, program='p.nc')
    assert convert.block_energy_from_msg(msg) == blocks
    assert msg.status[0].name == 'p.nc:3'
    end = ProgramEnd(program='p.nc', samples=10, batches=1, first_ns=0, last_ns=9)
    assert convert.program_end_from_msg(convert.program_end_msg(end)) == end
    starts, lines = np.array([5, 90, 200]), np.array([2, 3, 7])
    got = convert.lines_from_cdr(convert.lines_to_cdr(starts, lines, first_ns=5))
    np.testing.assert_array_equal(got[0], starts)
    np.testing.assert_array_equal(got[1], lines)
