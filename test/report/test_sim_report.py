"""simulate's report: one self-contained page plus its images, numbers for people."""
from __future__ import annotations

import re
from types import SimpleNamespace

import numpy as np
import pytest

from feed_axis_energy.errors import OutputError
from feed_axis_energy.report import MARKER
from feed_axis_energy.report.decimate import PowerTrace
from feed_axis_energy.report.page import fmt_duration, fmt_pct, fmt_si, short
from feed_axis_energy.report.sim_report import (CAUSE_KEY, causes_by_axis,
                                                causes_from_summary, rollups_from_summary,
                                                top_lines, write_sim_report)


@pytest.mark.parametrize('value, unit, text', [
    (14213.0, 'J', '14.2 kJ'), (830.4, 'W', '830 W'), (0.0412, 'm', '41.2 mm'),
    (0.0, 'J', '0 J'), (-88.37, 'J', '-88.4 J'), (2.5e6, 'J', '2.50 MJ'),
    (float('nan'), 'J', '–'), (float('inf'), 'W', '–'), (4.2e-7, 'J', '420 nJ'),
    (1.73e-17, 'J', '1.73e-17 J'), (-6e-18, 'J', '-6.00e-18 J')])
def test_si_numbers_have_three_significant_digits_and_a_prefix(value, unit, text) -> None:
    assert fmt_si(value, unit) == text


def test_percentages_durations_and_quoted_text() -> None:
    assert fmt_pct(61.7) == '62 %'
    assert fmt_pct(4.26) == '4.3 %'
    assert fmt_pct(0.523) == '0.52 %'
    assert fmt_pct(3.0, signed=True) == '+3.0 %'
    assert fmt_duration(192.4) == '3 min 12 s'
    assert fmt_duration(7500.0) == '2 h 05 min'
    assert fmt_duration(0.35) == '350 ms'
    assert len(short('x' * 500)) == 60


def _trace(n: int = 3000) -> PowerTrace:
    t = np.arange(n) * 1e-3
    power = np.column_stack((np.sin(t) ** 2 * 100.0, np.full(n, 5.0)))
    total = power.sum(axis=1)
    energy = np.cumsum(np.column_stack((power, total)), axis=0) * 1e-3
    chunk = SimpleNamespace(
        power=SimpleNamespace(t=t, axes=('X', 'Y'), power_w=power, total_w=total,
                              energy_j=energy[:, :2], total_energy_j=energy[:, 2],
                              line=1 + np.arange(n) // 1000),
        motion=SimpleNamespace(pos=np.column_stack((t * 0.01, t * 0.02))))
    trace = PowerTrace(columns=300)
    trace.add(chunk)
    return trace


def _summary(**extra) -> dict:
    base = {'program': '/x/part.ngc', 'machine': 'M', 'load_kg': 50.0, 'duration_s': 192.4,
            'samples': 3000, 'rate_hz': 1000.0, 'braking': 'regenerative',
            'energy_j': {'X': 10000.0, 'Y': 4200.0, 'total': 14200.0},
            'peak_power_w': {'X': 100.0, 'Y': 5.0, 'total': 105.0},
            'regenerated_energy_j': 300.0, 'loss_energy_j': 8800.0, 'top_blocks': []}
    base.update(extra)
    return base


BLOCKS = [(1, 3000.0, 1.0), (2, 9000.0, 1.0), (3, -400.0, 1.0), (4, 9000.0, 0.5)]


def test_top_lines_largest_magnitude_first_ties_by_line() -> None:
    assert [r[0] for r in top_lines(BLOCKS, 3)] == [2, 4, 1]
    assert top_lines([], 5) == []


def test_the_page_is_self_contained_and_answers_in_one_line(tmp_path) -> None:
    out = tmp_path / 'rep'
    texts = {1: 'G0 X10', 2: 'G1 X50 F3000 (a <b> tag)', 3: 'G4 P1', 4: 'G1 Y1'}
    index = write_sim_report(_summary(), _trace(), BLOCKS, out,
                             block_text=lambda lines: {n: texts[n] for n in lines})
    html = index.read_text()
    files = {p.name for p in out.iterdir()}
    assert files == {'index.html', MARKER, 'power.png', 'energy.png', 'path.png',
                     'blocks.png', 'causes.png'}
    # every image is embedded: no src that needs a file or the network
    srcs = re.findall(r'<img src="([^"]+)"', html)
    assert len(srcs) == 5 and all(s.startswith('data:image/png;base64,') for s in srcs)
    assert 'http' not in html.replace('http-equiv', '')
    assert '@media print' in html and 'size: A4' in html
    answer = re.search(r'<p class="answer">(.*?)</p>', html, re.S).group(1)
    assert '14.2 kJ per part' in answer and '3 min 12 s' in answer
    assert '62 % of it friction' in answer            # 8.8 kJ of 14.2 kJ
    assert 'a &lt;b&gt; tag' in html                   # block text escaped
    assert 'returned to the supply' in html
    assert not list(tmp_path.glob('.rep*'))


def test_a_full_breakdown_and_rollups_plug_in_from_plain_data(tmp_path) -> None:
    # the keys the cause branch publishes (/work/wt/notes/cause-api.md); the parts add up
    causes = {'friction': {'X': 6000.0, 'Y': 2800.0, 'total': 8800.0},
              'gravity_lift': {'X': 0.0, 'Y': 3000.0, 'total': 3000.0},
              'gravity_lower': {'X': 0.0, 'Y': -1000.0, 'total': -1000.0},
              'rotary_inertia': {'X': 2000.0, 'Y': 700.0, 'total': 2700.0},
              'effect:load_friction:X': {'X': 2000.0, 'Y': 0.0, 'total': 2000.0},
              'braking_burned': {'X': 0.0, 'Y': -1300.0, 'total': -1300.0}}
    summary = _summary(**{
        CAUSE_KEY: causes, 'causes': list(causes), 'braking_returned_j': 300.0,
        'gross_by_cause_j': {'gravity_lift': {'X': 0.0, 'Y': 3000.0, 'total': 3000.0},
                             'rotary_inertia': {'X': 2500.0, 'Y': 1270.0, 'total': 3770.0}},
        'rollups': {'operation': [{'name': 'O100 pocket', 'energy_j': 9000.0,
                                   'duration_s': 100.0},
                                  {'name': 'T2 drill', 'energy_j': 5200.0,
                                   'duration_s': 92.4}],
                    'subroutine': [{'name': 'o<pocket>', 'energy_j': 14200.0,
                                    'duration_s': 192.4}],
                    'tool': [{'name': 'T2', 'energy_j': 14200.0, 'duration_s': 192.4}],
                    'axis': [{'name': 'X', 'energy_j': 10000.0, 'duration_s': 192.4}]}})
    rows, full = causes_from_summary(summary)
    assert full
    assert [r[0] for r in rows] == [
        'friction (passive resistance)', 'lifting against gravity', 'lowering with gravity',
        'accelerating screw and rotor (net)', 'declared effect load_friction on X',
        'braking energy burned in the resistor']
    assert sum(r[1] for r in rows) == pytest.approx(summary['energy_j']['total'])
    axes, per_axis = causes_by_axis(summary)
    assert axes == ['X', 'Y'] and per_axis[1] == [0.0, 3000.0]
    assert set(rollups_from_summary(summary)) == {'operation', 'subroutine', 'tool'}
    html = write_sim_report(summary, _trace(), BLOCKS, tmp_path / 'r').read_text()
    assert 'O100 pocket' in html and 'Per operation' in html and 'Per tool' in html
    assert '<th>axis X</th>' in html and '+3.00 kJ' in html
    assert 'taken before giving back' in html and '3.77 kJ' in html
    assert 'o&lt;pocket&gt;' in html
    assert 'do not add up' not in html
    assert '62 % of it friction' in html           # the largest part, 8.8 of 14.2 kJ


def test_without_a_breakdown_the_page_says_what_it_shows(tmp_path) -> None:
    rows, full = causes_from_summary(_summary(braking='dissipated'))
    assert not full
    assert rows[1] == ('braking energy burned in the brake resistor (not in the total)',
                       300.0, False)
    html = write_sim_report(_summary(), _trace(), [], tmp_path / 'r').read_text()
    assert 'do not add up to the total' in html
    assert 'No source lines' in html


def test_an_existing_directory_is_kept_unless_force(tmp_path) -> None:
    out = tmp_path / 'r'
    write_sim_report(_summary(), _trace(), BLOCKS, out)
    with pytest.raises(OutputError, match='exists already'):
        write_sim_report(_summary(), _trace(), BLOCKS, out)
    write_sim_report(_summary(load_kg=1.0), _trace(), BLOCKS, out, force=True)
    assert '1.00 kg' in (out / 'index.html').read_text()


def test_a_report_without_samples(tmp_path) -> None:
    summary = _summary(samples=0, duration_s=0.0, energy_j={'X': 0.0, 'Y': 0.0, 'total': 0.0},
                       loss_energy_j=0.0, regenerated_energy_j=0.0)
    html = write_sim_report(summary, PowerTrace(), [], tmp_path / 'r').read_text()
    assert '0 J per part' in html and 'No source lines' in html


def test_the_loss_function_uncertainty_is_in_the_answer_where_known(tmp_path) -> None:
    spread = {'energy_sd_j': {'X': 213.0, 'total': 213.0}, 'relative_pct': 1.5,
              'axes': ['X'], 'axes_without': ['Y'], 'gradient': {'X': {'a': 1.0}},
              'units': {'X': {'a': 'N'}}, 'method': 'delta method'}
    index = write_sim_report(_summary(energy_uncertainty=spread), _trace(), BLOCKS,
                             tmp_path / 'rep')
    html = index.read_text()
    answer = re.search(r'<p class="answer">(.*?)</p>', html, re.S).group(1)
    assert '±210 J (±1.5 % of the total) from the loss-function uncertainty' in answer
    assert '±213 J' in html and 'not known' in html       # per axis: X known, Y not
    plain = write_sim_report(_summary(), _trace(), BLOCKS, tmp_path / 'plain').read_text()
    assert 'uncertainty' not in plain
