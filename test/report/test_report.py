"""write_report: one index.html with three plots per run embedded, written all or nothing."""
from __future__ import annotations

import base64
from dataclasses import replace
import importlib.util
from pathlib import Path
import re
import subprocess
import sys

import numpy as np
import pytest

from feed_axis_energy.measured.manifest import load_campaign
from feed_axis_energy.measured.compare import compare_campaign
from feed_axis_energy.errors import OutputError
from feed_axis_energy.report import MARKER, PLOT_KINDS, write_report
import feed_axis_energy.report.plots as plots

_HELPER = Path(__file__).resolve().parents[1] / 'measured' / 'test_compare.py'


def _synthetic():
    spec = importlib.util.spec_from_file_location('_synthetic_campaign', _HELPER)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope='module')
def comparison(tmp_path_factory):
    root = tmp_path_factory.mktemp('campaign')
    manifest = _synthetic().write_campaign(root, [
        {'name': 'zero load', 'load_kg': 0.0, 'offset_ms': 250, 'noise_w': 0.2},
        {'name': 'heavy', 'load_kg': 22.711, 'offset_ms': 100, 'factor': 1.05,
         'noise_w': 0.2},
    ])
    return compare_campaign(load_campaign(manifest), max_lag_s=1.0)


def test_report_is_one_page_with_every_plot_embedded(comparison, tmp_path):
    out = tmp_path / 'report'
    index = write_report(comparison, out)
    assert index == out / 'index.html'
    assert sorted(p.name for p in out.iterdir()) == sorted([MARKER, 'index.html'])
    page = index.read_text()
    srcs = re.findall(r'<img src="([^"]+)"', page)
    assert len(srcs) == len(PLOT_KINDS) * len(comparison.runs)
    for src in srcs:
        head, data = src.split(',', 1)
        assert head == 'data:image/png;base64'
        assert base64.b64decode(data)[:8] == b'\x89PNG\r\n\x1a\n'
    # the one-line answer comes first and names the worst run
    answer = re.search(r'<p class="answer">(.*?)</p>', page, re.S).group(1)
    assert 'simulated energy is within' in answer and 'heavy' in answer
    assert page.index('class="answer"') < page.index('Per run') < page.index('Per load')
    # summary first: the per-load table comes before the first run section
    assert page.index('Per load') < page.index('<section')
    for label in ('Average differential error [W]', 'Average percentual error [%]',
                  'Maximum differential error [W]', 'Maximum percentual error [%]',
                  'Energy error [J]', 'Energy error [%]', 'RMSE [W]'):
        assert label in page
    # provenance: the data file names and the offsets found
    for run in comparison.runs:
        assert Path(run.data_file).name in page
        assert f'{run.offset_used_s:+.3f}' in page
    assert 'heavy' in page and '22.711 kg' in page
    assert not list(tmp_path.glob('.report.*'))         # no temporary left behind


def test_an_earlier_report_is_replaced_but_a_foreign_directory_is_not(comparison, tmp_path):
    comparison = replace(comparison, runs=comparison.runs[:1])    # one run is enough here
    out = tmp_path / 'r'
    write_report(comparison, out)
    (out / 'stale.png').write_bytes(b'x')
    # replaced only with force (it was replaced silently before)
    with pytest.raises(OutputError, match='exists already'):
        write_report(comparison, out)
    assert (out / 'stale.png').exists()
    write_report(comparison, out, force=True)
    assert (out / MARKER).exists() and not (out / 'stale.png').exists()
    foreign = tmp_path / 'mine'
    foreign.mkdir()
    (foreign / 'notes.txt').write_text('keep me')
    with pytest.raises(OutputError, match='not an earlier output'):
        write_report(comparison, foreign, force=True)
    assert [p.name for p in foreign.iterdir()] == ['notes.txt']


def test_a_failure_leaves_nothing_half_written(comparison, tmp_path, monkeypatch):
    comparison = replace(comparison, runs=comparison.runs[:1])
    out = tmp_path / 'r'
    write_report(comparison, out)
    before = sorted(p.name for p in out.iterdir())

    def broken(*args, **kwargs):
        raise RuntimeError('disk full')

    monkeypatch.setattr(plots, 'plot_error', broken)
    with pytest.raises(RuntimeError, match='disk full'):
        write_report(comparison, out, force=True)
    assert sorted(p.name for p in out.iterdir()) == before     # earlier report intact
    assert sorted(p.name for p in tmp_path.iterdir()) == ['r']  # temporary removed


def test_report_imports_neither_pyplot_nor_ros():
    code = ('import sys, feed_axis_energy.report; '
            'print(sorted(m for m in sys.modules if m == "rclpy" or m.endswith("_msgs") '
            'or m == "matplotlib.pyplot"))')
    proc = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          timeout=60, check=True)
    assert proc.stdout.strip() == '[]'


def test_pct_scale_is_not_set_by_one_sample():
    pct = np.concatenate((np.linspace(0.0, 5.0, 999), [100.0]))
    limit, above = plots.pct_scale(pct)
    assert 5.0 < limit < 6.0 and above == 1
    # without an outlier nothing is clipped and the largest sample is inside the scale
    limit, above = plots.pct_scale(np.linspace(0.0, 5.0, 1000))
    assert above == 0 and limit >= 5.0
    assert plots.pct_scale(np.full(3, np.nan)) == (1.0, 0)
