"""Move-by-move trace of one program from the reference interpreter (LinuxCNC's rs274ngc).

Usage (needs the Debian package ``linuxcnc-uspace``; re-runs itself under /usr/bin/python3)::

    python3 bench/oracle_trace.py PROGRAM [--oracle shared/tools/run_oracle.py]

Prints one JSON object on stdout: the summary of ``run_oracle.py --one`` plus ``trace``, a list
of ``[kind, line, x, y, z, length]`` per canonical call (``traverse``, ``feed``, ``arc``,
``probe``, ``tap``: end point in machine coordinates and path length [mm], an arc's as the
oracle counts it; ``dwell``: ``[kind, line, seconds]``), where
``line`` is the interpreter's line number of the block that issued it. It uses the shared
oracle script as a library (same headless set-up: zero tool table, empty parameters,
subroutine links) and only adds a recording canon; ``bench/corpus.py --locate`` compares the
trace with our moves to find the first line where the two differ.
"""
from __future__ import annotations

import importlib.util
import json
import os
import sys

from shared_lookup import shared_path  # bench/shared_lookup.py (standard library only)

SYSTEM_PYTHON = '/usr/bin/python3'


def default_oracle() -> str:
    """Path of ``tools/run_oracle.py`` in the shared data ($FAE_SHARED, else ../shared), or ''."""
    path = shared_path('tools', 'run_oracle.py')
    return '' if path is None else str(path)


def _load(path: str):
    spec = importlib.util.spec_from_file_location('run_oracle', path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def trace_program(program: str, oracle_path: str, timeout: float = 120.0) -> dict:
    """Run ``program`` through the reference interpreter, recording every canonical call."""
    oracle = _load(oracle_path)
    base = oracle.Canon

    class TraceCanon(base):
        """The oracle's canon, also keeping each call with its source line."""

        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            self.line = 0
            self.trace = []

        def next_line(self, linecode):
            super().next_line(linecode)
            self.line = int(getattr(linecode, 'sequence_number', 0))

        def _move(self, kind, target, length_in=None, samples=()):
            before = self.s['feed_path_length_mm'] + self.s['traverse_path_length_mm']
            super()._move(kind, target, length_in, samples)
            mm = [round(v * oracle.IN2MM, 6) for v in self.mach[:3]]
            after = self.s['feed_path_length_mm'] + self.s['traverse_path_length_mm']
            self.trace.append([kind, self.line] + mm + [round(after - before, 6)])

        def straight_probe(self, *a):
            base.straight_probe(self, *a)
            self.trace[-1][0] = 'probe'

        def dwell(self, t):
            super().dwell(t)
            self.trace.append(['dwell', self.line, t])

        def result(self):
            out = super().result()
            out['trace'] = self.trace
            return out

    oracle.Canon = TraceCanon
    return oracle.run_one(program, timeout)


def main(argv: list[str]) -> int:
    """Command line (see the module docstring)."""
    import argparse
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('program')
    ap.add_argument('--oracle', default=default_oracle())
    ap.add_argument('--timeout', type=float, default=120.0)
    args = ap.parse_args(argv)
    if not args.oracle or not os.path.isfile(args.oracle):
        print('error: shared/tools/run_oracle.py not found (give --oracle)', file=sys.stderr)
        return 1
    print(json.dumps(trace_program(os.path.abspath(args.program), args.oracle, args.timeout)))
    return 0


if __name__ == '__main__':
    if os.path.realpath(sys.executable) != os.path.realpath(SYSTEM_PYTHON) and \
            os.path.exists(SYSTEM_PYTHON):
        os.execv(SYSTEM_PYTHON, [SYSTEM_PYTHON, os.path.abspath(__file__)] + sys.argv[1:])
    sys.exit(main(sys.argv[1:]))
