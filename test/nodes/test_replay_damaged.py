"""measured_replay on a damaged bag: one log line naming the bag, exit 1, nothing published."""
import importlib.util
from pathlib import Path
import shutil
import subprocess
import sys

import must_run
import pytest

must_run.import_or_skip('rclpy', 'rclpy')

_SPEC = importlib.util.spec_from_file_location(
    'hostile_inputs', Path(__file__).resolve().parents[1] / 'measured' /
    'hostile_inputs.py')
hostile_inputs = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(hostile_inputs)

# one case per kind of failure of the reader (storage, metadata, type, CDR content, empty)
CASES = ['truncated mcap 50 %', 'empty metadata.yaml', 'wrong message type',
         'array shorter than joint names', 'NaN in a message', 'value 1e300 in a message',
         'topics without messages']


@pytest.fixture(scope='module')
def valid_bags(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return hostile_inputs.bag_campaign(tmp_path_factory.mktemp('bags'), runs=1)


@pytest.mark.parametrize('damage', CASES)
def test_replay_of_a_damaged_bag_exits_1_with_one_line(valid_bags: Path, tmp_path: Path,
                                                       node_env: dict, damage: str) -> None:
    bag = tmp_path / 'r0'
    shutil.copytree(valid_bags.parent / 'r0', bag)
    hostile_inputs.BAG_DAMAGES[damage](bag)
    proc = subprocess.run(
        [sys.executable, '-m', 'feed_axis_energy.nodes.measured_replay', '--ros-args',
         '-p', f'bag:={bag}', '-p', 'rate:=0.0'],
        env=node_env, capture_output=True, text=True, timeout=60)
    output = proc.stdout + proc.stderr
    assert proc.returncode == 1, output
    assert 'Traceback' not in output
    errors = [ln for ln in output.splitlines() if 'cannot start' in ln]
    assert len(errors) == 1 and str(bag) in errors[0], output
