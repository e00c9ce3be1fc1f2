"""Benchmark: what the loss-function uncertainty (``physics/uncertainty.py``) costs a simulation.

Run by hand from the repository root: ``.venv/bin/python bench/bench_uncertainty.py``
(options: ``--repeat R``, ``--seconds S``).

The programs of ``bench_simulate.py`` (a: reciprocating strokes on the demonstrator,
power-regression loss; b: a dense 3-axis contour on the three-axis mill, Coulomb-viscous
loss) are simulated by the streamed path (``simulate_stream``) with the machine as shipped
and with a ``loss_covariance`` on every axis. Printed: CPU time (``time.process_time``,
best of ``--repeat``; the machine is shared, so wall time is not used), the extra CPU time
in %, and the uncertainty found.
"""
from __future__ import annotations

import argparse
from pathlib import Path
import sys
import time

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_simulate import contour_gcode, reciprocating_gcode  # noqa: E402

from feed_axis_energy.gcode.load import parse_gcode  # noqa: E402
from feed_axis_energy.machine.file import (load_machine, machine_from_dict,  # noqa: E402
                                           machine_to_dict)
from feed_axis_energy.sim.stream import simulate_stream  # noqa: E402

CONFIG = Path(__file__).resolve().parents[1] / 'config'


def with_covariance(machine):
    """``machine`` with a covariance of every loss parameter (diagonal, 3 % of each)."""
    data = machine_to_dict(machine)
    for name, axis in data['axes'].items():
        loss = machine.axis(name).loss
        units = loss.param_units()
        params = list(units)
        values = [float(axis['loss'][p]) for p in params]
        axis['loss_covariance'] = {
            'params': params, 'units': [units[p] for p in params],
            'matrix': [[(0.03 * v) ** 2 if i == j else 0.0 for j in range(len(params))]
                       for i, v in enumerate(values)]}
    return machine_from_dict(data)


def cpu(fn, repeat: int) -> tuple[float, object]:
    """Best CPU time of ``repeat`` calls [s] and the last result."""
    best, out = float('inf'), None
    for _ in range(repeat):
        t0 = time.process_time()
        out = fn()
        best = min(best, time.process_time() - t0)
    return best, out


def main() -> int:
    """Run the benchmark and print the figures."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--repeat', type=int, default=3)
    ap.add_argument('--seconds', type=float, default=300.0, help='nominal program time [s]')
    args = ap.parse_args()
    cases = [('a reciprocating', 'demonstrator.yaml', reciprocating_gcode(args.seconds)),
             ('b contour', 'three_axis_mill.yaml', contour_gcode(args.seconds))]
    print(f'{"program":<16} {"samples":>9} {"plain [s]":>10} {"with u(E) [s]":>14} '
          f'{"extra":>7}  u(E)')
    for label, config, text in cases:
        machine = load_machine(CONFIG / config)
        program = parse_gcode(text, file=label)
        plain_machine, spread_machine = machine, with_covariance(machine)

        def run(m):
            return simulate_stream(program.moves, m, file=label)[0]
        t_plain, s_plain = cpu(lambda: run(plain_machine), args.repeat)
        t_spread, s_spread = cpu(lambda: run(spread_machine), args.repeat)
        u = s_spread['energy_uncertainty']
        extra = 100.0 * (t_spread - t_plain) / t_plain
        print(f'{label:<16} {s_plain["samples"]:>9,} {t_plain:>10.2f} {t_spread:>14.2f} '
              f'{extra:>6.1f}%  ±{u["energy_sd_j"]["total"]:.4g} J '
              f'(±{u["relative_pct"]:.3g} % of {s_spread["energy_j"]["total"]:.4g} J)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
