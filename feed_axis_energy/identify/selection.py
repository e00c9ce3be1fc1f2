"""Forward selection of effects by held-out error: the linear algebra behind ``analyze``.

The residual of each run (measured minus simulated power, flattened over the measured axes)
is regressed on *blocks* of basis columns, one block per candidate (effect, axis, shape
values). Per run the cross products ``X'X``, ``X'y`` and ``y'y`` of every column are kept,
so a fit on any set of runs and columns is a small solve; held-out errors per run come from
fits on the other runs (*folds*).

Every column has physical bounds (:meth:`.effects.base.Effect.linear_bounds`): a fit
is the bounded least-squares solution (:func:`solve_normal`), so an impossible value (a
negative copper coefficient) is never a result; a value on its bound is flagged
(:func:`at_bounds`).

Acceptance of a candidate (:func:`forward_select`) is a matter of statistics, not of size:
the mean relative held-out gain ``g_r = 1 - mse_r(S + c) / mse_r(S)`` over held-out runs
must exceed ``se_factor`` standard errors of the mean; the drop of the in-sample residual
sum of squares, in units of the noise variance (:func:`.diagnostics.noise_level`, the
level every test of ``analyze`` uses), must exceed the chi-square limit of the candidate's
parameters at ``alpha / m`` for ``m`` candidates tried in the round (Bonferroni: the
multiple-testing control for false attributions); and the BIC must drop by at least
``min_bic_drop`` (2 by default: "positive" evidence on the scale of Kass & Raftery, *Bayes
Factors*, JASA 90 (1995), 773-795; a drop below 2 is "not worth more than a bare mention").
How large the
effect is (its share of the energy) decides how the report ranks it, never whether it
exists. A round does not end at a rejected best candidate: the next ones are tried, then
pairs of the best few (bounded, deterministic).
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
import itertools
import math
from typing import cast, Protocol

import numpy as np
from scipy import stats
from scipy.optimize import lsq_linear

__all__ = ['Block', 'Design', 'Holder', 'Step', 'SelectionResult', 'chi2_limit', 'forward_select',
           'gain_text', 'loro_folds', 'solve_normal', 'at_bounds']

# column sets whose per-run cross products a design keeps at once (a few MB at most)
_SUBS_KEPT = 64
# every run's Gram matrix and X'y on a set of columns, and the diagonal summed over runs
_Sub = tuple[list[np.ndarray], list[np.ndarray], np.ndarray]


def solve_normal(g: np.ndarray, b: np.ndarray, lower: np.ndarray | None = None,
                 upper: np.ndarray | None = None) -> np.ndarray:
    """Minimise ``theta' g theta - 2 b' theta`` within ``lower <= theta <= upper``.

    ``g`` is a Gram matrix ``X'X`` and ``b = X'y``: the least-squares fit of ``y`` on ``X``
    from its cross products. Columns are scaled to unit norm; collinear columns share the fit
    (minimum-norm solution). When the unconstrained solution breaks a bound, the bounded
    problem is solved by :func:`scipy.optimize.lsq_linear` on a square root of ``g``.
    """
    p = b.shape[0]
    if p == 0:
        return np.zeros(0)
    d = np.sqrt(np.clip(np.diag(g), 0.0, None))
    d[d == 0.0] = 1.0
    gs = g / np.outer(d, d)
    bs = b / d
    sol, *_ = np.linalg.lstsq(gs, bs, rcond=1e-10)
    theta = sol / d
    lo = np.full(p, -math.inf) if lower is None else np.asarray(lower, dtype=float)
    hi = np.full(p, math.inf) if upper is None else np.asarray(upper, dtype=float)
    if np.all(theta >= lo) and np.all(theta <= hi):
        return theta
    # g = V S V': A = S^(1/2) V' and t = S^(-1/2) V' b give |A u - t|^2 = u'g u - 2 b'u + c
    w, v = np.linalg.eigh(0.5 * (gs + gs.T))
    floor = 1e-10 * max(float(w.max()), 1e-300)
    keep = w > floor
    root = np.sqrt(w[keep])
    a = root[:, None] * v[:, keep].T
    t = (v[:, keep].T @ bs) / root
    if not keep.all():
        # collinear columns: the data leave a direction free, and a bounded solver would stop
        # anywhere along it (huge values of opposite sign that cancel); a penalty at the
        # rank threshold on that direction alone takes the smallest solution, as lstsq does
        a = np.vstack([a, math.sqrt(floor) * v[:, ~keep].T])
        t = np.concatenate([t, np.zeros(int((~keep).sum()))])
    res = lsq_linear(a, t, bounds=(lo * d, hi * d), method='bvls')
    return np.clip(res.x / d, lo, hi)


def at_bounds(theta: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> list[str | None]:
    """``'lower'``, ``'upper'`` or ``None`` per value: which physical bound it sits on."""
    out: list[str | None] = []
    for x, lo, hi in zip(theta, lower, upper):
        tol = 1e-9 * max(1.0, abs(float(x)))
        out.append('lower' if math.isfinite(lo) and x <= lo + tol else
                   'upper' if math.isfinite(hi) and x >= hi - tol else None)
    return out


@dataclass(frozen=True)
class Block:
    """Basis columns of one candidate.

    Attributes
    ----------
    key
        ``(effect_id, axis)``: the candidate; variants of shape values share it.
    shape
        Shape parameter values the columns were computed with.
    names
        Linear parameter names, one per column.
    cols
        Column indices in the design.
    """

    key: tuple[str, str]
    shape: Mapping[str, float]
    names: tuple[str, ...]
    cols: tuple[int, ...]


class Holder(Protocol):
    """Where :class:`Design` keeps its columns: ``hold(array)`` returns the array itself or
    an equal read-only copy it owns (:class:`.design.statestore.StateStore`: in memory
    within its budget, else memory-mapped)."""

    def hold(self, array: np.ndarray) -> np.ndarray: ...


class Design:
    """Per-run cross products of the residual and every candidate column.

    Parameters
    ----------
    y
        Residual of each run, flattened, ``[(n_r,), ...]``.
    store
        Keeps each block's columns (:class:`Holder`); without one they stay in memory.
        The cross products are always in memory (a few numbers per pair of columns); the
        columns themselves (grid points x columns of every run, 120 MiB for 15 runs of 10
        minutes) are read only to refine a shape, check consistency or predict, one run
        at a time.
    """

    def __init__(self, y: Sequence[np.ndarray], store: Holder | None = None) -> None:
        self.y = [np.asarray(v, dtype=float) for v in y]
        self.n = np.array([v.size for v in self.y])
        self.yy = np.array([float(v @ v) for v in self.y])
        self._store = store
        # per run, each block's columns (n_r, p_b), held by the store
        self._x: list[list[np.ndarray]] = [[] for _ in self.y]
        self._where: list[tuple[int, int]] = []     # column -> (block, column in it)
        self.gram: list[np.ndarray] = [np.zeros((0, 0)) for _ in self.y]
        self.xy: list[np.ndarray] = [np.zeros(0) for _ in self.y]
        self.blocks: list[Block] = []
        self.lower = np.zeros(0)
        self.upper = np.zeros(0)
        # each run's cross products restricted to a set of columns, by the columns: a
        # held-out score fits the same columns on many folds (cleared when columns are added)
        self._subs: dict[tuple[int, ...], _Sub] = {}

    @property
    def runs(self) -> int:
        """Number of runs."""
        return len(self.y)

    def add_block(self, key: tuple[str, str], shape: Mapping[str, float],
                  names: Sequence[str], columns: Sequence[np.ndarray], *,
                  bounds: tuple[Sequence[float] | np.ndarray, Sequence[float] | np.ndarray]
                  | None = None) -> Block:
        """Add one candidate's columns (``columns[r]`` of shape ``(n_r, p)``) to every run.

        ``bounds`` are the physical ``(lower, upper)`` bounds of its ``p`` parameters
        (default: none).
        """
        p = len(names)
        lo, hi = ((np.full(p, -math.inf), np.full(p, math.inf)) if bounds is None
                  else (np.asarray(bounds[0], dtype=float), np.asarray(bounds[1], dtype=float)))
        self.lower = np.concatenate([self.lower, lo])
        self.upper = np.concatenate([self.upper, hi])
        start = len(self._where)
        for r, c in enumerate(columns):
            c = np.ascontiguousarray(np.asarray(c, dtype=float).reshape(self.n[r], p))
            cross = (np.concatenate([b.T @ c for b in self._x[r]]) if self._x[r]
                     else np.zeros((0, p)))
            g = np.zeros((start + p, start + p))
            g[:start, :start] = self.gram[r]
            g[:start, start:] = cross
            g[start:, :start] = cross.T
            g[start:, start:] = c.T @ c
            self.gram[r] = g
            self.xy[r] = np.concatenate([self.xy[r], c.T @ self.y[r]])
            self._x[r].append(c if self._store is None else self._store.hold(c))
        b_index = len(self.blocks)
        self._where += [(b_index, i) for i in range(p)]
        block = Block(key=key, shape=dict(shape), names=tuple(names),
                      cols=tuple(range(start, start + p)))
        self.blocks.append(block)
        self._subs.clear()
        return block

    def columns(self, run: int, cols: Sequence[int]) -> np.ndarray:
        """The columns ``cols`` of ``run``, ``(n_r, len(cols))`` (a new array; a view of
        one block's columns when they are all of it, in order)."""
        cols = list(cols)
        blocks = self._x[run]
        if not cols:
            return np.zeros((self.n[run], 0))
        b0, i0 = self._where[cols[0]]
        if all(self._where[c] == (b0, i0 + k) for k, c in enumerate(cols)):
            return blocks[b0][:, i0:i0 + len(cols)]
        out = np.empty((self.n[run], len(cols)))
        for k, c in enumerate(cols):
            b, i = self._where[c]
            out[:, k] = blocks[b][:, i]
        return out

    def _sub(self, cols: list[int]) -> _Sub:
        """Every run's Gram matrix and ``X'y`` on ``cols``, and their summed diagonal."""
        key = tuple(cols)
        found = self._subs.get(key)
        if found is None:
            idx = np.ix_(cols, cols)
            grams = [g[idx] for g in self.gram]
            every = cast(np.ndarray, sum(g.diagonal()[cols] for g in self.gram))
            found = (grams, [v[cols] for v in self.xy], every)
            if len(self._subs) >= _SUBS_KEPT:
                self._subs.pop(next(iter(self._subs)))
            self._subs[key] = found
        return found

    def fit(self, cols: Sequence[int], runs: Sequence[int]) -> np.ndarray:
        """Bounded least-squares coefficients of ``cols`` on the pooled ``runs``.

        See :func:`solve_normal` (unit-norm scaling, minimum norm for collinear columns,
        the physical bounds of every column).
        """
        cols = list(cols)
        if not cols:
            return np.zeros(0)
        grams, xys, every = self._sub(cols)
        g = cast(np.ndarray, sum(grams[r] for r in runs))     # runs is not empty
        b = cast(np.ndarray, sum(xys[r] for r in runs))
        # A column (almost) absent from these runs, though present in others (a position
        # bump the training runs barely touch), is not fitted here: unit-norm scaling would
        # blow its coefficient up to meaningless sizes. Its value stays 0 (inside every
        # physical bound).
        strong = np.diag(g) > 1e-12 * every
        theta = np.zeros(len(cols))
        if np.any(strong):
            keep = np.flatnonzero(strong)
            theta[keep] = solve_normal(g[np.ix_(keep, keep)], b[keep],
                                       self.lower[cols][keep], self.upper[cols][keep])
        return theta

    def sse(self, cols: Sequence[int], theta: np.ndarray, run: int) -> float:
        """Residual sum of squares of ``run`` after subtracting ``X theta``."""
        cols = list(cols)
        if not cols:
            return float(self.yy[run])
        grams, xys, _ = self._sub(cols)
        g, b = grams[run], xys[run]
        return max(0.0, float(self.yy[run] - 2.0 * theta @ b + theta @ g @ theta))

    def predict(self, cols: Sequence[int], theta: np.ndarray, run: int) -> np.ndarray:
        """``X theta`` of one run, flattened like its residual."""
        cols = list(cols)
        if not cols:
            return np.zeros(self.n[run])
        return self.columns(run, cols) @ theta

    def heldout_mse(self, cols: Sequence[int],
                    folds: Sequence[tuple[Sequence[int], Sequence[int]]]) -> dict[int, float]:
        """Mean squared held-out residual of every test run: ``{run: mse}``."""
        out = {}
        for train, test in folds:
            theta = self.fit(cols, train)
            for r in test:
                out[r] = self.sse(cols, theta, r) / self.n[r]
        return out

    def total_sse(self, cols: Sequence[int]) -> float:
        """In-sample residual sum of squares of a fit on every run."""
        runs = range(self.runs)
        theta = self.fit(cols, runs)
        return float(sum(self.sse(cols, theta, r) for r in runs))

    def bic(self, cols: Sequence[int]) -> float:
        """``N ln(SSE/N) + p ln N`` of the in-sample fit on every run."""
        n = float(self.n.sum())
        sse = max(self.total_sse(cols), 1e-300)
        return n * math.log(sse / n) + len(list(cols)) * math.log(n)


def loro_folds(runs: int) -> list[tuple[list[int], list[int]]]:
    """Leave-one-run-out folds ``[(train, [test]), ...]``."""
    return [([i for i in range(runs) if i != r], [r]) for r in range(runs)]


@dataclass(frozen=True)
class Step:
    """One candidate (or pair) tried in a round of forward selection, and whether it was added.

    Attributes
    ----------
    key
        ``(effect_id, axis)`` of the candidate tried (of a pair: the first).
    shape
        Its best shape values.
    mean_gain, se_gain
        Mean relative held-out gain over held-out runs and its standard error.
    bic_before, bic_after
        BIC without and with it.
    accepted
        Whether it was added.
    reason
        Why (not).
    ranking
        ``[(key, mean held-out mse), ...]`` of every candidate of the round, best first.
    candidates
        ``[(key, mean relative held-out gain, its standard error), ...]`` of every candidate
        of the round (best variant of each), best first.
    round
        The round (several candidates may be tried in one).
    with_key
        The second candidate of a pair tried together, else ``None``.
    chi2, chi2_limit
        The drop of the in-sample residual sum of squares [sigma²] and its limit (NaN
        without a noise level).
    """

    key: tuple[str, str]
    shape: Mapping[str, float]
    mean_gain: float
    se_gain: float
    bic_before: float
    bic_after: float
    accepted: bool
    reason: str
    ranking: list[tuple[tuple[str, str], float]] = field(default_factory=list)
    candidates: list[tuple[tuple[str, str], float, float]] = field(default_factory=list)
    round: int = 1
    with_key: tuple[str, str] | None = None
    chi2: float = math.nan
    chi2_limit: float = math.nan


@dataclass(frozen=True)
class SelectionResult:
    """Outcome of :func:`forward_select`: the chosen blocks, in order, and every round.

    ``stop`` says why it stopped: ``'rejected'`` (the best candidate of the last round did
    not pass), ``'max_effects'`` (the cap was reached) or ``'no_candidates'``.
    """

    blocks: tuple[Block, ...]
    steps: tuple[Step, ...]
    stop: str = 'rejected'

    @property
    def cols(self) -> list[int]:
        """Design columns of the chosen blocks."""
        return [c for b in self.blocks for c in b.cols]


def _score(design: Design, cols: list[int], folds, base: dict[int, float]):
    mse = design.heldout_mse(cols, folds)
    runs = sorted(mse)
    gains = np.array([1.0 - mse[r] / base[r] if base[r] > 0.0 else 0.0 for r in runs])
    return float(np.mean([mse[r] for r in runs])), gains


def gain_text(gain: float, se: float) -> str:
    """A mean relative held-out gain in words: ``'held-out gain 1.20 % +- 0.30 %'``; a
    gain below -100 % as how many times the error without the effect it is (a fit that
    blows up on unseen runs, e.g. two nearly collinear columns, is no percentage)."""
    if gain > -1.0 or not math.isfinite(gain):
        return f'held-out gain {100 * gain:.2f} % +- {100 * se:.2f} %'
    return (f'held-out error {1.0 - gain:.3g} times the error without it on average (a fit '
            'that does not carry over to unseen runs)')


def chi2_limit(alpha: float, tests: int, params: int, floor_chi2: float = 0.0) -> float:
    """Limit of a residual drop [sigma²] for ``params`` new columns, at family level
    ``alpha`` over ``tests`` (Bonferroni), raised by ``floor_chi2`` (what the simulation's
    own sampling leaves in the residual, :func:`.simrate.sampling_left`). Every test of a
    residual drop in ``analyze`` (entry, pruning, offers on the summed power) uses it."""
    return float(stats.chi2.isf(alpha / max(tests, 1), max(params, 1))) + floor_chi2


@dataclass(frozen=True)
class _Trial:
    blocks: tuple[Block, ...]
    mean_gain: float
    se_gain: float
    bic_before: float
    bic_after: float
    chi2: float
    limit: float
    ok: bool
    reason: str


def _judge(design: Design, cols: list[int], blocks: Sequence[Block], folds,
           base: dict[int, float], *, n_test: int, se_factor: float, sigma2: float,
           alpha: float, tests: int, bic_before: float, min_bic_drop: float,
           floor_chi2: float) -> _Trial:
    """Is adding ``blocks`` beside ``cols`` statistically supported? (module docstring)."""
    new = cols + [c for b in blocks for c in b.cols]
    _, gains = _score(design, new, folds, base)
    mean_gain, se = _mean_se(gains)
    bic_after = design.bic(new)
    drop = design.total_sse(cols) - design.total_sse(new)
    known = math.isfinite(sigma2) and sigma2 > 0.0
    chi2 = drop / sigma2 if known else math.nan
    p = sum(len(b.cols) for b in blocks)
    limit = chi2_limit(alpha, tests, p, floor_chi2)
    if n_test < 2:
        ok, reason = False, 'fewer than 2 held-out runs: the gain has no standard error'
    elif not mean_gain > se_factor * se:
        ok, reason = False, (
            f'held-out gain {100 * mean_gain:.2f} % is within {se_factor:g} standard errors '
            f'({100 * se:.2f} %)' if mean_gain > -1.0 else gain_text(mean_gain, se))
    elif known and not chi2 > limit:
        ok, reason = False, (f'its drop of the residual is {chi2:.1f} sigma², not above '
                             f'{limit:.1f} (chi-square, {p} parameter(s), family level '
                             f'{alpha:g} over {tests} tests)')
    elif not bic_after < bic_before - min_bic_drop:
        ok, reason = False, (f'BIC does not drop ({bic_before:.1f} -> {bic_after:.1f})'
                             if not bic_after < bic_before else
                             f'BIC drops by {bic_before - bic_after:.1f} ({bic_before:.1f} -> '
                             f'{bic_after:.1f}), not by the {min_bic_drop:g} of positive '
                             'evidence')
    elif known and len(blocks) > 1 and (passenger := _passenger(
            design, cols, blocks, sigma2=sigma2, alpha=alpha, tests=tests,
            floor_chi2=floor_chi2)):
        ok, reason = False, passenger
    else:
        drop_text = f', residual drop {chi2:.1f} sigma² > {limit:.1f}' if known else ''
        ok, reason = True, (f'held-out gain {100 * mean_gain:.2f} % +- {100 * se:.2f} %'
                            f'{drop_text}, BIC {bic_before:.1f} -> {bic_after:.1f}')
    return _Trial(tuple(blocks), mean_gain, se, bic_before, bic_after, chi2, limit, ok, reason)


def _passenger(design: Design, cols: list[int], blocks: Sequence[Block], *, sigma2: float,
               alpha: float, tests: int, floor_chi2: float = 0.0) -> str:
    """Why a member of a set tried together adds nothing beside the others ('' if none).

    A pair is accepted only when each member, added last beside the other, drops the
    residual beyond the chi-square limit of its parameters too: a weak candidate does not
    ride into the model on a strong one.
    """
    every = cols + [c for b in blocks for c in b.cols]
    sse = design.total_sse(every)
    for block in blocks:
        without = [c for c in every if c not in block.cols]
        chi2 = (design.total_sse(without) - sse) / sigma2
        limit = chi2_limit(alpha, tests, len(block.cols), floor_chi2)
        if not chi2 > limit:
            return (f'{block.key[0]}@{block.key[1]} adds {chi2:.1f} sigma² beside the other, '
                    f'not above {limit:.1f}: tried together, it would ride on the other')
    return ''


def forward_select(design: Design, folds: Sequence[tuple[Sequence[int], Sequence[int]]], *,
                   exclude: Sequence[tuple[str, str]] = (), se_factor: float = 2.0,
                   sigma2: float = math.nan, alpha: float = 0.05, max_effects: int = 4,
                   max_tries: int = 8, pair_pool: int = 4,
                   min_bic_drop: float = 2.0, floor_chi2: float = 0.0) -> SelectionResult:
    """Add candidates while each is statistically supported on held-out runs.

    Per round the candidates are tried in the order of their held-out error (the best
    first, exact ties by BIC); the first that passes (module docstring) is added. When none
    of the first ``max_tries`` passes alone, the pairs of the ``pair_pool`` best are tried
    together (a loss two effects share, whose parts are weak alone), in the order of their
    held-out error. The search is bounded and deterministic.

    Parameters
    ----------
    design
        Residuals and candidate blocks (several blocks with the same key are variants of
        one candidate with different shape values; the best variant represents it).
    folds
        ``[(train runs, test runs), ...]``; every test run is scored by a fit on its train
        runs.
    exclude
        Candidate keys not to consider.
    se_factor
        The mean relative held-out gain must exceed this many standard errors.
    sigma2
        Noise variance per sample [W²] (:func:`.diagnostics.noise_level`); NaN: no
        chi-square test (BIC only).
    alpha
        Family level of the chi-square test of the residual drop: each of a round's ``m``
        candidates (``m·(m-1)/2`` pairs) is tested at ``alpha / m`` (Bonferroni), so on data
        without any effect a round adds one by chance with probability at most ``alpha``.
    max_effects
        Stop after this many.
    max_tries, pair_pool
        Bounds of the search of one round (above).
    min_bic_drop
        The BIC must drop by more than this (module docstring); ``0``: any drop.
    floor_chi2
        Added to every chi-square limit [noise variances]: what the simulation's own
        sampling still puts into the residual (``AnalyzeOptions.sampling_chi2``).

    Returns
    -------
    SelectionResult
        The chosen blocks and every candidate tried (``steps``, with its round).
    """
    chosen: list[Block] = []
    steps: list[Step] = []
    n_test = len({r for _, test in folds for r in test})
    stop = 'max_effects'
    round_no = 0
    while len(chosen) < max_effects:
        round_no += 1
        cols = [c for b in chosen for c in b.cols]
        base = design.heldout_mse(cols, folds)
        taken = {b.key for b in chosen} | set(exclude)
        best: dict[tuple[str, str], tuple[float, Block, np.ndarray]] = {}
        for block in design.blocks:
            if block.key in taken:
                continue
            mean_mse, gains = _score(design, cols + list(block.cols), folds, base)
            if block.key not in best or mean_mse < best[block.key][0]:
                best[block.key] = (mean_mse, block, gains)
        if not best:
            stop = 'no_candidates'
            break
        ranking = sorted(((k, v[0]) for k, v in best.items()), key=lambda kv: kv[1])
        top = ranking[0][1]
        spread = top - float(np.mean(list(base.values())))
        # Candidates that fit as well as the best (collinear ones) are ties: the one with
        # the lowest BIC (fewest parameters) wins, then catalog order.
        ties = [k for k, m in ranking if m - top <= 1e-3 * abs(spread) + 1e-12 * abs(top)]
        bics = {k: design.bic(cols + list(best[k][1].cols)) for k in ties}
        first = min(ties, key=lambda k: bics[k])
        order = [first] + [k for k, _ in ranking if k != first and k not in ties]
        cands = [(k, *_mean_se(best[k][2])) for k, _ in ranking]
        bic_before = design.bic(cols)

        def judge(blocks: list[Block], tests: int) -> _Trial:
            return _judge(design, cols, blocks, folds, base, n_test=n_test,
                          se_factor=se_factor, sigma2=sigma2, alpha=alpha, tests=tests,
                          bic_before=bic_before, min_bic_drop=min_bic_drop,
                          floor_chi2=floor_chi2)
        trials = [judge([best[k][1]], len(best)) for k in order[:max_tries]]
        passed = next((t for t in trials if t.ok), None)
        if passed is None and n_test >= 2:
            pool = order[:pair_pool]
            pairs = sorted(itertools.combinations(pool, 2), key=lambda ab: (
                _score(design, cols + list(best[ab[0]][1].cols) + list(best[ab[1]][1].cols),
                       folds, base)[0], order.index(ab[0]), order.index(ab[1])))
            npairs = max(len(best) * (len(best) - 1) // 2, 1)
            for a, b in pairs:
                t = judge([best[a][1], best[b][1]], npairs)
                trials.append(t)
                if t.ok:
                    passed = t
                    break
        for t in trials:
            steps.append(Step(key=t.blocks[0].key, shape=t.blocks[0].shape,
                              mean_gain=t.mean_gain, se_gain=t.se_gain,
                              bic_before=t.bic_before, bic_after=t.bic_after,
                              accepted=t is passed, reason=t.reason, ranking=ranking,
                              candidates=cands, round=round_no,
                              with_key=t.blocks[1].key if len(t.blocks) > 1 else None,
                              chi2=t.chi2, chi2_limit=t.limit))
            if t is passed:
                break
        if passed is None:
            stop = 'rejected'
            break
        chosen.extend(passed.blocks)
    return SelectionResult(blocks=tuple(chosen), steps=tuple(steps), stop=stop)


def _mean_se(gains: np.ndarray) -> tuple[float, float]:
    mean = float(np.mean(gains)) if gains.size else math.nan
    se = float(np.std(gains, ddof=1) / math.sqrt(gains.size)) if gains.size > 1 else math.inf
    return mean, se
