"""On-device replay buffer: a fixed-capacity ring of transitions, sampled uniformly.

Why not brax's ``UniformSamplingQueue``: when full it makes room by rolling the whole storage
(``jnp.roll`` under a ``lax.cond``), and under ``vmap`` over seeds that cond becomes a select,
so every insert would copy all 200K transitions. Here an insert writes ``n`` rows at
``(position + i) % capacity``: O(n), whatever the capacity and however it is batched.

The buffer holds any pytree of arrays with a leading capacity axis; ``add`` takes the same
pytree with a leading axis of ``n`` new transitions.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jp
from flax import struct


@struct.dataclass
class ReplayBuffer:
  """Storage (pytree, leading axis ``capacity``), the next write slot and the fill level."""

  data: Any
  position: jax.Array  # int32: next slot to write
  size: jax.Array  # int32: valid transitions, at most capacity

  @property
  def capacity(self) -> int:
    return jax.tree.leaves(self.data)[0].shape[0]


def template(fn, *args, lead: tuple = ()) -> Any:
  """Zeros shaped like ``fn(*args)`` with ``lead`` axes in front, from ``jax.eval_shape``
  (nothing is computed; ``args`` may be ``jax.ShapeDtypeStruct``s)."""
  shapes = jax.eval_shape(fn, *args)
  return jax.tree.map(lambda s: jp.zeros(tuple(lead) + s.shape, s.dtype), shapes)


def init(example: Any, capacity: int) -> ReplayBuffer:
  """An empty buffer for transitions shaped like ``example`` (one transition, no batch axis;
  arrays or ``jax.ShapeDtypeStruct``s)."""
  if capacity < 1:
    raise ValueError(f"capacity must be >= 1, got {capacity}")
  data = jax.tree.map(lambda x: jp.zeros((capacity,) + jp.shape(x), jp.result_type(x)), example)
  return ReplayBuffer(data=data, position=jp.zeros((), jp.int32), size=jp.zeros((), jp.int32))


def add(buffer: ReplayBuffer, transitions: Any) -> ReplayBuffer:
  """Write ``n`` transitions (leading axis ``n``), overwriting the oldest when full."""
  n = jax.tree.leaves(transitions)[0].shape[0]
  cap = buffer.capacity
  if n > cap:
    raise ValueError(f"cannot add {n} transitions to a buffer of capacity {cap}")
  idx = (buffer.position + jp.arange(n)) % cap
  data = jax.tree.map(lambda d, t: d.at[idx].set(t.astype(d.dtype)), buffer.data, transitions)
  return ReplayBuffer(data=data, position=(buffer.position + n) % cap,
                      size=jp.minimum(buffer.size + n, cap))


def sample(buffer: ReplayBuffer, key: jax.Array, batch_size: int) -> Any:
  """``batch_size`` transitions drawn uniformly, with replacement, from the filled part.

  Sampling an empty buffer returns slot 0 (zeros); callers gate updates on ``size``.
  """
  idx = jax.random.randint(key, (batch_size,), 0, jp.maximum(buffer.size, 1))
  return jax.tree.map(lambda d: d[idx], buffer.data)
