"""The force held at standstill: last direction of motion, chunking, bounds."""
import numpy as np
import pytest

from feed_axis_energy.physics.standstill import HoldState, holding_force, last_direction


def test_last_direction_by_hand():
    v = np.array([0.0, 0.0, 0.01, 0.02, 0.0, 0.00005, -0.03, 0.0, 0.0, 0.02])
    want = np.array([0, 0, 1, 1, 1, 1, -1, -1, -1, 1], dtype=float)
    assert last_direction(v, rest_speed=1e-4)[:, 0].tolist() == want.tolist()


def test_holding_force_by_hand_two_axes():
    v = np.array([[0.0, 0.0], [0.01, -0.01], [0.0, -0.01], [0.0, 0.0]])
    f = holding_force(v, [30.0, 12.0])
    # axis 1: rest before any motion holds nothing; after moving + it holds +30 N at rest
    assert f[:, 0].tolist() == [0.0, 0.0, 30.0, 30.0]
    # axis 2: moving in - (no hold while moving), then holds -12 N
    assert f[:, 1].tolist() == [0.0, 0.0, 0.0, -12.0]


def test_chunks_equal_one_pass():
    rng = np.random.default_rng(3)
    # runs of motion and rest of random lengths and signs on three axes
    v = np.repeat(rng.choice([-0.02, 0.0, 0.0, 0.03], size=(200, 3)), 7, axis=0)
    whole = holding_force(v, [5.0, 0.0, 2.5])
    state = HoldState()
    parts = [holding_force(v[a:a + 97], [5.0, 0.0, 2.5], state=state)
             for a in range(0, v.shape[0], 97)]
    np.testing.assert_array_equal(np.concatenate(parts), whole)
    assert state.direction.tolist() == last_direction(v)[-1].tolist()


@pytest.mark.parametrize('hold', [-1.0, np.nan, np.inf])
def test_hold_out_of_bounds_is_refused(hold):
    with pytest.raises(ValueError, match='holding force'):
        holding_force(np.zeros((3, 1)), hold)


def test_negative_rest_speed_is_refused():
    with pytest.raises(ValueError, match='rest_speed'):
        last_direction(np.zeros(3), rest_speed=-1.0)
