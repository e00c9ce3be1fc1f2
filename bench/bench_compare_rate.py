"""``compare`` on measured runs at drive-trace rates: wall time and peak RSS against length.

Usage: ``PYTHONPATH=. .venv/bin/python bench/bench_compare_rate.py [--minutes 1,10,80]
[--noise-w W] [--offset-ms MS] [--timeout S]``

For each length, a temporary directory (never the repository) gets:

* the demonstrator's reciprocating program (400 mm strokes at 100..500 mm/s with a 1 s dwell
  after each, cycling through the feeds, as ``bench_scale.py``) filling that many minutes;
* a "measured" CSV at 1 kHz: the program's own simulated total power (``simulate_stream``
  on ``config/demonstrator.yaml`` at its 1 kHz rate, streamed chunk by chunk), delayed by a
  known offset (2 s of standstill before the program plus ``--offset-ms``, default
  1234 ms: 3.234 s in all), averaged over the 1 ms window ending at
  each stamp (the instrument ``compare`` assumes by default), plus Gaussian noise
  (``--noise-w``, default 2 W), written in W with a time column in s; 2 s of standstill
  after the program;
* a one-run manifest.

``python -m feed_axis_energy compare MANIFEST --json --quiet`` then runs as a child
process (process start included); it is reaped with ``os.wait4`` for its own peak RSS
(``ru_maxrss``) and CPU time. Printed per length: measured samples, wall and CPU time, peak
RSS, the found offset and its error, the status, the energy error and the RMSE (which
should be close to the noise), and the cost relative to the first length. A child that runs
longer than ``--timeout`` is killed and reported as not finished. The issue's targets
(issue 24): 10 min <= 12 x the 1 min case, <= 60 s and <= 500 MB; 80 min within 600 s and
500 MB.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path
import sys
import tempfile
import time
from typing import IO

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from child_cli import run_cli  # noqa: E402

from feed_axis_energy.gcode import iter_moves  # noqa: E402,I100
from feed_axis_energy.machine import load_machine  # noqa: E402
from feed_axis_energy.paths import config_dir  # noqa: E402
from feed_axis_energy.sim import simulate_stream  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
FEEDS_MM_S = (100, 200, 300, 400, 500)
PAD_S = 2.0


def program_text(minutes: float) -> str:
    """Reciprocating strokes cycling through the five feeds until ``minutes`` are filled."""
    lines = ['( bench: repeated demonstrator strokes )', 'G21 G90 G94 G61', 'G0 X0', 'G4 P1']
    t, i = 1.0, 0
    while t < minutes * 60.0:
        f = FEEDS_MM_S[i % len(FEEDS_MM_S)]
        lines += [f'G1 X400 F{f * 60}', 'G4 P1', 'X0', 'G4 P1']
        t += 2 * (400.0 / f + 1.0)
        i += 1
    lines.append('M30')
    return '\n'.join(lines) + '\n'


class MeterWriter:
    """The 1 kHz meter: delayed, 1 ms-window-averaged, noisy power rows, chunk by chunk."""

    def __init__(self, fh: IO[str], *, offset_ms: int, noise_w: float, seed: int):
        self.fh = fh
        self.offset = offset_ms
        self.noise = noise_w
        self.rng = np.random.default_rng(seed)
        self.row = 0
        self.prev: float | None = None
        fh.write('time_s,X_power_W\n')

    def _write(self, p: np.ndarray) -> None:
        t = (self.row + np.arange(p.size)) * 1e-3
        y = p + self.rng.normal(0.0, self.noise, p.size)
        np.savetxt(self.fh, np.column_stack([t, y]), fmt=['%.3f', '%.4f'], delimiter=',')
        self.row += p.size

    def add(self, p_sim: np.ndarray) -> None:
        """Simulated power at 1 kHz, the next samples of the program."""
        if self.prev is None:
            # standstill before the program starts, and the record's lead of ``offset``
            self._write(np.full(int(PAD_S * 1e3) + self.offset, float(p_sim[0])))
            self.prev = float(p_sim[0])
        both = np.concatenate([[self.prev], p_sim])
        self._write(0.5 * (both[1:] + both[:-1]))     # mean over the 1 ms window
        self.prev = float(p_sim[-1])

    def close(self) -> None:
        """Standstill after the program."""
        self._write(np.full(int(PAD_S * 1e3), float(self.prev or 0.0)))


def build(root: Path, minutes: float, *, offset_ms: int, noise_w: float) -> tuple[Path, int]:
    """Program, measured CSV and manifest in ``root``; returns the manifest and the rows."""
    prog = root / 'reciprocating.nc'
    prog.write_text(program_text(minutes))
    machine_file = config_dir() / 'demonstrator.yaml'
    machine = load_machine(machine_file)
    with open(root / 'run.csv', 'w') as fh:
        meter = MeterWriter(fh, offset_ms=offset_ms, noise_w=noise_w, seed=24)
        simulate_stream(iter_moves(prog, **machine.gcode_keywords()), machine, file=str(prog),
                        on_chunk=lambda chunk: meter.add(chunk.power.total_w))
        meter.close()
    manifest = {'name': 'rate', 'machine': str(machine_file),
                'defaults': {'time': {'column': 'time_s', 'unit': 's'},
                             'axes': {'X': {'power': {'column': 'X_power_W', 'unit': 'W'}}}},
                'runs': [{'name': f'm{minutes:g}', 'load_kg': 0.0, 'data': 'run.csv',
                          'motion': {'program': prog.name}}]}
    path = root / 'campaign.yaml'
    path.write_text(json.dumps(manifest))
    return path, meter.row


def run_compare(manifest: Path, timeout_s: float) -> tuple[float, float, int, dict | None]:
    """``compare --json`` as a child: wall [s], CPU [s], peak RSS [bytes], the JSON or None."""
    child = run_cli(['compare', str(manifest), '--json', '--quiet'], timeout_s=timeout_s)
    if child.code != 0 and child.wall_s <= timeout_s:
        sys.exit(f'compare exited {child.code}: {child.stderr[-800:]}')
    result = json.loads(child.stdout) if child.code == 0 else None
    return child.wall_s, child.cpu_s, child.peak_rss_bytes, result


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--minutes', default='1,10,80',
                    help='lengths of the runs [min], comma-separated (default: 1,10,80)')
    ap.add_argument('--noise-w', type=float, default=2.0, help='meter noise SD [W]')
    ap.add_argument('--offset-ms', type=int, default=1234,
                    help='how much later the measured record is [ms] (default: 1234)')
    ap.add_argument('--timeout', type=float, default=900.0,
                    help='kill a compare after this many seconds (default: 900)')
    args = ap.parse_args()
    minutes = [float(m) for m in args.minutes.split(',') if m.strip()]
    first: tuple[float, float] | None = None
    ok = True
    for m in minutes:
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            manifest, rows = build(Path(tmp), m, offset_ms=args.offset_ms,
                                   noise_w=args.noise_w)
            size = (Path(tmp) / 'run.csv').stat().st_size
            print(f'{m:g} min: {rows:,} rows at 1 kHz ({size / 1e6:.0f} MB CSV) generated in '
                  f'{time.perf_counter() - t0:.1f} s', flush=True)
            wall, cpu, rss, res = run_compare(manifest, args.timeout)
        line = (f'  compare: wall {wall:.1f} s  CPU {cpu:.1f} s  peak RSS {rss / 2**20:.0f} MiB')
        if res is None:
            print(f'{line}  NOT FINISHED (killed after {args.timeout:g} s)', flush=True)
            ok = False
            continue
        r = res['runs'][0]
        off = r['offset']['found_s']
        truth = PAD_S + args.offset_ms / 1e3      # the record starts PAD_S before the program
        metrics = r['metrics']['total']
        ppm = r['offset']['drift_ppm']
        # a record shorter than the drift estimate needs has none (DRIFT_MIN_DURATION_S)
        drift = 'drift not estimated' if ppm is None else f'drift {ppm:+.0f} ppm'
        line += (f'  offset {off:+.4f} s (error {1e3 * (off - truth):+.3f} ms, '
                 f'{r["offset"]["status"]}, {drift})  '
                 f'energy error {metrics["energy_error_pct"]:+.3f} %'
                 f'  RMSE {metrics["rmse_w"]:.3f} W')
        if first is None:
            first = (wall, cpu)
        else:
            line += f'  x{wall / first[0]:.1f} wall, x{cpu / first[1]:.1f} CPU of the first'
        print(line, flush=True)
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())
