"""The Ref methods' informed switch at Middle decisions (``switch.py``), as the paper's code."""

import jax
import jax.numpy as jp
import numpy as np

from nonmono_jax import hierarchy, homeostasis, switch as switch_lib

C = 10


def _run(config, values, rewards, key=0):
  """Feed one decision per (value, reward); returns the modes after each and the switches."""
  sw = switch_lib.make_informed_switch(config, hierarchy.RANDOM, C)
  state = sw.init(jp.float32(values[0]))
  decide = jax.jit(sw.decide)
  modes, switches, states = [], [], []
  keys = jax.random.split(jax.random.PRNGKey(key), len(values))
  for v, r, k in zip(values[1:], rewards, keys):
    state, switched = decide(state, jp.float32(v), jp.float32(r), k)
    modes.append(int(sw.mode(state)))
    switches.append(bool(switched))
    states.append(state)
  return np.array(modes), np.array(switches), states


def test_checks_once_the_window_holds_k_segments_and_explores_exactly():
  """rho = 1: homeostasis switches at its first check, which waits for k segments; an explore
  period is explore_steps / c decisions; then a fresh window waits k segments again."""
  k = 4
  config = homeostasis.HomeostasisConfig(rho=1.0, k=k, explore_steps=3 * C)
  n = 20
  modes, switches, _ = _run(config, np.linspace(0, 1, n + 1), np.ones(n))
  explore = modes == hierarchy.RANDOM
  # decisions 0..k-2 fill the window; the k-th decision (index k - 1) checks and switches
  np.testing.assert_array_equal(switches[:k], [False] * (k - 1) + [True])
  np.testing.assert_array_equal(explore[:k + 3], [False] * (k - 1) + [True] * 3 + [False])
  # after the explore period: k decisions of exploit before the next check switches again
  nxt = k - 1 + 3 + k
  assert switches[nxt] and not switches[k:nxt].any()


def test_value_promise_discrepancy_over_k_segments_and_stats_reset():
  """x = |V(s_{j-k}) - sum_i gamma^i R_{j-k+i} - gamma^k V(s_j)| in the Middle's units; the
  homeostasis statistics restart after an explore period (``reset_stats``)."""
  k, gamma = 3, 0.9
  config = homeostasis.HomeostasisConfig(rho=1.0, k=k, gamma=gamma, explore_steps=C)
  values = [5.0, 4.0, 2.0, 1.0, 7.0]
  rewards = [-1.0, -2.0, -0.5, 0.0]
  _, switches, states = _run(config, values, rewards)
  assert switches[k - 1]
  expected = abs(5.0 - (-1.0 - 0.9 * 2.0 - 0.81 * 0.5) - 0.729 * 1.0)
  np.testing.assert_allclose(states[k - 1].homeostasis.xbar, expected, rtol=1e-5)
  assert int(states[k - 1].homeostasis.t) == 1
  # the one-decision explore period ends at the next decision: a fresh window and statistics
  after = states[k]
  assert int(after.homeostasis.t) == 0 and int(after.filled) == 0
  np.testing.assert_allclose(after.values, np.full(k + 1, values[k + 1]))
  kept = homeostasis.HomeostasisConfig(rho=1.0, k=k, gamma=gamma, explore_steps=C,
                                       reset_stats=False)
  assert int(_run(kept, values, rewards)[2][k].homeostasis.t) == 1


def test_rate_follows_rho_per_check():
  """At rho = 0.1 per check the share of checks that switch is near 0.1."""
  config = homeostasis.HomeostasisConfig(rho=0.1, k=2, explore_steps=C)
  sw = switch_lib.make_informed_switch(config, hierarchy.PPO, C)
  n = 4000
  values = jax.random.normal(jax.random.PRNGKey(1), (n,))

  def body(state, x):
    v, key = x
    state, switched = sw.decide(state, v, jp.float32(-1.0), key)
    return state, (switched, state.explore_left)

  _, (switched, left) = jax.lax.scan(body, sw.init(jp.float32(0.0)),
                                     (values, jax.random.split(jax.random.PRNGKey(2), n)))
  checks = n - 2 * int(np.asarray(switched).sum())  # each explore decision is no check
  rate = np.asarray(switched).sum() / checks
  assert 0.06 < rate < 0.14, rate
