"""config/foxglove_layout.json opens the demo's bags: every plotted path exists there."""
import json
from pathlib import Path
import re

from feed_axis_energy.cli import main
from feed_axis_energy.record import bagio
from feed_axis_energy.record.plotread import read_plot_topic

REPO = Path(__file__).resolve().parents[2]
LAYOUT = REPO / 'config' / 'foxglove_layout.json'
_PATH = re.compile(r'^(?P<topic>/[\w/]+)\.(?P<field>position|velocity|effort)'
                   r'\[(?P<index>\d+|:)\]$')


def _paths(layout: dict) -> list[str]:
    return [p['value'] for cfg in layout['configById'].values() for p in cfg.get('paths', [])]


def test_layout_panels_are_placed_and_paths_are_well_formed():
    layout = json.loads(LAYOUT.read_text(encoding='utf-8'))
    placed = set(re.findall(r'"([^"]+![^"]+)"', json.dumps(layout['layout'])))
    assert placed == set(layout['configById'])
    paths = _paths(layout)
    assert len(paths) >= 6
    assert all(_PATH.match(p) for p in paths), paths


def test_layout_paths_exist_in_the_demo_bag(tmp_path):
    out = tmp_path / 'demo'
    assert main(['demo', '--out', str(out), '--quiet']) == 0
    bags = sorted(p for p in out.iterdir() if (p / 'metadata.yaml').exists())
    assert bags
    layout = json.loads(LAYOUT.read_text(encoding='utf-8'))
    for bag in bags[:1]:
        topics = bagio.bag_topics(bag)
        for path in _paths(layout):
            m = _PATH.match(path)
            assert m['topic'] in topics and topics[m['topic']][1] > 0, path
            series = read_plot_topic(bag, m['topic'])
            values = getattr(series, m['field'])
            assert values is not None, path                  # the field is filled
            if m['index'] != ':':
                assert int(m['index']) < len(series.names), path
