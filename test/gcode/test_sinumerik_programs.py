"""Real Sinumerik programs from ../shared: the eight NC programs of the KIT data set and the
corpus's three Sinumerik programs, with paths derived by hand from their text.

KIT data: "Training and validation dataset of milling processes for time series
prediction", KIT wbk, DOI 10.5445/IR/1000157789, CC BY-NC-ND 4.0 -- read unmodified from
``../shared/data/kit-dmc60h/nc`` (see its PROVENANCE.md), never copied here.
"""
from __future__ import annotations

import math
from pathlib import Path
import subprocess
import sys

import must_run
import pytest
from shared_data import shared_path, SKIP_REASON

from feed_axis_energy.errors import GcodeError
from feed_axis_energy.gcode import iter_moves, load_gcode
from feed_axis_energy.gcode.program import MoveKind
from feed_axis_energy.gcode.stats import arc_extremes

MM = 1e-3
KIT = shared_path('data', 'kit-dmc60h', 'nc')
CORPUS = shared_path('corpus', 'gcode', 'John15321__CNC')
needs_kit = must_run.skipif('shared', KIT is None, f'KIT NC programs: {SKIP_REASON}')
needs_corpus = must_run.skipif('shared', CORPUS is None, f'corpus/gcode: {SKIP_REASON}')

FEED = (MoveKind.LINEAR, MoveKind.ARC_CW, MoveKind.ARC_CCW)
ARCS = (MoveKind.ARC_CW, MoveKind.ARC_CCW)

# The four training programs (two machines, two materials) share one path, as do the four
# validation programs: only S and F differ, and the DMC 60H ones add G57, "G1 B0" (the
# rotary table to 0, dropped here with ignore_axes) and M6 on its own line.
TRAINING = ['DMC_60H/AL2007_TRAINING.MPF', 'DMC_60H/V_S235_TRAINING.MPF',
            'DMG_CMX_600V/AL2007_Training.MPF', 'DMG_CMX_600V/V_S235_Training.MPF']
VALIDATION = ['DMC_60H/AL2007_VALIDATION.MPF', 'DMC_60H/V_S235JR_VALIDATION.MPF',
              'DMG_CMX_600V/AL2007_Validation.MPF', 'DMG_CMX_600V/V_S235JR_Validation.MPF']

# Training, by hand from the text:
#  level 1, 20 mm cutter at Z-10: 7 passes X-20 <-> X95 (115 mm each) at Y10..65, then
#  7 passes Y55 <-> Y170 (115 mm each) at X10..65: 14 * 115 = 1610 mm;
#  level 2, 10 mm cutter at Z-15: approach Y-10 -> Y15 (25 mm), full circles about
#  (32.5, 50) of radius 35, 25, 20, 15 with 10 + 5 + 5 mm steps between them;
#  5 mm cutter at Z-13: approach Y185 -> Y160 (25 mm), full circles about (32.5, 137.5)
#  of radius 22.5, 17.5, 15, 12.5 with 5 + 2.5 + 2.5 mm steps.
TRAINING_FEED_MM = (1610 + 25 + 10 + 5 + 5 + 2 * math.pi * (35 + 25 + 20 + 15)
                    + 25 + 5 + 2.5 + 2.5 + 2 * math.pi * (22.5 + 17.5 + 15 + 12.5))
# feed moves span X -20..95 (level 1; the circles reach X -2.5..67.5), Y -10..185 (the
# approaches of the 10 mm and 5 mm cutters feed from Y-10 and Y185; level 1 spans Y10..170,
# the circles Y15..85 and Y115..160), Z -15..-10
TRAINING_BOX_MM = ((-20.0, -10.0, -15.0), (95.0, 185.0, -10.0))

# Validation, by hand: approach Y-10 -> Y10 (20 mm) at Z-5; outer rounded square X10..65,
# Y10..65 with corners of radius 17.5 (4 quarter arcs, straight sides 10 + 20 + 20 + 20 +
# 10 mm); step to Y15 (5 mm); inner one X15..60, Y15..60, radius 12.5 (sides 10 + 20 +
# 20 + 20 + 10); cross: (37.5,15) -> (15,15) 22.5 mm, the two diagonals 45*sqrt(2) and the
# top side 45 mm.
VALIDATION_FEED_MM = (20 + 80 + 2 * math.pi * 17.5 + 5 + 80 + 2 * math.pi * 12.5
                      + 22.5 + 2 * 45 * math.sqrt(2) + 45)
VALIDATION_BOX_MM = ((10.0, -10.0, -5.0), (65.0, 65.0, -5.0))


def feed_summary(moves):
    """(feed path length [mm], number of arcs, feed-move box [mm]) of a program."""
    feed = [m for m in moves if m.kind in FEED]
    pts = [m.start for m in feed] + [m.end for m in feed]
    for m in feed:
        if m.kind in ARCS:
            pts += arc_extremes(m)
    lo = tuple(min(p[i] for p in pts) / MM for i in range(3))
    hi = tuple(max(p[i] for p in pts) / MM for i in range(3))
    return sum(m.length_m for m in feed) / MM, sum(m.kind in ARCS for m in feed), (lo, hi)


@needs_kit
@pytest.mark.parametrize('name, feed_mm, n_arcs, box', [
    *[(n, TRAINING_FEED_MM, 8, TRAINING_BOX_MM) for n in TRAINING],
    *[(n, VALIDATION_FEED_MM, 8, VALIDATION_BOX_MM) for n in VALIDATION],
])
def test_kit_programs_run_with_the_path_of_their_text(name, feed_mm, n_arcs, box):
    path = KIT / name
    # the dialect is chosen from the .MPF suffix; B (rotary table) is not an axis here
    prog = load_gcode(path, ignore_axes=['B'])
    length, arcs, (lo, hi) = feed_summary(prog.moves)
    assert length == pytest.approx(feed_mm, abs=1e-6)
    assert arcs == n_arcs
    assert lo == pytest.approx(box[0], abs=1e-9) and hi == pytest.approx(box[1], abs=1e-9)
    assert any('sinumerik' in w for w in prog.warnings)
    # the final G0 Z100 of every program, and the streamed moves equal the collected ones
    assert prog.moves[-2].end[2] / MM == pytest.approx(100.0)
    assert [m.end for m in iter_moves(path, ignore_axes=['B'])] == [m.end for m in prog.moves]


@needs_kit
def test_kit_dmc_program_names_its_rotary_word_without_ignore_axes():
    with pytest.raises(GcodeError, match='B') as info:
        load_gcode(KIT / 'DMC_60H/V_S235JR_VALIDATION.MPF')
    assert info.value.line == 12     # "G1 B0 F1500"


@needs_corpus
def test_corpus_przyklad_is_accepted():
    prog = load_gcode(CORPUS / 'Gcode__PRZYKLAD.nc', dialect='sinumerik')
    length, arcs, (lo, hi) = feed_summary(prog.moves)
    # face milling at Z0: three passes X-25 <-> X125 (150 mm each); contour at Z-21: X-15 ->
    # X0 (15), Y35 -> Y75 (40), X0 -> X100 (100), Y75 -> Y0 (75), X100 -> X0 (100),
    # Y0 -> Y35 (35), X0 -> X-15 (15)
    assert length == pytest.approx(3 * 150 + 15 + 40 + 100 + 75 + 100 + 35 + 15)
    assert arcs == 0
    assert lo == pytest.approx((-25, 0, -21)) and hi == pytest.approx((125, 75, 0))


@needs_corpus
@pytest.mark.parametrize('name, refusals', [
    # the first line of each refused construct (each is refused at every place: counted
    # below); Zadanie also calls a subprogram file that is not in the corpus (EXTCALL "Zgrubne
    # ogolne.spf")
    ('FinitoFinale__Zadanie.MPF', ({'Zgrubne ogolne.spf': 74, 'ANG=': 181, 'RND=': 184,
                                    'POCKET4': 232, 'POCKET3': 258, 'HOLES1': 286, 'HOLES2': 292,
                                    'CYCLE801': 297, 'CYCLE840': 389}, 21)),
    ('Zad2__PRZYKLAD.nc', ({'ANG=': 183, 'RND=': 186, 'POCKET4': 242, 'POCKET3': 268,
                            'HOLES1': 296, 'HOLES2': 302, 'CYCLE801': 307, 'CYCLE840': 399},
                           20)),
])
def test_corpus_programs_refused_by_name_at_every_place(name, refusals):
    refusals, n_places = refusals
    path = CORPUS / name
    with pytest.raises(GcodeError):
        load_gcode(path, dialect='sinumerik')
    stream = iter_moves(path, dialect='sinumerik', max_errors=1000)
    list(stream)
    first: dict[str, int] = {}
    for err in stream.errors:
        for key in refusals:
            if err.text.startswith(key) or key in err.reason.split(' (')[0]:
                first.setdefault(key, err.line)
    assert first == refusals
    # RND= 6 times, ANG= twice, POCKET3/4 twice each, CYCLE801 twice, CYCLE840 three times,
    # HOLES1 and HOLES2 once (their REPEATB repeats name the same place once)
    assert len(stream.errors) == n_places
    assert len({(e.line, e.column) for e in stream.errors}) == n_places


@needs_kit
def test_readme_simulate_command_on_a_kit_program():
    repo = Path(__file__).resolve().parents[2]
    out = subprocess.run([sys.executable, '-m', 'feed_axis_energy', 'simulate',
                          str(KIT / 'DMC_60H/V_S235JR_VALIDATION.MPF'), '--machine',
                          str(repo / 'config/three_axis_mill.yaml'), '--ignore-axes', 'B'],
                         capture_output=True, text=True, cwd=repo, timeout=300)
    assert out.returncode == 0, out.stderr
    assert 'read in the sinumerik dialect' in out.stderr
    assert 'energy [J]' in out.stdout
