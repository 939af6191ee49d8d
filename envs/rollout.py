"""The one env rollout: ``env.step`` in a ``lax.scan``, driven by a policy with a carry.

Evaluation and rendering (the hierarchical policy, ``nonmono_jax/core/evaluate.py``), the random
baseline and the env benchmark all unroll through it:

    (last_state, carry), records = unroll(env, state, act, xs, carry, observe)

per step: ``a = act(carry, s, x)``, ``s' = env.step(s, a)``, ``carry, record = observe(carry,
s, s', x)``; ``xs`` are the scan's inputs (step indices, keys).
"""

from __future__ import annotations

from typing import Any, Callable

import jax


def _nothing(carry, s, s_next, x):
  return carry, None


def unroll(env, state, act: Callable, xs, carry: Any = None,
           observe: Callable = _nothing):
  """``lax.scan`` of env steps from ``state`` over ``xs`` (see the module doc)."""

  def body(c, x):
    s, carry = c
    s_next = env.step(s, act(carry, s, x))
    carry, record = observe(carry, s, s_next, x)
    return (s_next, carry), record

  return jax.lax.scan(body, (state, carry), xs)
