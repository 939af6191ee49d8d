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
interval estimates): with 5-8 seeds the bootstrap distribution has only 126-6435 distinct
resamples, and the Monte Carlo error of a 2.5 % percentile from 2000 replicates is
sqrt(0.025 x 0.975 / 2000) = 0.35 percentile points, small next to the interval's width, while
a table of every task and method stays under a second. Replicates are drawn from a numpy
Generator seeded by ``seed``: the same call gives the same interval.
"""

from __future__ import annotations

from typing import Callable

import numpy as np
import scipy.stats

REPS = 2000
SIZE = 0.95


def iqm(scores) -> np.ndarray:
  """Interquartile mean over runs x tasks (axes 0 and 1), per any further axis (steps)."""
  s = np.asarray(scores, dtype=float)
  return scipy.stats.trim_mean(s.reshape(-1, *s.shape[2:]), proportiontocut=0.25, axis=0)


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


def interval(statistic: Callable[..., np.ndarray], *scores, reps: int = REPS,
             size: float = SIZE, seed: int = 0):
  """(point, lower, upper): ``statistic(*scores)`` and its stratified-bootstrap percentile
  interval of coverage ``size``.

  ``statistic`` reduces axes 0 and 1 (runs, tasks) of each argument and keeps any further
  ones (the replicates come on a last axis), as ``iqm`` and ``probability_of_improvement``
  do. Several score arrays (P(X > Y)) are resampled independently of one another.
  """
  if not (isinstance(reps, (int, np.integer)) and reps >= 1):
    raise ValueError(f"reps must be an integer >= 1, got {reps!r}")
  if not 0 < size < 1:
    raise ValueError(f"size must be in (0, 1), got {size!r}")
  scores = [as_scores(s) for s in scores]
  rng = np.random.default_rng(seed)
  replicates = statistic(*(resample(s, reps, rng) for s in scores))
  tail = 100 * (1 - size) / 2
  lower, upper = np.percentile(replicates, [tail, 100 - tail], axis=-1)
  return statistic(*scores), lower, upper


def iqm_curve(values, reps: int = REPS, size: float = SIZE, seed: int = 0):
  """(iqm, lower, upper) per step of one task's ``values`` (runs, steps): the aggregate
  curve with pointwise intervals (rliable's sample-efficiency curves)."""
  values = np.asarray(values, dtype=float)
  if values.ndim != 2:
    raise ValueError(f"values must be (runs, steps), got shape {values.shape}")
  return interval(iqm, values[:, None, :], reps=reps, size=size, seed=seed)
