"""Re-alignment after effects are added: ``analyze``'s *after* is what ``compare`` would say.

The baseline offset of a run is estimated against the declared model, which lacks the very
effects ``analyze`` looks for; with them added, the best offset can move (a missing load
friction skews the strokes' power). So every *after* is a fresh comparison
(:func:`.measured.compare.compare_run` semantics: simulate with the effects declared in the
machine, estimate the offset anew, average over the instrument window, Table-1 metrics):

* a held-out run is compared with the machine plus the effects fitted on its fold's
  training runs;
* every run is also compared with the machine plus the effects fitted on all runs — the
  machine ``analyze --out-machine`` writes — so these figures are exactly those of
  ``compare --machine AUGMENTED.yaml``.

Effects that describe the comparison rather than the machine (``time_offset``) are not
declared: the new offset estimate takes their place.
"""
from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from ..effects import get_effect
from ..machine import DeclaredEffect, Machine
from ..measured import (Campaign, compare_one_run, DEFAULT_MAX_LAG_S, MeasuredRun, MotionCache,
                        RunComparison)
from .drivecorr import declared_values, fold_corrections
from .selection import Block

__all__ = ['augmented_outcome', 'iter_realigned', 'machine_with']


def machine_with(machine: Machine, blocks: Sequence[Block], theta: np.ndarray, *,
                 measures: str | None = None) -> Machine:
    """The machine plus the blocks' effects with coefficients ``theta`` (in block order).

    Parameters
    ----------
    machine
        The declared machine.
    blocks
        Selected effects; their linear parameters take consecutive entries of ``theta``,
        their shape parameters the block's values.
    theta
        Linear coefficients of every block's columns, concatenated.
    measures
        What every run's meter measures; with ``'motor'``, ``copper`` and ``iron`` on axes
        with a declared drive change the drive's values instead (:mod:`.drivecorr`).

    Returns
    -------
    Machine
        ``machine`` with the machine-property effects appended to its ``effects`` (the same
        construction as :meth:`.results.AnalysisResult.augmented_machine`).
    """
    added = []
    folded = []
    pos = 0
    for block in blocks:
        values = [(name, float(theta[pos + i])) for i, name in enumerate(block.names)]
        pos += len(block.names)
        values += [(name, float(value)) for name, value in block.shape.items()]
        if declared_values(machine, block.key[1], block.key[0], measures) is not None:
            folded.append((block.key[0], block.key[1], dict(values)))
        elif get_effect(block.key[0]).machine_property:
            added.append(DeclaredEffect(id=block.key[0], axis=block.key[1],
                                        params=tuple(values)))
    machine = fold_corrections(machine, folded)
    if not added:
        return machine
    return replace(machine, effects=machine.effects + tuple(added))


def iter_realigned(campaign: Campaign, machine: Machine, names: Sequence[str], *,
                   baseline: Sequence[RunComparison] = (),
                   loaded: Mapping[str, MeasuredRun] | None = None,
                   ) -> Iterator[RunComparison]:
    """Compare the named runs with ``machine``, offsets estimated anew, as ``compare`` does,
    one run at a time: a caller that keeps only part of each comparison (or holds it in a
    memory-mapped store) never has every run's comparison in memory at once.

    Parameters
    ----------
    campaign
        The campaign the runs belong to.
    machine
        Machine with the effects to compare against.
    names
        Run names.
    baseline
        Comparisons with the same machine already made (reused by name, bit for bit the
        same as a new one).
    loaded
        Runs already loaded, by name (each CSV is parsed once per analysis).

    Yields
    ------
    RunComparison
        One per name, in order.
    """
    known = {c.name: c for c in baseline}
    cache = MotionCache(machine)
    for name in names:
        if name in known:
            yield known[name]
            continue
        # compare_campaign's defaults: analyze compares its baseline with them; the meter
        # check (not part of the after figures) is left to the baseline
        yield compare_one_run(campaign.run(name), machine, cache, max_lag_s=DEFAULT_MAX_LAG_S,
                              window_s=None, offset_s=None, min_correlation=0.5,
                              floor_fraction=0.05, check_meter=False,
                              measured=(loaded or {}).get(name))


def augmented_outcome(cmp: RunComparison) -> dict[str, Any]:
    """JSON-able figures of one run compared with the augmented machine.

    Returns
    -------
    dict
        ``{name, load_kg, role, offset, metrics: {total, <axis>...}}`` with the keys of
        ``compare --json``'s run objects.
    """
    full = cmp.to_dict()
    return {k: full[k] for k in ('name', 'load_kg', 'role', 'offset', 'metrics')}
