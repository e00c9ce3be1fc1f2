"""The recording writer alone: samples per second of ``SimulationBagWriter`` on one core.

Usage: PYTHONPATH=. python bench/bench_record.py [--case demonstrator|contour|both]
       [--minutes M] [--compression zstd,lz4,none] [--repeat R]
       [--background] [--plot-rate-hz off,20,0] [--floor]

Simulates M minutes (default 20) of the bench_scale programs (1 axis demonstrator, 3 axis
contour) once, keeps the chunks in memory, then times only the writing of those chunks as a
recording (default batch of 100 samples per message, MCAP chunks of 1 MiB) into a temporary
directory, best of R (default 3), for each compression, in the caller's thread (one core)
or, with ``--background``, with compression and file writes in a second thread. Printed per
case and compression: samples simulated (and recorded: a standstill is recorded at 1 Hz),
wall time of the writer, simulated samples/s by wall and by CPU time (issue 10 target:
>= 2e6 on one core), bag bytes per simulated sample; and the share of each stage (CDR
encoding with numpy, compression, CRC, file writes) from a profiled run in one thread.
``--plot-rate-hz`` (comma-separated; ``off``: no plot topics, 0: every sample) repeats each
measurement per display rate of the plot topics and prints the bag's bytes per program hour.

``--floor`` prints, per case, a lower bound of the writer's time per sample on one core: the
CDR encoding of the three series topics alone (:func:`.cdr.joint_trajectory_rows` on the
simulated arrays, no framing, thinning or plot topics) plus the compression alone of the
recording's chunk bytes, each the best of R runs in a tight loop (warm caches, so less than
in the writer), for zstd levels -1 (the default), -3, -7 and -10 and for lz4; and the sample
rate that bound allows, against the issue's 2e6 samples/s (500 ns per sample).
"""
import argparse
import cProfile
from pathlib import Path
import pstats
import sys
import tempfile
import time

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / 'bench'))

from bench_scale import contour_program, demonstrator_program  # noqa: E402

from feed_axis_energy.gcode.load import load_gcode  # noqa: E402
from feed_axis_energy.machine.file import load_machine  # noqa: E402
from feed_axis_energy.plan.stream import iter_motion  # noqa: E402
from feed_axis_energy.record.recording import SimulationBagWriter  # noqa: E402
from feed_axis_energy.sim.stream import iter_simulation  # noqa: E402

_STAGES = {
    'CDR encoding': ('cdr.py',),
    'compression': ("'compress' of", 'lz4'),
    'CRC': ('zlib.crc32',),
    'file writes': ("'write' of '_io",),
}


def _chunks(case: str, minutes: float) -> list:
    text = (demonstrator_program if case == 'demonstrator' else contour_program)(minutes / 60)
    name = 'demonstrator.yaml' if case == 'demonstrator' else 'three_axis_mill.yaml'
    machine = load_machine(ROOT / 'config' / name)
    with tempfile.TemporaryDirectory() as tmp:
        prog = Path(tmp) / f'{case}.nc'
        prog.write_text(text)
        program = load_gcode(prog)
    motions = iter_motion(program.moves, machine.limits(), options=machine.planner.options(),
                          file=str(prog))
    return list(iter_simulation(motions, machine))


def _write(chunks: list, path: Path, compression: str, background: bool = False,
           plot_rate_hz: float | None = None) -> int:
    """Write the chunks as a recording; return the number of samples recorded."""
    with SimulationBagWriter(path, compression=compression, background=background,
                             plot_rate_hz=plot_rate_hz) as writer:
        for chunk in chunks:
            writer.write(chunk)
        writer.finish([], summary={}, stamp_s=float(chunks[-1].power.t[-1]))
    return writer.samples


def _floor(case: str, chunks: list, repeat: int) -> None:
    """Print the CDR-plus-compression lower bound of the writer per sample (module doc)."""
    import numpy as np
    import zstandard
    import lz4.frame
    from mcap.records import Chunk
    from mcap.stream_reader import StreamReader

    from feed_axis_energy.record.mcapstream import RECORD_HEAD
    from feed_axis_energy.record.cdr import joint_trajectory_rows
    from feed_axis_energy.record.recording import simulation_columns
    n = sum(c.power.t.shape[0] for c in chunks)
    cdr = float('inf')
    for _ in range(repeat):
        t0 = time.process_time()
        for chunk in chunks:
            m = chunk.power.t.shape[0] // 100 * 100
            t_ns = np.rint(chunk.motion.t[:m] * 1e9).astype(np.int64)
            for names, fields in simulation_columns(chunk).values():
                joint_trajectory_rows(t_ns, names, [None if f is None else
                                                    tuple(a[:m] for a in f) for f in fields],
                                      points=100, lead=RECORD_HEAD)
        cdr = min(cdr, time.process_time() - t0)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / 'plain'
        _write(chunks, path, 'none')
        (mcap,) = path.glob('*.mcap')
        with open(mcap, 'rb') as fh:
            data = [r.data for r in StreamReader(fh, skip_magic=False, emit_chunks=True).records
                    if isinstance(r, Chunk)]
    raw = sum(len(d) for d in data)
    cdr_ns = cdr / n * 1e9
    print(f'{case:12s} floor: {raw / n:.0f} B of records per sample; CDR encoding alone '
          f'{cdr_ns:.0f} ns/sample', flush=True)
    codecs = {f'zstd {lv}': zstandard.ZstdCompressor(level=lv, write_checksum=True).compress
              for lv in (-1, -3, -7, -10)}
    codecs['lz4'] = lz4.frame.compress
    for name, fn in codecs.items():
        best = float('inf')
        for _ in range(repeat):
            t0 = time.process_time()
            size = sum(len(fn(d)) for d in data)
            best = min(best, time.process_time() - t0)
        ns = best / n * 1e9
        print(f'{case:12s} floor: {name:8s} {raw / best / 1e9:.2f} GB/s, {ns:.0f} ns/sample, '
              f'{size / n:.1f} B/sample; CDR + compression {cdr_ns + ns:.0f} ns/sample: at most '
              f'{1e9 / (cdr_ns + ns):,.0f} samples/s on one core (target 2,000,000: 500 ns)',
              flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--case', choices=('demonstrator', 'contour', 'both'), default='both')
    ap.add_argument('--minutes', type=float, default=20.0)
    ap.add_argument('--compression', default='zstd,none')
    ap.add_argument('--repeat', type=int, default=3)
    ap.add_argument('--background', action='store_true',
                    help='compress and write in a second thread (as simulate --out does)')
    ap.add_argument('--plot-rate-hz', default='off,20',
                    help='display rates of the plot topics, comma-separated (off: none)')
    ap.add_argument('--floor', action='store_true',
                    help='print the CDR + compression lower bound per sample instead')
    args = ap.parse_args()
    plots = [None if r == 'off' else float(r) for r in args.plot_rate_hz.split(',')]
    cases = ('demonstrator', 'contour') if args.case == 'both' else (args.case,)
    for case in cases:
        chunks = _chunks(case, args.minutes)
        if args.floor:
            _floor(case, chunks, args.repeat)
            continue
        n = sum(c.power.t.shape[0] for c in chunks)
        hours = float(chunks[-1].power.t[-1]) / 3600
        for compression, plot in ((c, p) for c in args.compression.split(',') for p in plots):
            best = cpu = float('inf')
            with tempfile.TemporaryDirectory() as tmp:
                for i in range(args.repeat):
                    path = Path(tmp) / f'run{i}'
                    t0, c0 = time.perf_counter(), time.process_time()
                    kept = _write(chunks, path, compression, args.background, plot)
                    best = min(best, time.perf_counter() - t0)
                    cpu = min(cpu, time.process_time() - c0)
                    size = sum(f.stat().st_size for f in path.rglob('*') if f.is_file())
                prof = cProfile.Profile()
                prof.enable()
                _write(chunks, Path(tmp) / 'profiled', compression, False, plot)   # one thread
                prof.disable()
            stats = pstats.Stats(prof).stats
            total = sum(v[2] for v in stats.values())
            share = {name: sum(v[2] for k, v in stats.items()
                               if any(p in f'{k[0]}:{k[2]}' for p in pats)) / total
                     for name, pats in _STAGES.items()}
            split = ', '.join(f'{name} {100 * s:.0f} %' for name, s in share.items())
            label = 'off' if plot is None else f'{plot:g} Hz'
            print(f'{case:12s} {compression:5s} plot {label:6s} {n:,} samples '
                  f'({kept:,} recorded)  '
                  f'writer {best:.3f} s  '
                  f'{n / best:,.0f} samples/s (CPU {cpu:.3f} s: {n / cpu:,.0f}/s)  '
                  f'bag {size / n:.1f} B/sample, {size / hours / 1e6:.1f} MB per program hour  '
                  f'(profiled: {split}, rest {100 * (1 - sum(share.values())):.0f} %)',
                  flush=True)


if __name__ == '__main__':
    main()
