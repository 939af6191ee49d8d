"""Per-step metrics that declare how a chunk reduces them (a tree map, no parsing of names).

    Metric.mean(x)            mean over all steps of the chunk
    Metric.when(x, updated)   mean over the steps where ``updated`` (a level learned, a horizon
                              ended); 0 if it never did
    Metric.sum(x)             sum over the chunk (counts: env steps per mode, decisions, switches)

A step returns a flat dict of ``Metric``s; ``reduce`` turns the stacked (time-major) dict into
plain arrays, one per name, so every metric the program computes reaches the chunk's output.
"""

from __future__ import annotations

import jax
import jax.numpy as jp
from flax import struct

MEAN, WHEN, SUM = "mean", "when", "sum"


@struct.dataclass
class Metric:
  """A value with its chunk reduction (``kind``, static) and, for ``when``, its weight."""

  value: jax.Array
  weight: jax.Array
  kind: str = struct.field(pytree_node=False, default=MEAN)

  @classmethod
  def mean(cls, value) -> "Metric":
    return cls(jp.asarray(value), jp.zeros(()), MEAN)

  @classmethod
  def when(cls, value, updated) -> "Metric":
    return cls(jp.asarray(value), jp.asarray(updated, jp.float32), WHEN)

  @classmethod
  def sum(cls, value) -> "Metric":
    return cls(jp.asarray(value), jp.zeros(()), SUM)

  def reduce(self, axis: int = 0) -> jax.Array:
    if self.kind == SUM:
      return self.value.sum(axis=axis)
    if self.kind == WHEN:
      w = self.weight
      return (self.value * w).sum(axis=axis) / jp.maximum(w.sum(axis=axis), 1.0)
    return self.value.mean(axis=axis)


def level(name: str, values: dict, updated) -> dict:
  """``{name/k: mean over the steps where updated}`` and ``name/updated`` (their count)."""
  return {**{f"{name}/{k}": Metric.when(v, updated) for k, v in values.items()},
          f"{name}/updated": Metric.sum(jp.asarray(updated, jp.float32))}


def reduce(metrics: dict, axis: int = 0) -> dict:
  """Stacked metrics (time on ``axis``) -> one array per name."""
  return {name: m.reduce(axis) for name, m in metrics.items()}
