"""Vectorised JointTrajectory serialisation gives the bytes of rosbags' serializer."""
import numpy as np
import pytest

from feed_axis_energy.core import bagio
from feed_axis_energy.core.cdr import joint_trajectory_cdr


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
