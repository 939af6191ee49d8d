"""The mechanics every learner shares: one optax gradient step, and U updates in a scan.

    params, opt_state, aux = gradient_step(loss, optimizer, params, opt_state, *args, lr=lr)
    state, last_metrics    = repeat(update, state, n)         # update(state, i) -> (state, m)
"""

from __future__ import annotations

from typing import Callable

import jax
import jax.numpy as jp
import optax


def gradient_step(loss: Callable, optimizer: optax.GradientTransformation, params, opt_state,
                  *args, lr=None):
  """One step of ``optimizer`` on ``loss(params, *args) -> (value, aux)``; returns the new
  params, the optimizer state and ``aux``.

  ``lr``: a (traced) learning rate, or a pytree prefix of ``params`` of them, that scales the
  updates of an ``optimizer`` built with learning rate 1 (``optax.adam(1.0)``): the same
  update as ``optax.adam(lr)`` to the bit ((-1 * u) * lr == u * -lr), and an optimizer state
  that does not hold it (checkpoints keep their shape)."""
  grads, aux = jax.grad(loss, has_aux=True)(params, *args)
  updates, opt_state = optimizer.update(grads, opt_state, params)
  if lr is not None:
    updates = jax.tree.map(lambda rate, u: jax.tree.map(lambda x: x * rate, u), lr, updates)
  return optax.apply_updates(params, updates), opt_state, aux


def repeat(update: Callable, state, n: int):
  """``n`` updates ``update(state, i) -> (state, metrics)`` in a ``lax.scan``; the metrics of
  the last one."""
  state, metrics = jax.lax.scan(update, state, jp.arange(n))
  return state, jax.tree.map(lambda m: m[-1], metrics)
