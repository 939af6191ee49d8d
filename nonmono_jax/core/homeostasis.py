"""Pislar et al. (2022)'s informed switching trigger: value promise discrepancy + homeostasis.

The Ref:Uniform and Ref:PPO baselines of Kim et al. (2023) are "X, intra(100), informed":
X = start in explore mode (in the paper's code: one starting phase of 250K steps after
warm-up), intra(100) = a switch happens inside an episode and an explore period lasts
``explore_steps`` (100) steps, informed = the exploit -> explore switch is triggered by a
signal (``modes/trigger.py`` applies it at Middle decisions, as the paper's code does). The
signal is the value promise discrepancy

  D(t-k, t) = | V(s_{t-k}) - sum_{i=0}^{k-1} gamma^i r_{t-k+i} - gamma^k V(s_t) |,

how far the value promised k steps ago is from what was received since. Its scale is unknown,
so homeostasis turns it into switch decisions at a target rate rho. Per step t = 1, 2, ...:

  tau      = min(t, 100 / rho)
  xbar     <- (1 - 1/tau) xbar     + x / tau
  x2bar    <- (1 - 1/tau) x2bar    + (x - xbar)^2 / tau
  xplus    =  exp((x - xbar) / sqrt(x2bar))
  xplusbar <- (1 - 1/tau) xplusbar + xplus / tau
  switch   ~  Bernoulli(min(1, rho * xplus / xplusbar))

xplus divides by the standard deviation sqrt(x2bar), as Pislar et al. do; Kim et al.'s PyTorch
code divides by the variance x2bar (a quirk not reproduced).
"""

from __future__ import annotations

import jax
import jax.numpy as jp
from flax import struct

# declared with the agent's config, which imports no JAX
from nonmono_jax.core.config import CADENCES, HomeostasisConfig  # noqa: F401

EPS = 1e-8  # floor of the standard deviation: x2bar is 0 at the first step and on a constant x
MAX_Z = 50.0  # cap of the standardised excess, so exp never overflows to inf (inf/inf = NaN)
HORIZON = 100.0  # tau's cap is HORIZON / rho: averages over ~100 expected switches


def value_promise_discrepancy(v_start: jax.Array, rewards: jax.Array, v_end: jax.Array,
                              gamma: float | jax.Array) -> jax.Array:
  """D(t-k, t) from V(s_{t-k}), the k rewards r_{t-k}..r_{t-1} and V(s_t).

  ``rewards[i]`` is r_{t-k+i}, the reward received right after s_{t-k+i} (Pislar et al.'s
  definition; Kim et al.'s text writes R_{t-i}, a typo: that would index the rewards backwards
  from t). One window per call; vmap over windows.
  """
  k = rewards.shape[0]
  discounts = jp.power(gamma, jp.arange(k, dtype=jp.float32))
  discounted = jp.sum(discounts * rewards)
  return jp.abs(v_start - discounted - jp.power(gamma, k) * v_end)


@struct.dataclass
class HomeostasisState:
  """Running averages of homeostasis; ``t`` counts the updates made so far."""

  t: jax.Array  # int32
  xbar: jax.Array  # running mean of x
  x2bar: jax.Array  # running variance of x
  xplusbar: jax.Array  # running mean of xplus


def init() -> HomeostasisState:
  """The state before the first update."""
  zero = jp.zeros((), jp.float32)
  return HomeostasisState(t=jp.zeros((), jp.int32), xbar=zero, x2bar=zero, xplusbar=zero)


def switch_probability(state: HomeostasisState, x: jax.Array,
                       rho: float | jax.Array) -> tuple[HomeostasisState, jax.Array]:
  """(updated state, switch probability min(1, rho * xplus / xplusbar)) for the signal x.

  xplus standardises by the standard deviation sqrt(x2bar), as Pislar et al. do; Kim et al.'s
  PyTorch code divides by the variance x2bar instead (a quirk not reproduced here).

  x - xbar is computed as (1 - 1/tau) (x - xbar_old), so the first step after a reset gives
  z = 0 exactly. Computed as x - xbar it is 0 only if XLA evaluates x the same way in both
  places: a fused program that recomputes x may round it differently, and the difference of
  ~1e-8, divided by the floor EPS, made z about 3 (xplus about 20) in the first check after
  every reset (seen in a program compiled at LLVM -O0: the switch rate fell from rho to rho/5).
  """
  x = jp.asarray(x, jp.float32)
  rho = jp.asarray(rho, jp.float32)
  t = state.t + 1
  tau = jp.minimum(t.astype(jp.float32), HORIZON / rho)
  keep = 1.0 - 1.0 / tau
  deviation = x - state.xbar
  xbar = state.xbar + deviation / tau  # = keep xbar + x / tau
  excess = keep * deviation  # = x - xbar, and exactly 0 at t = 1 (keep = 0)
  x2bar = keep * state.x2bar + jp.square(excess) / tau
  z = excess / jp.maximum(jp.sqrt(x2bar), EPS)
  xplus = jp.exp(jp.minimum(z, MAX_Z))
  xplusbar = keep * state.xplusbar + xplus / tau
  prob = jp.minimum(1.0, rho * xplus / xplusbar)
  return HomeostasisState(t=t, xbar=xbar, x2bar=x2bar, xplusbar=xplusbar), prob


def update(state: HomeostasisState, x: jax.Array, key: jax.Array,
           rho: float | jax.Array) -> tuple[HomeostasisState, jax.Array]:
  """(updated state, switch) with switch ~ Bernoulli(min(1, rho * xplus / xplusbar)).

  ``rho`` may be traced (vmap a sweep over it); ``state``, ``x`` and ``key`` vmap over seeds.
  """
  state, prob = switch_probability(state, x, rho)
  return state, jax.random.bernoulli(key, prob)
