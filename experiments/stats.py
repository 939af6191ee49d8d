"""Aggregate statistics over seeds as rliable defines them (Agarwal et al. 2021, "Deep
Reinforcement Learning at the Edge of the Statistical Precipice"), in numpy and scipy.

Scores are arrays of shape (runs, tasks), or (runs, tasks, steps) for curves; a 1-D array is
the runs of one task. Here a score is a seed's S_E (final, best, or at each evaluation).

- ``iqm``: the interquartile mean, the mean of the middle 50 % of all runs x tasks
  (``scipy.stats.trim_mean(x, 0.25)`` over the flattened scores: int(0.25 n) scores cut at
  each end, as rliable's ``aggregate_iqm``).
- ``probability_of_improvement``: P(X > Y), per task the Mann-Whitney U statistic of X over Y
  divided by n m (every pair of a run of X and a run of Y counts 1 when X's is higher, 1/2 when
  they tie), averaged over tasks (rliable's ``probability_of_improvement``).
- ``interval``: a statistic with its percentile confidence interval from the stratified
  bootstrap: the runs are resampled with replacement within each task (and, for curves, at
  each step independently: pointwise intervals), several score arrays independently of one
  another (rliable's ``StratifiedBootstrap`` / ``StratifiedIndependentBootstrap``), and the
  interval is the 2.5th and 97.5th percentiles of the replicates (``np.percentile``, linear,
  as ``arch``'s ``conf_int(method="percentile")``).

``REPS`` = 2000 replicates by default (rliable: 2000 for its performance profiles, 50000 for
interval estimates), drawn from a numpy Generator seeded by ``seed``: the same call gives the
same interval, and a table of every task and method stays under a second. The Monte Carlo
error of a 2.5 % percentile from 2000 replicates is sqrt(0.025 x 0.975 / 2000) = 0.35
percentile points; with 5-8 seeds the bootstrap distribution has only 126-6435 distinct
resamples (as multisets) and gaps between them, so an end can move by a large step with the
draw. A reading that compares an end with a level or with another interval by a small margin
can then flip with ``seed`` (the Ant Push study's claim 4a, ``results/antpush/README.md``).

``reps="exact"`` computes the interval from every resample instead of a draw: each array's
n^n equally likely resamples of its n runs per task (and the product of these over tasks and
over several arrays), enumerated as the multisets they form, each weighted by the number of
ordered resamples it stands for, and the percentiles of that bootstrap distribution itself
(``weighted_percentile``: its inverse distribution function, where the drawn percentiles go
as the draws grow). Not the linear interpolation between the n^n values that ``np.percentile``
would make of them as a sample: with 3 runs, the all-lowest resample has probability 1/27 (above
2.5 %), so the lower end is the lowest run's value, as in every large draw; interpolating
between the 27 values would put it a fifth of the way to the next (until 2026-12-06 it did;
tests/test_stats.py). That needs a statistic that
does not depend on the order of the runs (``iqm`` and ``probability_of_improvement`` do not)
and at most ``EXACT_LIMIT`` multisets in all: 6 runs have 462 (of 46,656 resamples), 10 runs
92,378; P(X > Y) of 6 runs against 6 is 462^2 = 213,444.
"""

from __future__ import annotations

import itertools
import math
from typing import Callable

import numpy as np
import scipy.stats

REPS = 2000
SIZE = 0.95
EXACT_LIMIT = 1_000_000  # multisets that reps="exact" enumerates, over all arrays and tasks
CHUNK = 20_000  # exact replicates computed at once (memory)


def iqm(scores) -> np.ndarray:
  """Interquartile mean over runs x tasks (axes 0 and 1), per any further axis (steps)."""
  s = np.asarray(scores, dtype=float)
  return scipy.stats.trim_mean(s.reshape(-1, *s.shape[2:]), proportiontocut=0.25, axis=0)


def mean(scores) -> np.ndarray:
  """Mean over runs x tasks (axes 0 and 1), per any further axis (steps)."""
  s = np.asarray(scores, dtype=float)
  return s.reshape(-1, *s.shape[2:]).mean(axis=0)


def probability_of_improvement(x, y) -> np.ndarray:
  """P(X > Y): per task U / (n m), ties 1/2, averaged over tasks (axis 1 of (runs, tasks))."""
  x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
  pairs = (x[:, None] > y[None, :]) + 0.5 * (x[:, None] == y[None, :])
  return pairs.mean(axis=(0, 1)).mean(axis=0)


def as_scores(scores) -> np.ndarray:
  """A float array (runs, tasks, ...); 1-D runs become one task. Raises ValueError."""
  s = np.asarray(scores, dtype=float)
  s = s[:, None] if s.ndim == 1 else s
  if s.ndim < 2 or s.shape[0] == 0 or s.shape[1] == 0:
    raise ValueError(f"scores must be (runs, tasks[, steps]) with at least one of each, "
                     f"got shape {np.shape(scores)}")
  if not np.isfinite(s).all():
    raise ValueError("scores must be finite (a NaN or inf among them)")
  return s


def resample(scores: np.ndarray, reps: int, rng: np.random.Generator) -> np.ndarray:
  """Stratified bootstrap replicates, on a new last axis: the runs (axis 0) drawn with
  replacement for every task, and every step, on its own."""
  idx = rng.integers(scores.shape[0], size=scores.shape + (reps,))
  return np.take_along_axis(scores[..., None], idx, axis=0)


def multisets(n: int):
  """Every resample of n runs up to order: (K, n) sorted run indices, K = C(2n - 1, n), and
  (K,) how many of the n^n ordered resamples each one is (n! / prod of its counts!)."""
  idx = np.array(list(itertools.combinations_with_replacement(range(n), n)), dtype=np.intp)
  counts = (idx[:, :, None] == np.arange(n)).sum(1)
  factorial = np.array([math.factorial(k) for k in range(n + 1)], dtype=np.int64)
  return idx, factorial[n] // factorial[counts].prod(1)


def _exact_replicates(statistic, scores: list[np.ndarray]):
  """``statistic`` of every distinct stratified resample of ``scores`` (the replicates on a
  last axis) and each one's weight, the number of ordered resamples it stands for."""
  sets = {n: multisets(n) for n in {s.shape[0] for s in scores}}
  dims = [len(sets[s.shape[0]][0]) for s in scores for _ in range(s.shape[1])]
  total = math.prod(dims)
  if total > EXACT_LIMIT:
    raise ValueError(f"reps='exact' needs {total} resamples as multisets (runs per array "
                     f"{[s.shape[0] for s in scores]}, tasks {[s.shape[1] for s in scores]}), "
                     f"more than EXACT_LIMIT = {EXACT_LIMIT}; give an integer reps")
  values, weights = [], []
  for start in range(0, total, CHUNK):
    which = np.unravel_index(np.arange(start, min(start + CHUNK, total)), dims)
    weight, k, drawn = np.ones(len(which[0]), dtype=np.int64), 0, []
    for s in scores:
      idx, mult = sets[s.shape[0]]
      per_task = []
      for _ in range(s.shape[1]):
        per_task.append(idx[which[k]].T)  # (runs, m)
        weight, k = weight * mult[which[k]], k + 1
      cols = np.stack(per_task, axis=1).reshape(s.shape[:2] + (1,) * (s.ndim - 2) + (-1,))
      drawn.append(np.take_along_axis(s[..., None], cols, axis=0))
    values.append(statistic(*drawn))
    weights.append(weight)
  return np.concatenate(values, axis=-1), np.concatenate(weights)


def weighted_percentile(values, weights, q):
  """The ``q``-th percentiles of the distribution that gives each value (last axis) its
  integer weight: ``np.percentile(np.repeat(values, weights, axis=-1), q, axis=-1,
  method="averaged_inverted_cdf")`` without building the repeated array. The inverse of the
  distribution function (the mean of two values where it sits exactly on ``q``): the limit of
  the percentile of ever more draws from the distribution, as ``interval``'s drawn replicates
  estimate it."""
  values, weights = np.asarray(values, dtype=float), np.asarray(weights, dtype=np.int64)
  order = np.argsort(values, axis=-1, kind="stable")
  v = np.take_along_axis(values, order, axis=-1)
  cum = np.cumsum(weights[order], axis=-1)
  n = cum[..., -1:]
  last = v.shape[-1] - 1
  out = []
  for p in np.atleast_1d(q):
    k = p / 100 * n
    on_step = np.isclose(k, np.round(k), rtol=1e-12, atol=1e-9)
    j = np.where(on_step, np.round(k), np.floor(k))  # the order statistic j (0-based) ...
    upper = np.minimum((cum <= j).sum(-1, keepdims=True), last)
    lower = np.minimum((cum <= j - 1).sum(-1, keepdims=True), last)  # ... and j - 1
    a, b = np.take_along_axis(v, lower, -1), np.take_along_axis(v, upper, -1)
    out.append(np.where(on_step, (a + b) / 2, b)[..., 0])
  return np.stack(out) if np.ndim(q) else out[0]


def interval(statistic: Callable[..., np.ndarray], *scores, reps=REPS,
             size: float = SIZE, seed: int = 0):
  """(point, lower, upper): ``statistic(*scores)`` and its stratified-bootstrap percentile
  interval of coverage ``size``.

  ``statistic`` reduces axes 0 and 1 (runs, tasks) of each argument and keeps any further
  ones (the replicates come on a last axis), as ``iqm`` and ``probability_of_improvement``
  do. Several score arrays (P(X > Y)) are resampled independently of one another. ``reps``:
  the number of replicates drawn (seeded by ``seed``), or "exact" for every resample (the
  module's docstring; ``seed`` is then unused).
  """
  exact = isinstance(reps, str) and reps == "exact"
  if not exact and not (isinstance(reps, (int, np.integer)) and reps >= 1):
    raise ValueError(f"reps must be an integer >= 1 or 'exact', got {reps!r}")
  if not 0 < size < 1:
    raise ValueError(f"size must be in (0, 1), got {size!r}")
  scores = [as_scores(s) for s in scores]
  tail = 100 * (1 - size) / 2
  if exact:
    replicates, weights = _exact_replicates(statistic, scores)
    lower, upper = weighted_percentile(replicates, weights, [tail, 100 - tail])
  else:
    rng = np.random.default_rng(seed)
    replicates = statistic(*(resample(s, reps, rng) for s in scores))
    lower, upper = np.percentile(replicates, [tail, 100 - tail], axis=-1)
  return statistic(*scores), lower, upper


def mean_curve(values, reps=REPS, size: float = SIZE, seed: int = 0):
  """(mean, lower, upper) per step of one task's ``values`` (runs, steps): the mean curve with
  pointwise stratified-bootstrap intervals."""
  values = np.asarray(values, dtype=float)
  if values.ndim != 2:
    raise ValueError(f"values must be (runs, steps), got shape {values.shape}")
  return interval(mean, values[:, None, :], reps=reps, size=size, seed=seed)


def iqm_curve(values, reps=REPS, size: float = SIZE, seed: int = 0):
  """(iqm, lower, upper) per step of one task's ``values`` (runs, steps): the aggregate
  curve with pointwise intervals (rliable's sample-efficiency curves)."""
  values = np.asarray(values, dtype=float)
  if values.ndim != 2:
    raise ValueError(f"values must be (runs, steps), got shape {values.shape}")
  return interval(iqm, values[:, None, :], reps=reps, size=size, seed=seed)
