"""Network factories: each returns a frozen ``Network`` of pure ``init`` / ``apply`` functions.

Following brax's ``networks.py``: the flax module stays inside the factory; callers see
``params = net.init(key)`` and ``net.apply(params, *inputs)`` (inputs are concatenated on the
last axis, so ``apply(params, obs, goal)`` is a goal-conditioned network).

Initialisation (``INITS``): ``"lecun"``, lecun-uniform weights and zero biases (flax's usual);
``"torch"``, PyTorch's default for ``nn.Linear``, which the paper's code keeps: weights and
biases both U(-1/sqrt(fan_in), 1/sqrt(fan_in)), 1/sqrt(3) of lecun-uniform's weight scale.
"""

from __future__ import annotations

import dataclasses
from typing import Callable, Sequence

import flax.linen as nn
import jax
import jax.numpy as jp

from nonmono_jax.core.config import INITS

Activation = Callable[[jax.Array], jax.Array]


def _torch_uniform(fan_in: int):
  bound = 1.0 / fan_in**0.5
  return lambda key, shape, dtype=jp.float32: jax.random.uniform(key, shape, dtype, -bound, bound)


@dataclasses.dataclass(frozen=True)
class Network:
  """A pure network: ``init(key) -> params``, ``apply(params, *inputs) -> output``."""

  init: Callable[[jax.Array], dict]
  apply: Callable[..., jax.Array]


class MLP(nn.Module):
  """Dense layers with an activation between them and an optional one at the end."""

  sizes: Sequence[int]
  activation: Activation = nn.relu
  final_activation: Activation | None = None
  weights: str = "lecun"  # INITS (``init`` is flax's method)

  @nn.compact
  def __call__(self, x: jax.Array) -> jax.Array:
    for i, size in enumerate(self.sizes):
      if self.weights == "torch":
        uniform = _torch_uniform(x.shape[-1])
        dense = nn.Dense(size, kernel_init=uniform, bias_init=uniform, name=f"dense_{i}")
      else:
        dense = nn.Dense(size, kernel_init=nn.initializers.lecun_uniform(), name=f"dense_{i}")
      x = dense(x)
      if i < len(self.sizes) - 1:
        x = self.activation(x)
    if self.final_activation is not None:
      x = self.final_activation(x)
    return x


def make_mlp(input_size: int, hidden: Sequence[int], output_size: int,
             activation: Activation = nn.relu,
             final_activation: Activation | None = None, init: str = "lecun") -> Network:
  """An MLP over the concatenation of its inputs (total width ``input_size``), initialised
  as ``init`` says (``INITS``)."""
  if init not in INITS:
    raise ValueError(f"init must be one of {', '.join(INITS)}, got {init!r}")
  module = MLP(tuple(hidden) + (output_size,), activation, final_activation, init)

  def init(key):
    return module.init(key, jp.zeros((1, input_size)))

  def apply(params, *inputs):
    return module.apply(params, jp.concatenate(inputs, axis=-1))

  return Network(init, apply)
