"""Network factories: each returns a frozen ``Network`` of pure ``init`` / ``apply`` functions.

Following brax's ``networks.py``: the flax module stays inside the factory; callers see
``params = net.init(key)`` and ``net.apply(params, *inputs)`` (inputs are concatenated on the
last axis, so ``apply(params, obs, goal)`` is a goal-conditioned network).

Initialisation (``INITS``): ``"lecun"``, lecun-uniform weights and zero biases (flax's usual);
``"torch"``, PyTorch's default for ``nn.Linear``, which the paper's code keeps: weights and
biases both U(-1/sqrt(fan_in), 1/sqrt(fan_in)), 1/sqrt(3) of lecun-uniform's weight scale.

The dots' operands (``MATMULS``): ``"float32"``, or ``"bfloat16"``: each layer's input and
weights rounded to bfloat16 for its dot (forward and backward), the products summed and
returned in float32, the bias, activations, parameters and optimizer state float32. On a CPU
with AVX512-BF16 XLA runs those dots 1.4-1.6x faster (docs/benchmarks.md); it changes the
arithmetic, so it is an option, off in every preset.
"""

from __future__ import annotations

import dataclasses
from typing import Callable, Sequence

import flax.linen as nn
import jax
import jax.numpy as jp

from nonmono_jax.core.config import INITS, MATMULS

Activation = Callable[[jax.Array], jax.Array]


def _torch_uniform(fan_in: int):
  bound = 1.0 / fan_in**0.5
  return lambda key, shape, dtype=jp.float32: jax.random.uniform(key, shape, dtype, -bound, bound)


@dataclasses.dataclass(frozen=True)
class Network:
  """A pure network: ``init(key) -> params``, ``apply(params, *inputs) -> output``."""

  init: Callable[[jax.Array], dict]
  apply: Callable[..., jax.Array]


def _bfloat16_dot(lhs, rhs, dimension_numbers, precision=None, preferred_element_type=None):
  """``lax.dot_general`` of the operands rounded to bfloat16, summed and returned in float32."""
  return jax.lax.dot_general(lhs.astype(jp.bfloat16), rhs.astype(jp.bfloat16),
                             dimension_numbers, precision=precision,
                             preferred_element_type=jp.float32)


class MLP(nn.Module):
  """Dense layers with an activation between them and an optional one at the end."""

  sizes: Sequence[int]
  activation: Activation = nn.relu
  final_activation: Activation | None = None
  weights: str = "lecun"  # INITS (``init`` is flax's method)
  matmul: str = "float32"  # MATMULS: the dots' operands

  @nn.compact
  def __call__(self, x: jax.Array) -> jax.Array:
    dot = {"dot_general": _bfloat16_dot} if self.matmul == "bfloat16" else {}
    for i, size in enumerate(self.sizes):
      if self.weights == "torch":
        uniform = _torch_uniform(x.shape[-1])
        dense = nn.Dense(size, kernel_init=uniform, bias_init=uniform, name=f"dense_{i}",
                         **dot)
      else:
        dense = nn.Dense(size, kernel_init=nn.initializers.lecun_uniform(), name=f"dense_{i}",
                         **dot)
      x = dense(x)
      if i < len(self.sizes) - 1:
        x = self.activation(x)
    if self.final_activation is not None:
      x = self.final_activation(x)
    return x


def make_mlp(input_size: int, hidden: Sequence[int], output_size: int,
             activation: Activation = nn.relu,
             final_activation: Activation | None = None, init: str = "lecun",
             matmul: str = "float32") -> Network:
  """An MLP over the concatenation of its inputs (total width ``input_size``), initialised
  as ``init`` says (``INITS``), its dots on ``matmul`` operands (``MATMULS``)."""
  if init not in INITS:
    raise ValueError(f"init must be one of {', '.join(INITS)}, got {init!r}")
  if matmul not in MATMULS:
    raise ValueError(f"matmul must be one of {', '.join(MATMULS)}, got {matmul!r}")
  module = MLP(tuple(hidden) + (output_size,), activation, final_activation, init, matmul)

  def init(key):
    return module.init(key, jp.zeros((1, input_size)))

  def apply(params, *inputs):
    return module.apply(params, jp.concatenate(inputs, axis=-1))

  return Network(init, apply)
