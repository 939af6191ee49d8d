"""The Ref methods' informed switch at Middle decisions (``modes/trigger.py``), as the paper's
code."""

import jax
import jax.numpy as jp
import numpy as np
import pytest

from nonmono_jax.core import hierarchy, homeostasis
from nonmono_jax.core.modes import trigger as switch_lib

C = 10
EXPLORE, EXPLOIT = hierarchy.RANDOM, hierarchy.TD3


def _run(config, values, rewards, key=0, rhos=None):
  """Feed one decision per (value, reward) (and rho, else the config's); returns the modes
  after each and the switches."""
  sw = switch_lib.make_informed_switch(config, hierarchy.RANDOM, C)
  state = sw.init(jp.float32(values[0]))
  decide = jax.jit(sw.decide)
  modes, switches, states = [], [], []
  keys = jax.random.split(jax.random.PRNGKey(key), len(values))
  rhos = [config.rho] * len(rewards) if rhos is None else rhos
  for v, r, k, rho in zip(values[1:], rewards, keys, rhos):
    state, switched = decide(state, jp.float32(v), jp.float32(r), k, jp.float32(rho))
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


def _code_run(rhos):
  """The code's cadence (k = 30) on a constant signal, so a check switches with probability
  rho exactly: (mode of each segment from the end of the starting phase, switches, states)."""
  config = homeostasis.HomeostasisConfig(k=30, cadence="code")
  n = len(rhos)
  modes, switches, states = _run(config, np.zeros(n + 1), np.zeros(n), rhos=rhos)
  sw = switch_lib.make_informed_switch(config, EXPLORE, C)
  first = int(sw.mode(sw.init(jp.float32(0.0))))
  return np.concatenate([[first], modes]), switches, states


def test_code_cadence_switches_certain():
  """rho = 1: after the starting phase 29 explore segments, then a check (it switches); each
  switch explores exactly k = 30 segments with the next check right after them."""
  modes, switches, states = _code_run([1.0] * 120)
  assert (modes == EXPLORE).all()
  # decision j ends segment j (segment 0 is the restart's); checks at 28, 58, 88, 118
  np.testing.assert_array_equal(np.flatnonzero(switches), [28, 58, 88, 118])
  # fresh statistics at each check: one update since the reset
  assert all(int(states[j].homeostasis.t) == 1 for j in (28, 58, 88, 118))
  assert [int(states[j].explore_left) for j in (27, 28, 29, 57)] == [1, 30, 29, 1]


def test_code_cadence_switches_impossible():
  """rho = 0: 29 explore segments after the starting phase, then a check at every segment and
  the exploit mode (TD3) for good."""
  modes, switches, states = _code_run([0.0] * 80)
  np.testing.assert_array_equal(modes, [EXPLORE] * 29 + [EXPLOIT] * 52)
  assert not switches.any()
  np.testing.assert_array_equal([int(s.homeostasis.t) for s in states],
                                [0] * 28 + list(range(1, 53)))


def test_code_cadence_one_switch_between_exploits():
  """One certain switch at the 6th check: 30 explore segments, a check right after them (no
  exploit period, no window to fill), then exploit with a check every segment."""
  rhos = [0.0] * 33 + [1.0] + [0.0] * 40
  modes, switches, states = _code_run(rhos)
  np.testing.assert_array_equal(np.flatnonzero(switches), [33])
  np.testing.assert_array_equal(
      modes, [EXPLORE] * 29 + [EXPLOIT] * 5 + [EXPLORE] * 30 + [EXPLOIT] * 11)
  # the check after the explore run is the first of fresh statistics; then one per segment
  assert int(states[62].homeostasis.t) == 6 and int(states[63].homeostasis.t) == 1
  assert int(states[73].homeostasis.t) == 11
  assert int(states[63].filled) == 30  # the window slid over the explore segments


def _explore_share(cadence, p, n=30000):
  """Share of explore segments over n decisions at switch probability p per check."""
  config = homeostasis.HomeostasisConfig(rho=p, k=30, explore_steps=100, cadence=cadence)
  sw = switch_lib.make_informed_switch(config, hierarchy.PPO, C)

  def body(state, key):
    state, _ = sw.decide(state, jp.float32(0.0), jp.float32(0.0), key)
    return state, sw.mode(state) == hierarchy.PPO

  _, explore = jax.lax.scan(body, sw.init(jp.float32(0.0)),
                            jax.random.split(jax.random.PRNGKey(3), n))
  return float(np.mean(np.asarray(explore)))


def test_code_cadence_explore_share():
  """A check explores k = 30 segments with probability p, else exploits one: a share of
  30 p / (1 + 29 p); the periods' 10 explore and 30 exploit segments give 10 p / (1 + 39 p)."""
  p = 0.02
  code, periods = _explore_share("code", p), _explore_share("periods", p)
  np.testing.assert_allclose(code, 30 * p / (1 + 29 * p), rtol=0.25)
  np.testing.assert_allclose(periods, 10 * p / (1 + 39 * p), rtol=0.25)
  assert code > 2.5 * periods, (code, periods)


def test_cadence_validation_and_default():
  assert homeostasis.HomeostasisConfig().cadence == "periods"
  with pytest.raises(ValueError, match="homeostasis.cadence must be one of periods, code"):
    homeostasis.HomeostasisConfig(cadence="counter")
  # the periods cadence restarts into exploit; the code's into its k - 1 explore decisions
  for cadence, left in (("periods", 0), ("code", 29)):
    sw = switch_lib.make_informed_switch(
        homeostasis.HomeostasisConfig(cadence=cadence), hierarchy.PPO, C)
    assert int(sw.init(jp.float32(1.0)).explore_left) == left
