"""Schedule gates: ``lax.cond`` on the unbatched global step, zeros where the branch is skipped.

The predicate comes from the trainer's step counter, which is not batched over seeds, so under
the seed ``vmap`` the ``cond`` stays a real branch (docs/spec.md, section 6; ``tests/test_agent.py``
counts them in the jaxpr).
"""

from __future__ import annotations

import jax
import jax.numpy as jp


def gated(pred, fn, operand, reads=()):
  """``lax.cond(pred, fn, skip, operand, *reads)``: skip returns ``operand`` and zero outputs.

  ``fn(operand, *reads) -> (operand', out)``; the zeros of ``out`` take its shapes from
  ``jax.eval_shape``. ``operand`` is what the branch writes, ``reads`` what it only reads:
  give the branch no more than it writes as ``operand``, for every leaf that passes through a
  ``cond`` unchanged is a buffer XLA copies, in the branch and again into the scan's carry
  (whole train states through the gates made copies 9 % of an Ant step before;
  docs/benchmarks.md). ``fn`` is traced once: through ``jax.jit``, whose trace ``eval_shape``
  makes and the ``cond`` branch reuses (tracing twice doubled the Python tracing of the
  evaluation's env rollout, about a minute for the MJX ant); XLA inlines the call.
  """
  fn = jax.jit(fn)
  _, shapes = jax.eval_shape(fn, operand, *reads)

  def skip(x, *_):
    return x, jax.tree.map(lambda s: jp.zeros(s.shape, s.dtype), shapes)

  return jax.lax.cond(pred, fn, skip, operand, *reads)
