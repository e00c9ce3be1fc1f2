"""Effects the power data cannot tell apart: groups of forms with the same power shape.

A selected effect ``E`` is *uniquely named* only when no other candidate, or set of
candidates, reproduces the power it was fitted with. :func:`find_groups` tests, for every
selected effect, whether the fitted power of the whole selection ``p_S = X_S theta`` (on the
campaign's measured samples, every run pooled) lies in the span of the *other* selected
effects plus a set ``G`` of one or two other candidates on the same axis: the bounded
least-squares projection (the parameters of ``G`` within their physical bounds) leaves a
residual sum of squares ``r²``. Every parameter of the projection lies within its physical
bounds and the catalog's plausible range (:func:`plausible_bounds`).

Threshold, tied to the noise: if the truth lies in that span, ``p_S`` differs from it only
by the noise ``E``'s own parameters fitted, whose sum of squares is at most
``sigma² · chi²(p_E)`` (``p_E`` parameters of ``E``). So ``G`` is an *equivalent form* of
``E`` when ``r² <= sigma² · chi2.ppf(1 - alpha, p_E)`` (``alpha`` = 1e-3): a larger residual
would be evidence, at ``p < alpha``, for ``E``'s own shape. The relative residual
``r / |p_E|`` and its limit are reported beside it. The same limit applies to the data
themselves: ``G`` is also equivalent when its bounded fit to the residual is worse than the
selection's by less than ``sigma² · chi2.ppf(1 - alpha, p_E)`` (the data cannot prefer ``E``
at ``p < alpha``; e.g. weak ``copper`` selected as ``coulomb``, whose fitted powers differ
more than the noise but fit the data equally well).

Forms of one or two candidates are searched (pairs only of candidates that do not suffice
alone, each with its best shape variant); ``iron`` = ``coulomb`` + ``viscous`` is such a
pair. Selected effects that appear in each other's forms are merged into one
:class:`AmbiguousGroup`: one finding, "a loss of this shape", with its fitted power and
energy, never one member named by chance. Two selected effects on one axis whose fitted
powers mostly cancel (the norm of their sum below :data:`CANCEL_RATIO` of the larger one's)
are one finding too, a form with no members: only their sum is determined (a flat part of
``position_friction``'s node forces against ``iron``'s ``|omega|`` term).

A group whose members cover at least half of the catalog's candidates on its axis (and at
least :data:`SHAPELESS_MIN` of them) has no shape the data single out: almost any loss
reproduces its power within the noise (typically a fitted power far below the noise riding
beside a real effect). It is *shapeless* (:attr:`AmbiguousGroup.shapeless`): ``analyze``
offers its loss with the augmented machine and names nothing of it.

``time_offset`` takes no part in the groups (it describes the alignment, not the machine),
but a selected effect whose power a shift of the records reproduces by the same test
(:func:`timing_forms`) cannot be told from a sub-millisecond error of the alignment: a
0.25 ms delay of a large viscous loss ``c·v²`` leaves ``2cδ·v·a``, the shape of a moved
mass. ``analyze`` offers such an effect, and names it only when its own shape is evidence.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
import itertools
import math
from typing import Any, cast

import numpy as np
from scipy import stats

from ..effects import EFFECTS, get_effect
from .selection import Block, Design, solve_normal

__all__ = ['EQUIVALENCE_ALPHA', 'MAX_FORM_SIZE', 'CANCEL_RATIO', 'SHAPELESS_SHARE',
           'SHAPELESS_MIN', 'EquivalentForm', 'AmbiguousGroup', 'timing_forms',
           'find_groups', 'form_text', 'found_text', 'plausible_bounds']

EQUIVALENCE_ALPHA = 1e-3
"""Probability below which a projection residual counts as evidence for the effect's shape."""
MAX_FORM_SIZE = 2
"""Most candidates in one equivalent form."""
CANCEL_RATIO = 0.5
"""Two selected powers whose sum's norm is below this share of the larger one cancel."""
SHAPELESS_SHARE = 0.5
"""Share of an axis's candidates whose forms make a group shapeless (module docstring)."""
SHAPELESS_MIN = 6
"""Fewest members of a shapeless group (a short catalog's groups are shapes, not noise)."""


def _label(key: tuple[str, str]) -> str:
    return f'{key[0]}@{key[1]}'


@dataclass(frozen=True)
class EquivalentForm:
    """Other candidates that reproduce a selected effect's power within the noise.

    Attributes
    ----------
    replaces
        ``effect@axis`` of the selected effect(s) replaced.
    members
        ``effect@axis`` of the candidates of the form.
    parameters
        ``{member: {name: value}}``: their bounded fit to the selection's power.
    relative_residual, limit
        ``r / |p_E|`` and its limit ``sqrt(sigma² chi2.ppf(1 - alpha, p_E)) / |p_E|``.
    data_increase, data_limit
        How much worse the form fits the residual itself than the selection [sigma²], and
        the limit ``chi2.ppf(1 - alpha, p_E)``. A form qualifies when either figure is
        within its limit.
    """

    replaces: tuple[str, ...]
    members: tuple[str, ...]
    parameters: dict[str, dict[str, float]]
    relative_residual: float
    limit: float
    data_increase: float = math.nan
    data_limit: float = math.nan

    def to_dict(self) -> dict[str, Any]:
        """Plain dict (keys in docs/analyze.md)."""
        return {'replaces': list(self.replaces), 'members': list(self.members),
                'parameters': {k: dict(v) for k, v in self.parameters.items()},
                'relative_residual': self.relative_residual, 'limit': self.limit,
                'data_increase': self.data_increase, 'data_limit': self.data_limit}


@dataclass(frozen=True)
class AmbiguousGroup:
    """One finding: selected effects and their equivalent forms, one power shape.

    Attributes
    ----------
    axis
        Measured axis.
    selected
        ``effect@axis`` of the selected effects in the group (their fitted power is the
        group's).
    members
        Every effect of the group: the selected ones, then the others, in catalog order.
    forms
        The equivalent forms found.
    power_rms_w, power_mean_w, energy_j
        RMS and mean of the group's fitted power over every measured sample of the campaign
        [W], and its energy summed over the runs [J].
    candidates
        How many catalog candidates on the axis were tested (``time_offset`` left out);
        0 when unknown.
    """

    axis: str
    selected: tuple[str, ...]
    members: tuple[str, ...]
    forms: tuple[EquivalentForm, ...]
    power_rms_w: float
    power_mean_w: float
    energy_j: float
    candidates: int = 0

    @property
    def shapeless(self) -> bool:
        """Whether most of the catalog reproduces the group's power (module docstring)."""
        need = max(SHAPELESS_MIN, math.ceil(SHAPELESS_SHARE * self.candidates))
        return self.candidates > 0 and len(self.members) >= need

    @property
    def message(self) -> str:
        """One sentence: the shape, its forms, its power and energy."""
        return (f'{self.axis}: a loss of one power shape that these data cannot attribute to '
                f'one effect; equivalent forms: {form_text(self)}; fitted power '
                f'{self.power_rms_w:.3g} W RMS ({self.power_mean_w:.3g} W mean), '
                f'{self.energy_j:.4g} J over the campaign')

    def to_dict(self) -> dict[str, Any]:
        """Plain dict (keys in docs/analyze.md)."""
        return {'axis': self.axis, 'selected': list(self.selected),
                'members': list(self.members), 'forms': [f.to_dict() for f in self.forms],
                'power_rms_w': self.power_rms_w, 'power_mean_w': self.power_mean_w,
                'energy_j': self.energy_j, 'candidates': self.candidates,
                'message': self.message}


def form_text(group: AmbiguousGroup) -> str:
    """``iron = coulomb + viscous = position_friction + viscous`` (ids, axis left out)."""
    def short(labels: Sequence[str]) -> str:
        return ' + '.join(label.rsplit('@', 1)[0] for label in labels)
    parts: dict[tuple[str, ...], list[str]] = {}
    for f in group.forms:
        parts.setdefault(f.replaces, []).extend(
            [short(f.members)] if f.members else [])
    cancel = {f.replaces for f in group.forms if not f.members}
    return '; '.join(' = '.join([short(rep)] + alts)
                     + (' (fitted powers that cancel)' if rep in cancel else '')
                     for rep, alts in parts.items())


def found_text(effects: Sequence[Any], groups: Sequence[AmbiguousGroup]) -> str:
    """What was added, in words (``effects`` have ``id`` and ``axis``).

    A selected effect of an ambiguous group is never named alone: the group is named as a
    loss of one shape with its forms.
    """
    grouped = {m for g in groups for m in g.selected}
    parts = [f'{e.id} on {e.axis}' for e in effects if f'{e.id}@{e.axis}' not in grouped]
    parts += [f'a loss on {g.axis} that these data cannot attribute to one effect '
              f'({form_text(g)})' for g in groups]
    return ', '.join(parts)


def _residual(gram: np.ndarray, target: np.ndarray, cols: list[int], lower: np.ndarray,
              upper: np.ndarray, target_ss: float) -> tuple[float, np.ndarray]:
    """Bounded projection of the fitted power on ``cols``: ``(r², coefficients)``.

    ``target`` is ``X' p`` for every design column, ``target_ss`` is ``|p|²``.
    """
    if not cols:
        return target_ss, np.zeros(0)
    g = gram[np.ix_(cols, cols)]
    b = target[cols]
    # the same unit-norm scaling and bounds as every fit (solve_normal)
    phi = solve_normal(g, b, lower[cols], upper[cols])
    return max(0.0, float(target_ss - 2.0 * phi @ b + phi @ g @ phi)), phi


def plausible_bounds(design: Design) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of every design column for a form: physical bounds and the catalog's range.

    A form is a physical alternative, so its parameters must lie in the catalog's plausible
    range (``Param.low`` .. ``Param.high``) as well as in the physical bounds. Without that,
    two nearly collinear columns (``iron``'s ``|omega|`` and symmetric ``coulomb``) can
    cancel with coefficients of 1e9 and "reproduce" anything at the level of rounding.
    """
    lower, upper = design.lower.copy(), design.upper.copy()
    for block in design.blocks:
        if block.key[0] not in EFFECTS:     # not a catalog effect: its own bounds only
            continue
        params = {p.name: p for p in get_effect(block.key[0]).params}
        for name, col in zip(block.names, block.cols):
            lower[col] = max(lower[col], params[name].low)
            upper[col] = min(upper[col], params[name].high)
    return lower, upper


class _Data:
    """Pooled cross products of the design and the selection's own fit to the residual."""

    def __init__(self, design: Design, gram: np.ndarray, cols_s: list[int],
                 theta: np.ndarray) -> None:
        self.xy = cast(np.ndarray, sum(design.xy[r] for r in range(design.runs)))
        self.yy = float(design.yy.sum())
        g = gram[np.ix_(cols_s, cols_s)]
        self.sse_s = float(self.yy - 2.0 * theta @ self.xy[cols_s] + theta @ g @ theta)

    def increase(self, gram: np.ndarray, cols: list[int], lower: np.ndarray,
                 upper: np.ndarray) -> tuple[float, np.ndarray]:
        """How much worse the bounded fit of ``cols`` fits the residual: ``(dSSE, coef)``."""
        g = gram[np.ix_(cols, cols)]
        b = self.xy[cols]
        phi = solve_normal(g, b, lower[cols], upper[cols])
        return float(self.yy - 2.0 * phi @ b + phi @ g @ phi) - self.sse_s, phi


def _best_forms(gram, target, target_ss, design: Design, rest: list[int],
                replaced: Sequence[Block], taken, keys, limit_ss: float, max_size: int,
                forms_skip: Sequence[str], lower: np.ndarray, upper: np.ndarray, data: _Data):
    """Forms of ``max_size`` candidates at most that replace ``replaced`` beside ``rest``.

    A form qualifies when it reproduces the selection's fitted power (projection residual)
    *or* fits the residual itself (data) within ``limit_ss`` of the selection's fit.
    """
    axis = replaced[0].key[1]
    best: dict[tuple[str, str], tuple[float, Block]] = {}
    for other in design.blocks:
        if other.key in taken or other.key[1] != axis or other.key[0] in forms_skip:
            continue
        cols = rest + list(other.cols)
        ss, _ = _residual(gram, target, cols, lower, upper, target_ss)
        inc, _ = data.increase(gram, cols, lower, upper)
        score = min(ss, inc)
        if other.key not in best or score < best[other.key][0]:
            best[other.key] = (score, other)
    order = sorted(best, key=lambda k: list(keys).index(k) if k in keys else len(keys))
    alone = [k for k in order if best[k][0] <= limit_ss]
    combos: list[tuple[tuple[str, str], ...]] = [(k,) for k in alone]
    if max_size >= 2:
        combos += list(itertools.combinations([k for k in order if k not in alone], 2))
    out = []
    for combo in combos:
        members = [best[k][1] for k in combo]
        cols = rest + [c for m in members for c in m.cols]
        ss, phi = _residual(gram, target, cols, lower, upper, target_ss)
        inc, phi_data = data.increase(gram, cols, lower, upper)
        if ss > limit_ss and inc > limit_ss:
            continue
        if ss > limit_ss:
            phi = phi_data      # qualified by the data: report that fit
        params: dict[str, dict[str, float]] = {}
        at = len(rest)
        for m in members:
            vals = {n: float(v) for n, v in zip(m.names, phi[at:at + len(m.cols)])}
            vals.update({n: float(v) for n, v in m.shape.items()})
            params[_label(m.key)] = vals
            at += len(m.cols)
        out.append((combo, params, ss, inc))
    return out


def find_groups(design: Design, blocks: Sequence[Block], theta: np.ndarray, *,
                sigma2: float, keys: Sequence[tuple[str, str]], periods_s: Sequence[float],
                axes: Sequence[str], alpha: float = EQUIVALENCE_ALPHA,
                max_size: int = MAX_FORM_SIZE,
                skip: Sequence[str] = ('time_offset',)) -> list[AmbiguousGroup]:
    """Selected effects whose power other candidates reproduce within the noise, grouped.

    Parameters
    ----------
    design
        Residuals and every candidate block.
    blocks, theta
        The selected blocks and their coefficients fitted on every run.
    sigma2
        Noise variance per sample [W²].
    keys
        Every candidate ``(effect, axis)`` in catalog order (the order of members).
    periods_s
        Sample period of each run [s] (for the energy).
    axes
        Measured axes in the order the residual is flattened (sample-major).
    alpha
        See the module docstring.
    max_size
        Most candidates in one form.
    skip
        Effect ids neither tested nor used in a form (``time_offset``: it describes the
        alignment, not the machine).

    Returns
    -------
    list of AmbiguousGroup
        One per set of selected effects that share forms; empty when every selected effect
        is uniquely named (or ``sigma2`` is not a positive number).

    Notes
    -----
    Every subset ``T`` of the selected effects on one axis is tried as the part replaced
    (``p_S`` projected on the others plus the form); a subset of two or more is replaced
    by one candidate only (``position_friction + viscous = iron``), its limit uses the
    parameters of the whole subset.
    """
    blocks = list(blocks)
    if not blocks or not (math.isfinite(sigma2) and sigma2 > 0.0):
        return []
    gram, target, target_ss, data = _pooled(design, blocks, theta)
    taken = {b.key for b in blocks}
    lower, upper = plausible_bounds(design)
    starts = list(np.cumsum([0] + [len(b.cols) for b in blocks[:-1]]))
    own = {}
    for i, b in enumerate(blocks):
        th = theta[starts[i]:starts[i] + len(b.cols)]
        own[i] = float(th @ gram[np.ix_(b.cols, b.cols)] @ th)
    testable = [i for i, b in enumerate(blocks) if b.key[0] not in skip and own[i] > 0.0]
    forms: list[tuple[tuple[int, ...], EquivalentForm]] = []
    for i, j in itertools.combinations(testable, 2):
        # two fitted powers that mostly cancel: only their sum is determined (a flat part
        # of position_friction against iron's |omega| part)
        if blocks[i].key[1] != blocks[j].key[1]:
            continue
        th_i = theta[starts[i]:starts[i] + len(blocks[i].cols)]
        th_j = theta[starts[j]:starts[j] + len(blocks[j].cols)]
        cross = float(th_i @ gram[np.ix_(blocks[i].cols, blocks[j].cols)] @ th_j)
        ratio = math.sqrt(max(own[i] + own[j] + 2.0 * cross, 0.0) / max(own[i], own[j]))
        if ratio < CANCEL_RATIO:
            forms.append(((i, j), EquivalentForm(
                replaces=(_label(blocks[i].key), _label(blocks[j].key)), members=(),
                parameters={}, relative_residual=ratio, limit=CANCEL_RATIO)))
    for size in range(1, len(testable) + 1):
        for subset in itertools.combinations(testable, size):
            if len({blocks[i].key[1] for i in subset}) > 1:
                continue
            replaced = [blocks[i] for i in subset]
            rest = [c for k, b in enumerate(blocks) if k not in subset for c in b.cols]
            n_par = sum(len(b.cols) for b in replaced)
            limit_ss = sigma2 * float(stats.chi2.ppf(1.0 - alpha, n_par))
            cols_t = [c for b in replaced for c in b.cols]
            th = np.concatenate([theta[starts[i]:starts[i] + len(blocks[i].cols)]
                                 for i in subset])
            own_ss = float(th @ gram[np.ix_(cols_t, cols_t)] @ th)
            if own_ss <= 0.0:
                continue
            found = _best_forms(gram, target, target_ss, design, rest, replaced, taken, keys,
                                limit_ss, max_size if size == 1 else 1, skip, lower, upper,
                                data)
            forms.extend((subset, _form(replaced, f, own_ss=own_ss, limit_ss=limit_ss,
                                        sigma2=sigma2)) for f in found)
    return _merge(design, blocks, theta, starts, forms, keys=keys, periods_s=periods_s,
                  axes=axes, skip=skip)


def _form(replaced: Sequence[Block], found, *, own_ss: float, limit_ss: float,
          sigma2: float) -> EquivalentForm:
    """An equivalent form of ``replaced`` from one :func:`_best_forms` result
    ``(candidates, parameters, projection residual, data increase)``; ``own_ss`` is the
    replaced part's own fitted power ``|p_T|²``, ``limit_ss`` the limit of both tests."""
    combo, params, ss, inc = found
    return EquivalentForm(
        replaces=tuple(_label(b.key) for b in replaced),
        members=tuple(_label(k) for k in combo), parameters=params,
        relative_residual=math.sqrt(ss / own_ss), limit=math.sqrt(limit_ss / own_ss),
        data_increase=inc / sigma2, data_limit=limit_ss / sigma2)


def _pooled(design: Design, blocks: Sequence[Block], theta: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray, float, _Data]:
    """The selection's fitted power pooled over every run: the Gram matrix of every design
    column, ``X' p_S``, ``|p_S|²`` and the data's cross products (:class:`_Data`)."""
    gram = cast(np.ndarray, sum(design.gram[r] for r in range(design.runs)))
    cols_s = [c for b in blocks for c in b.cols]
    target = gram[:, cols_s] @ theta
    target_ss = float(theta @ gram[np.ix_(cols_s, cols_s)] @ theta)
    return gram, target, target_ss, _Data(design, gram, cols_s, theta)


def timing_forms(design: Design, blocks: Sequence[Block], theta: np.ndarray, *,
                 sigma2: float, keys: Sequence[tuple[str, str]],
                 alpha: float = EQUIVALENCE_ALPHA,
                 timing: str = 'time_offset') -> dict[str, EquivalentForm]:
    """Selected effects whose power a shift of the records reproduces within the noise.

    For every selected block but ``timing`` ones, the candidate ``timing`` block of its
    axis (when the design has one and it is not selected) is tried as a one-member form
    beside the other selected effects, with :func:`find_groups`' test and limit.

    Returns
    -------
    dict
        ``{effect@axis: the qualifying form}``; empty when none qualifies or ``sigma2`` is
        not a positive number.
    """
    blocks = list(blocks)
    if not blocks or not (math.isfinite(sigma2) and sigma2 > 0.0):
        return {}
    gram, target, target_ss, data = _pooled(design, blocks, theta)
    taken = {b.key for b in blocks}
    lower, upper = plausible_bounds(design)
    others = tuple({b.key[0] for b in design.blocks} - {timing})
    out = {}
    at = 0
    for i, b in enumerate(blocks):
        th, at = theta[at:at + len(b.cols)], at + len(b.cols)
        own_ss = float(th @ gram[np.ix_(b.cols, b.cols)] @ th)
        if b.key[0] == timing or own_ss <= 0.0:
            continue
        rest = [c for k, o in enumerate(blocks) if k != i for c in o.cols]
        limit_ss = sigma2 * float(stats.chi2.ppf(1.0 - alpha, len(b.cols)))
        for found in _best_forms(gram, target, target_ss, design, rest, [b], taken, keys,
                                 limit_ss, 1, others, lower, upper, data):
            out[_label(b.key)] = _form([b], found, own_ss=own_ss, limit_ss=limit_ss,
                                       sigma2=sigma2)
    return out


def _merge(design: Design, blocks: list[Block], theta: np.ndarray, starts: list[int],
           forms: list[tuple[tuple[int, ...], EquivalentForm]], *, keys, periods_s,
           axes, skip=()) -> list[AmbiguousGroup]:
    """Selected effects replaced together, or named in each other's forms, become one group."""
    labels = [_label(b.key) for b in blocks]
    parent = list(range(len(blocks)))

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for subset, f in forms:
        for i in subset[1:]:
            parent[root(i)] = root(subset[0])
        for m in f.members:
            if m in labels:
                parent[root(labels.index(m))] = root(subset[0])
    order = {_label(k): n for n, k in enumerate(keys)}
    groups = []
    for r in sorted({root(i) for subset, _ in forms for i in subset}):
        idx = [i for i in range(len(blocks)) if root(i) == r]
        fs = [f for subset, f in forms if root(subset[0]) == r]
        selected = tuple(labels[i] for i in idx)
        others = {m for f in fs for m in f.members} - set(selected)
        members = selected + tuple(sorted(others, key=lambda m: order.get(m, len(order))))
        cols = [c for i in idx for c in blocks[i].cols]
        th = np.concatenate([theta[starts[i]:starts[i] + len(blocks[i].cols)] for i in idx])
        j = list(axes).index(blocks[idx[0]].key[1])
        ss = energy = duration = 0.0
        count = 0
        for run in range(design.runs):
            p = design.predict(cols, th, run).reshape(-1, len(axes))[:, j]
            ss += float(p @ p)
            count += p.size
            energy += float(p.sum()) * periods_s[run]
            duration += p.size * periods_s[run]
        groups.append(AmbiguousGroup(
            axis=blocks[idx[0]].key[1], selected=selected, members=members, forms=tuple(fs),
            power_rms_w=math.sqrt(ss / count) if count else 0.0,
            power_mean_w=energy / duration if duration > 0.0 else 0.0, energy_j=energy,
            candidates=sum(1 for k in keys if k[1] == blocks[idx[0]].key[1]
                           and k[0] not in skip)))
    return groups
