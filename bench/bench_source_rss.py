"""RSS of ``gcode_trajectory``'s setpoint source over a long job, glibc's mmap threshold dynamic
or fixed (``heap.py``).

    PYTHONPATH=. .venv/bin/python bench/bench_source_rss.py [--pairs 150]

Writes the soak program of ``bench/bench_soak.py`` (``--pairs`` strokes of 100 mm back and
forth at 3 m/min on ``three_axis_mill_drives.yaml``; 150: 619 s), then, in one child process
per mode, plans it with :class:`~feed_axis_energy.graph.SetpointSource` as the node does
(survey, then every batch of 100 samples) and prints the RSS and Python's traced memory
(tracemalloc) at 10 %, 50 % and the end of the batches: ``dynamic`` (glibc's default) and
``fixed`` (:func:`feed_axis_energy.heap.fix_mmap_threshold`, what the node calls).
"""
from __future__ import annotations

import argparse
import json
import os
from pathlib import Path
import subprocess
import sys
import tempfile

ROOT = Path(__file__).resolve().parents[1]

CHILD = r'''
import json, sys, tracemalloc
mode, program = sys.argv[1], sys.argv[2]
if mode == 'fixed':
    from feed_axis_energy.heap import fix_mmap_threshold
    assert fix_mmap_threshold(), 'mallopt refused (not glibc?)'
from feed_axis_energy.gcode import iter_moves
from feed_axis_energy.graph import SetpointSource
from feed_axis_energy.machine import load_machine
from feed_axis_energy.paths import config_dir
from feed_axis_energy.plan import iter_motion

def rss_mib():
    with open('/proc/self/status') as f:
        for line in f:
            if line.startswith('VmRSS:'):
                return int(line.split()[1]) / 1024.0

machine = load_machine(config_dir() / 'three_axis_mill_drives.yaml')
options, keywords, limits = machine.planner.options(), machine.gcode_keywords(), machine.limits()
source = SetpointSource(lambda: iter_motion(iter_moves(program, **keywords), limits,
                                            options=options, file=program), batch=100)
survey = source.survey()
tracemalloc.start()
marks = {survey.n_batches // 10: '10 %', survey.n_batches // 2: '50 %',
         survey.n_batches - 1: 'end'}
out = {'samples': survey.n_samples, 'duration_s': survey.duration_s,
       'after_survey_mib': rss_mib(), 'marks': []}
for b in source.batches():
    if b.index in marks:
        out['marks'].append((marks[b.index], rss_mib(),
                             tracemalloc.get_traced_memory()[0] / 2 ** 20))
print(json.dumps(out))
'''


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--pairs', type=int, default=150,
                        help='strokes back and forth (150: a 619 s program)')
    args = parser.parse_args()
    if args.pairs < 1:
        parser.error('--pairs must be >= 1')
    env = {k: v for k, v in os.environ.items() if k != 'MALLOC_MMAP_THRESHOLD_'}
    env['PYTHONPATH'] = str(ROOT)
    with tempfile.TemporaryDirectory(prefix='fae-bench-rss-') as tmp:
        program = Path(tmp) / 'soak.nc'
        program.write_text('G21 G90 G94 G61\nG0 X0\n' + 'G1 X100 F3000\nG1 X0 F3000\n'
                           * args.pairs + 'M2\n')
        for mode in ('dynamic', 'fixed'):
            proc = subprocess.run([sys.executable, '-c', CHILD, mode, str(program)], env=env,
                                  capture_output=True, text=True, timeout=1800)
            if proc.returncode:
                print(f'{mode}: failed\n{proc.stderr[-2000:]}', file=sys.stderr)
                return 1
            r = json.loads(proc.stdout.strip().splitlines()[-1])
            marks = ', '.join(f'{name} {rss:.1f} MiB (traced {traced:.2f} MiB)'
                              for name, rss, traced in r['marks'])
            first, last = r['marks'][0][1], r['marks'][-1][1]
            print(f"{mode:7s}: {r['samples']} samples, {r['duration_s']:.1f} s of program; "
                  f"RSS after the survey {r['after_survey_mib']:.1f} MiB; batches {marks}; "
                  f"10 % -> end {last - first:+.1f} MiB")
    return 0


if __name__ == '__main__':
    sys.exit(main())
