"""The Top level's transition and update, and what the ablations switch off."""

import jax
import jax.numpy as jp
import numpy as np

from nonmono_jax.core import hierarchy, lanes, ppo
from nonmono_jax.core.modes import top as top_lib
from nonmono_jax.core.modes.top import Horizon, make_top
from nonmono_jax.host import methods

OBS = 4
TARGET = (0.0, 19.0, 0.5)
_ppo = ppo.PPOConfig(hidden=(8,), discrete=True)


def _top(method):
  """The Top of ``method`` and its numbers (``hp``)."""
  config = methods.build_config("paper", method, "AntPush", {
      "top.ppo": _ppo, "returns_cross_episodes": False})[0]
  return make_top(OBS, TARGET, config), lanes.of(config).top


def _horizon(mode, reward=-100.0, done_count=30.0, count=50.0):
  return Horizon(obs=jp.zeros(OBS + 3), mode=jp.asarray(mode, jp.int32), log_prob=jp.zeros(()),
                 reward=jp.asarray(reward), done_count=jp.asarray(done_count),
                 count=jp.asarray(count))


def test_close_rewards_and_dones():
  top, hp = _top("ours")  # Push: alpha (0, 0.4, 0.7), S_O 0.6 each, 0.9 while starting
  for mode, alpha in enumerate((0.0, 0.4, 0.7)):
    tr, m = top.close(_horizon(mode), False, False, hp)
    np.testing.assert_allclose(tr.reward, -100.0 * (1 + alpha), rtol=1e-6)
    np.testing.assert_allclose(m["s_o_m"], 0.6)
    assert tr.done == 1.0  # 30/50 = 0.6 >= S_O = 0.6
  tr, _ = top.close(_horizon(hierarchy.PPO), True, False, hp)
  assert tr.done == 0.0  # the starting mode asks for 0.9
  tr, _ = top.close(_horizon(hierarchy.PPO, done_count=0.0), False, True, hp)
  assert tr.done == 1.0  # an episode's end ends the Top's return too
  no_mod, hp = _top("ours-no-reward-mod")
  tr, _ = no_mod.close(_horizon(hierarchy.RANDOM), False, False, hp)
  np.testing.assert_allclose(tr.reward, -100.0)  # alpha = 0


def test_top_accumulates_its_horizon():
  top, _ = _top("ours")
  h = _horizon(0, reward=0.0, done_count=0.0, count=0.0)
  for r, s in ((-2.0, 0.0), (-1.0, 1.0), (-0.5, 1.0)):
    h = top.accumulate(h, jp.asarray(r), jp.asarray(s))
  np.testing.assert_allclose((h.reward, h.done_count, h.count), (-3.5, 2.0, 3.0))


def test_forced_start_is_random_with_its_log_prob():
  top, _ = _top("ours")
  params = top.ppo.init(jax.random.PRNGKey(0)).params
  obs = jp.ones(OBS)
  h = top.start(params, obs, jax.random.PRNGKey(1), True)
  assert h.mode == hierarchy.RANDOM
  x = jp.concatenate([obs, jp.asarray(TARGET)])
  logp = jp.stack([top.ppo.log_prob(params, x, jp.asarray(a), None) for a in range(3)])
  np.testing.assert_allclose(jp.exp(logp).sum(), 1.0, rtol=1e-6)
  np.testing.assert_allclose(h.log_prob, logp[hierarchy.RANDOM], rtol=1e-6)
  modes = jax.vmap(lambda k: top.start(params, obs, k, False).mode)(
      jax.random.split(jax.random.PRNGKey(2), 300))
  assert set(np.unique(modes)) == {0, 1, 2}


def _rollout():
  return ppo.Rollout(obs=jax.random.normal(jax.random.PRNGKey(3), (2, 8, OBS + 3)),
                     action=jp.array([[0, 1, 2, 0, 1, 2, 0, 0]] * 2),
                     log_prob=jp.full((2, 8), -1.1), reward=-jp.arange(16.0).reshape(2, 8),
                     done=jp.zeros((2, 8)).at[:, 3].set(1))


def test_loss_modification_weights_td3_down_and_exploration_up():
  rollout, s_e = _rollout(), jp.asarray(0.5)
  (top, hp), (plain, plain_hp) = _top("ours"), _top("ours-no-loss-mod")
  state = top.ppo.init(jax.random.PRNGKey(0))
  got, _ = top.update(state, rollout, s_e, hp)
  weights = jp.where(rollout.action == 0, 0.5, 1.5)
  want, _ = top.ppo.update(state, rollout, None, weights, hp.ppo)
  for a, b in zip(jax.tree.leaves(got.params), jax.tree.leaves(want.params)):
    np.testing.assert_allclose(a, b, rtol=1e-6)
  # Without the loss modification S_E does not matter, and with S_E = 0 both agree.
  a, _ = plain.update(state, rollout, s_e, plain_hp)
  b, _ = plain.update(state, rollout, jp.asarray(0.9), plain_hp)
  c, _ = top.update(state, rollout, jp.asarray(0.0), hp)
  same = lambda x, y: all(np.allclose(p, q) for p, q in zip(jax.tree.leaves(x.params),
                                                              jax.tree.leaves(y.params)))
  assert same(a, b) and same(a, c) and not same(a, got)


# --- the Top's formulas: hand-worked values ----------------------------------------------------

def test_success_ratio_and_top_done_per_mode():
  s_o = jp.array([0.6, 0.6, 0.9])  # Ant Fall
  ratio = top_lib.success_ratio(jp.array(35.0), jp.array(50.0))
  np.testing.assert_allclose(ratio, 0.7)
  assert float(top_lib.top_done(ratio, s_o, hierarchy.TD3)) == 1.0
  assert float(top_lib.top_done(ratio, s_o, hierarchy.RANDOM)) == 0.0
  assert float(top_lib.success_ratio(jp.array(0.0), jp.array(0.0))) == 0.0


def test_reward_modification_penalises_modes_with_larger_alpha():
  alpha = jp.array([0.0, 0.4, 0.7])  # Ant Push
  r = jp.array(-100.0)
  modes = (hierarchy.TD3, hierarchy.PPO, hierarchy.RANDOM)
  got = [float(top_lib.modified_reward(r, alpha, m)) for m in modes]
  np.testing.assert_allclose(got, [-100.0, -140.0, -170.0])
  # Ant Fall's negative alpha makes TD3's reward less negative.
  fall = jp.array([-0.2, -0.2, 0.7])
  np.testing.assert_allclose(top_lib.modified_reward(r, fall, hierarchy.TD3), -80.0)


def test_loss_weights():
  modes = jp.array([0, 1, 2, 0])
  w = top_lib.loss_weights(modes, 0.3)
  np.testing.assert_allclose(w, [0.7, 1.3, 1.3, 0.7], rtol=1e-6)
  w = top_lib.loss_weights(modes, jp.array([0.1, 0.2, 0.3, 0.4]), td3_mode=2)
  np.testing.assert_allclose(w, [1.1, 1.2, 0.7, 1.4], rtol=1e-6)
