"""A start from the offsets a candidate effect gives: records of the power alone.

On records without motion columns the offset of each run comes from the power's correlation
with the declared model, and a large missing effect pulls it (a moved mass shifts every
stroke's peak). :func:`joint_start` screens, per candidate, the offsets each run would have
with it in the model (:func:`.jointalign.joint_screen`) and gives the comparisons at the best
candidate's offsets when they move the runs and cut the screen's residual; ``analyze`` then runs
a whole analysis from there, and the better model of the data (BIC) wins.
"""
from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import replace

import numpy as np

from ...effects import EffectState, get_effect
from ...machine import Machine
from ...measured import (Campaign, CampaignComparison, first_order_lag, load_run, MeasuredRun,
                         MotionCache, predicted_signal, quantity_of, RunComparison, RunSpec,
                         simulate_declared_chunks)
from ...physics import state_from_simulation
from ...sim import SimulationResult
from .jointalign import (JOINT_STEP_S, joint_screen, JointFit, ScreenCandidate, ScreenRun,
                         screen_span)
from .pinning import at_offsets, split_pinned

__all__ = ['JOINT_MIN_GAIN', 'joint_eligible', 'joint_start']

JOINT_MIN_GAIN = 0.05
"""Relative drop of the screen's residual that makes a candidate's offsets a start of their
own (:mod:`.jointalign`; with some run moved by at least one coarse step)."""


def joint_eligible(campaign: Campaign, runs: Sequence[RunComparison]) -> bool:
    """Records of the power alone simulated from their programs: no
    run aligned on measured motion, every run a power trace with a program."""
    return bool(runs) and all(
        r.offset.anchor != 'motion' and quantity_of(r.measures).is_power
        and campaign.run(r.name).motion_program is not None for r in runs)


def _screen_items(campaign: Campaign, machine: Machine, runs: Sequence[RunComparison],
                  candidates: Sequence[ScreenCandidate], loaded: Mapping[str, MeasuredRun],
                  ) -> Iterator[tuple[ScreenRun, list[np.ndarray]]]:
    """Per run, what :func:`.jointalign.joint_screen` reads: the run (its first stretch,
    the simulation cropped to what that stretch sees) and every candidate's basis there."""
    cache = MotionCache(machine)
    for r in runs:
        spec = campaign.run(r.name)
        measured = loaded[r.name] if r.name in loaded else load_run(spec)
        n, lo, hi = screen_span(r.t, r.offset_used_s, r.window_s)
        state, total = _simulated_to(spec, measured, machine, cache, r.axes, hi)
        a = max(int(np.searchsorted(state.t, lo, side='right')) - 1, 0)
        b = min(int(np.searchsorted(state.t, hi, side='left')) + 1, state.t.size)
        t_sim = state.t[a:b]
        bases = []
        for c in candidates:
            j = state.axes.index(c.key[1]) if c.key[1] in state.axes else None
            p = len(get_effect(c.key[0]).linear_params())
            if j is None:
                bases.append(np.zeros((b - a, p)))
                continue
            basis = get_effect(c.key[0]).basis(state, dict(c.shape))[:, j, :]
            # the meter's filter runs from the record's start: filter, then crop
            bases.append((first_order_lag(state.t, basis, r.filter_s) if r.filter_s
                          else basis)[a:b])
        y_sim = (first_order_lag(state.t, total, r.filter_s) if r.filter_s else total)[a:b]
        yield ScreenRun(r.name, r.t[:n], r.total_meas_w[:n], t_sim, y_sim, r.offset_used_s,
                        r.window_s, r.stamp), bases


def _simulated_to(spec: RunSpec, measured: MeasuredRun, machine: Machine, cache: MotionCache,
                  axes: Sequence[str], hi: float) -> tuple[EffectState, np.ndarray]:
    """The run's declared state and predicted total from its start to the first chunk past
    ``hi`` [s] (simulated time): chunk by chunk where the run streams, the later chunks let
    go as they come (the meter's filter runs from the start, so the start is kept)."""
    states: list[EffectState] = []
    totals: list[np.ndarray] = []

    def keep(sim: SimulationResult) -> None:
        if states and float(states[-1].t[-1]) > hi:
            return
        totals.append(predicted_signal(
            spec.instrument.measures, sim, machine, axes, manifest=spec.manifest,
            key=spec.key, start_direction=measured.extra.get('direction_before')).sum(axis=1))
        states.append(state_from_simulation(sim))

    simulate_declared_chunks(spec, measured, machine, cache, keep)
    return EffectState.joined(states), totals[0] if len(totals) == 1 else np.concatenate(totals)


def joint_start(campaign: Campaign, machine: Machine, cmp: CampaignComparison,
                candidates_for: Callable[[Sequence[str]], list[ScreenCandidate]],
                loaded: Mapping[str, MeasuredRun],
                ) -> tuple[CampaignComparison, JointFit] | None:
    """The comparisons with the pinned runs at the offsets the best screened candidate gives
    them (:func:`.jointalign.joint_screen`), when moving there cuts the screen's residual by
    :data:`JOINT_MIN_GAIN` and some run moves by at least a coarse step (a large effect
    may pull only the slow runs, where it weighs most); else ``None``. ``candidates_for``
    gives the candidates screened on the runs' axes."""
    pinned, _ = split_pinned(cmp.runs, campaign=campaign)
    if len(pinned) < 2:
        return None
    candidates = candidates_for(pinned[0].axes)
    if not candidates:
        return None
    fits = joint_screen(_screen_items(campaign, machine, pinned, candidates, loaded),
                        candidates)
    best = fits[0]
    if best.gain < JOINT_MIN_GAIN or best.largest_move_s < JOINT_STEP_S:
        return None
    moved = dict(zip([r.name for r in pinned], best.offsets_s))
    runs = at_offsets(campaign, machine, cmp.runs, moved, loaded=loaded, why=(
        f'the offset with {best.key[0]}@{best.key[1]} in the model (jointly searched)'))
    return replace(cmp, runs=tuple(runs)), best
