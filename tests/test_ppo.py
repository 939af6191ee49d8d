"""nonmono_jax.core.ppo: returns, the clipped loss, Train_T's weights, the std schedule,
learning."""

from __future__ import annotations

import math

import jax
import jax.numpy as jp
import numpy as np
import pytest

from nonmono_jax.core import lanes, ppo
from nonmono_jax.core.modes.top import loss_weights

SMALL = (16, 16)


def _rollout(net, params, key, obs, std, reward_fn, n=8):
  """n one-step episodes from the same observation."""
  obs_b = jp.broadcast_to(obs, (n, obs.shape[-1]))
  action, logp = net.act(params, obs_b, key, std)
  return ppo.Rollout(obs=obs_b, action=action, log_prob=logp, reward=reward_fn(action),
                     done=jp.ones((n,), jp.float32))


def _train(net, key, reward_fn, std, iters, obs):
  """Collect-and-update ``iters`` times inside one jitted scan; returns the final state."""
  k_init, k_run = jax.random.split(key)

  def body(state, k):
    batch = _rollout(net, state.params, k, obs, std, reward_fn)
    state, metrics = net.update(state, batch, std, jp.ones(batch.reward.shape),
                                lanes.of(net.config))
    return state, metrics["loss"]

  state, losses = jax.jit(lambda s, ks: jax.lax.scan(body, s, ks))(
      net.init(k_init), jax.random.split(k_run, iters))
  assert np.all(np.isfinite(losses))
  return state


def test_config_validation():
  ppo.PPOConfig()
  for field, bad in [("lr_actor", 0.0), ("lr_critic", -1e-3), ("clip", 0.0), ("clip", 1.0),
                     ("k_epochs", 0), ("gamma", 0.0), ("gamma", 1.5)]:
    with pytest.raises(ValueError, match=field):
      ppo.PPOConfig(**{field: bad})
  ppo.PPOConfig(gamma=1.0)


def test_monte_carlo_returns_reset_at_done():
  rewards = jp.array([1.0, 2.0, 3.0, 4.0])
  dones = jp.array([0.0, 1.0, 0.0, 0.0])
  # backwards, gamma 0.5: G3 = 4, G2 = 3 + 2 = 5, G1 = 2 (done: reset), G0 = 1 + 1 = 2
  raw = ppo.monte_carlo_returns(rewards, dones, 0.5, normalize=False)
  np.testing.assert_allclose(raw, [2.0, 2.0, 5.0, 4.0], rtol=1e-6)
  # mean 3.25, unbiased std 1.5 (torch's .std())
  norm = jax.jit(ppo.monte_carlo_returns, static_argnums=2)(rewards, dones, 0.5)
  np.testing.assert_allclose(norm, [-5 / 6, -5 / 6, 7 / 6, 0.5], rtol=1e-5)
  # bool dones, and a rollout ending mid-episode is not bootstrapped
  raw = ppo.monte_carlo_returns(rewards, dones.astype(bool), 1.0, normalize=False)
  np.testing.assert_allclose(raw, [3.0, 2.0, 7.0, 4.0])


def test_per_sample_loss_matches_numpy_clipped_and_unclipped():
  cfg = ppo.PPOConfig(hidden=SMALL)
  net = ppo.make_ppo(3, 2, cfg, action_scale=jp.array([2.0, 0.5]))
  params = net.init(jax.random.PRNGKey(0)).params
  std = jp.float32(0.4)
  obs = jax.random.normal(jax.random.PRNGKey(1), (3, 3))
  action = jax.random.normal(jax.random.PRNGKey(2), (3, 2))
  rewards = jp.array([2.0, -2.0, 0.0])  # dones everywhere: R = [1, -1, 0] after normalising
  new_logp = net.log_prob(params, obs, action, std)
  # ratios 1.5 (A > 0: clipped at 1.2), 1/1.5 (A < 0: clipped at 0.8), 1.1 (not clipped)
  old_logp = new_logp - jp.log(jp.array([1.5, 1 / 1.5, 1.1]))
  batch = ppo.Rollout(obs=obs, action=action, log_prob=old_logp, reward=rewards,
                      done=jp.ones(3))
  loss, metrics = jax.jit(net.per_sample_loss)(params, batch, std, lanes.of(cfg))

  ret = np.array([1.0, -1.0, 0.0])
  v = np.asarray(net.value(params, obs))
  adv = ret - v
  assert adv[0] > 0 and adv[1] < 0  # so samples 0 and 1 take the clipped branch
  ratio = np.array([1.5, 1 / 1.5, 1.1])
  unclipped, clipped = ratio * adv, np.clip(ratio, 0.8, 1.2) * adv
  surrogate = np.minimum(unclipped, clipped)
  np.testing.assert_allclose(surrogate[:2], clipped[:2])
  assert not np.allclose(surrogate[:2], unclipped[:2])
  np.testing.assert_allclose(surrogate[2], unclipped[2])
  sigma = 0.4 * np.array([2.0, 0.5])
  ent = np.sum(0.5 * np.log(2 * np.pi * np.e * sigma**2))
  expected = -surrogate + 0.5 * (v - ret) ** 2 - 0.01 * ent
  np.testing.assert_allclose(loss, expected, rtol=1e-5, atol=1e-6)
  np.testing.assert_allclose(metrics["clip_fraction"], 2 / 3, rtol=1e-6)
  np.testing.assert_allclose(metrics["entropy"], ent, rtol=1e-5)

  # clipped samples pass no gradient to the actor (the Gaussian entropy is parameter-free)
  def actor_loss(actor_params, i):
    p = {"actor": actor_params, "critic": params["critic"]}
    return net.per_sample_loss(p, batch, std, lanes.of(cfg))[0][i]

  for i, zero in [(0, True), (1, True), (2, False)]:
    g = jax.grad(actor_loss)(params["actor"], i)
    norm = sum(float(jp.abs(x).sum()) for x in jax.tree.leaves(g))
    assert (norm == 0.0) == zero, (i, norm)


def test_discrete_log_prob_and_entropy():
  net = ppo.make_ppo(4, 3, ppo.PPOConfig(hidden=SMALL, discrete=True))
  params = net.init(jax.random.PRNGKey(0)).params
  obs = jax.random.normal(jax.random.PRNGKey(1), (5, 4))
  a, logp = net.act(params, obs, jax.random.PRNGKey(2), 0.0)
  assert a.shape == (5,) and a.dtype in (jp.int32, jp.int64)
  np.testing.assert_allclose(logp, net.log_prob(params, obs, a, 0.0), rtol=1e-6)
  probs = np.exp([net.log_prob(params, obs, jp.full((5,), k), 0.0) for k in range(3)])
  np.testing.assert_allclose(probs.sum(0), 1.0, rtol=1e-5)
  np.testing.assert_allclose(net.entropy(params, obs, 0.0), -(probs * np.log(probs)).sum(0),
                             rtol=1e-5)
  assert net.mode(params, obs).shape == (5,)


@pytest.mark.parametrize("head", ["linear", "tanh"])
def test_gaussian_log_prob_is_a_normal_density(head):
  """The paper's head: std in goal units (0.5 here), whatever the range; "tanh": std x range."""
  scale = np.array([3.0, 1.0])
  net = ppo.make_ppo(2, 2, ppo.PPOConfig(hidden=SMALL, mean_head=head), action_scale=scale)
  params = net.init(jax.random.PRNGKey(0)).params
  obs = jp.ones((2,))
  mean = np.asarray(net.mode(params, obs))
  if head == "tanh":
    assert np.all(np.abs(mean) <= scale)
  action, logp = net.act(params, obs, jax.random.PRNGKey(1), 0.5)
  sigma = 0.5 * (scale if head == "tanh" else np.ones(2))
  h = np.sum(0.5 * math.log(2 * math.pi * math.e) + np.log(sigma))
  np.testing.assert_allclose(net.entropy(params, obs, 0.5), h, rtol=1e-5)
  ref = np.sum(-0.5 * ((action - mean) / sigma) ** 2 - np.log(sigma) - 0.5 * math.log(2 * np.pi))
  np.testing.assert_allclose(logp, ref, rtol=1e-5)


def test_gaussian_std_schedule():
  cfg = ppo.PPOConfig()
  std = jax.jit(ppo.gaussian_std, static_argnums=1)
  for step, want in [(0, 0.6), (249_999, 0.6), (250_000, 0.55), (500_000, 0.5),
                     (2_250_000, 0.15), (2_500_000, 0.1), (10_000_000, 0.1)]:
    np.testing.assert_allclose(std(jp.int32(step), cfg), want, rtol=1e-6)


def test_discrete_bandit_learns_action_2():
  cfg = ppo.PPOConfig(hidden=SMALL, discrete=True, lr_actor=3e-3, lr_critic=3e-3)
  net = ppo.make_ppo(2, 3, cfg)
  obs = jp.ones((2,))
  state = _train(net, jax.random.PRNGKey(0), lambda a: (a == 2).astype(jp.float32), 0.0,
                 iters=60, obs=obs)
  p2 = float(jp.exp(net.log_prob(state.params, obs, jp.int32(2), 0.0)))
  assert p2 > 0.9, p2
  assert int(net.mode(state.params, obs)) == 2


def test_gaussian_mean_moves_to_optimum():
  cfg = ppo.PPOConfig(hidden=SMALL, lr_actor=1e-3, lr_critic=3e-3)
  net = ppo.make_ppo(2, 1, cfg)
  key = jax.random.PRNGKey(0)
  obs = jp.zeros((2,))  # zero biases at init: the mean starts at exactly 0
  assert float(net.mode(net.init(jax.random.split(key)[0]).params, obs)[0]) == 0.0
  state = _train(net, key, lambda a: -((a[:, 0] - 0.5) ** 2), jp.float32(0.2), iters=150,
                 obs=obs)
  after = float(net.mode(state.params, obs)[0])
  assert abs(after - 0.5) < 0.15, after  # seeds 0-5 land within 0.07


def _leaves_equal(a, b):
  return all(np.array_equal(x, y) for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b)))


def test_loss_weights_scale_the_gradient():
  cfg = ppo.PPOConfig(hidden=SMALL, discrete=True, k_epochs=1)
  net = ppo.make_ppo(2, 3, cfg)
  state = net.init(jax.random.PRNGKey(0))
  batch = _rollout(net, state.params, jax.random.PRNGKey(1), jp.ones((2,)), 0.0,
                   lambda a: (a == 2).astype(jp.float32))
  batch = batch.replace(obs=jax.random.normal(jax.random.PRNGKey(2), batch.obs.shape))
  ones = jp.ones((8,))

  hp = lanes.of(cfg)
  g1, _ = jax.grad(net.loss, has_aux=True)(state.params, batch, 0.0, ones, hp)
  g2, _ = jax.grad(net.loss, has_aux=True)(state.params, batch, 0.0, 2 * ones, hp)
  for x, y in zip(jax.tree.leaves(g1), jax.tree.leaves(g2)):
    np.testing.assert_allclose(y, 2 * x, rtol=1e-5, atol=1e-8)

  update = jax.jit(lambda state, batch, std, weights: net.update(state, batch, std, weights, hp))
  s_ones, m = update(state, batch, 0.0, ones)
  assert set(m) == {"loss", "policy_loss", "value_loss", "entropy", "approx_kl",
                    "clip_fraction"}
  # Adam ignores a uniform scale, so double the weight of some samples only
  weights = loss_weights(jp.arange(8) % 3, 0.5)
  s_w, _ = update(state, batch, 0.0, weights)
  assert not _leaves_equal(s_w.params, s_ones.params)
  s_zero, _ = update(state, batch, 0.0, jp.zeros((8,)))
  assert _leaves_equal(s_zero.params, state.params)


def test_update_vmaps_over_seeds():
  cfg = ppo.PPOConfig(hidden=SMALL)
  net = ppo.make_ppo(3, 2, cfg, action_scale=jp.array([1.0, 4.0]))
  states = jax.vmap(net.init)(jax.random.split(jax.random.PRNGKey(0), 2))

  def step(state, key, std):
    batch = _rollout(net, state.params, key, jp.ones((3,)), std,
                     lambda a: -jp.sum(a**2, axis=-1), n=3)
    return net.update(state, batch, std, jp.ones(batch.reward.shape), lanes.of(cfg))

  std = ppo.gaussian_std(jp.int32(300_000), cfg)
  new, metrics = jax.jit(jax.vmap(step, in_axes=(0, 0, None)))(
      states, jax.random.split(jax.random.PRNGKey(1), 2), std)
  assert metrics["loss"].shape == (2,) and np.all(np.isfinite(metrics["loss"]))
  for leaf in jax.tree.leaves(new.params):
    assert leaf.shape[0] == 2 and not np.allclose(leaf[0], leaf[1])
  assert not _leaves_equal(new.params, states.params)


def test_monte_carlo_returns_per_env_rows():
  """(envs, N) rollouts: returns run along each row, normalised over all of them."""
  rewards = jp.array([[1.0, 2.0, 3.0], [0.0, -1.0, 4.0]])
  dones = jp.array([[0, 1, 0], [0, 0, 0]])
  raw = ppo.monte_carlo_returns(rewards, dones, 0.5, normalize=False)
  for row in range(2):
    np.testing.assert_allclose(
        raw[row], ppo.monte_carlo_returns(rewards[row], dones[row], 0.5, normalize=False))
  np.testing.assert_allclose(raw[0], [1 + 0.5 * 2, 2, 3])
  norm = ppo.monte_carlo_returns(rewards, dones, 0.5)
  np.testing.assert_allclose(norm, (raw - raw.mean()) / (raw.std(ddof=1) + 1e-7), rtol=1e-5)


def test_zero_scale_dimension_is_fixed_and_finite():
  """A goal range of 0 in a dimension (z for the point robot) pins it at 0, with finite logp."""
  learner = ppo.make_ppo(5, 3, ppo.PPOConfig(hidden=(8,)), action_scale=jp.array([4.0, 4.0, 0.0]))
  params = learner.init(jax.random.PRNGKey(0)).params
  obs = jp.ones(5)
  a, logp = learner.act(params, obs, jax.random.PRNGKey(1), 0.6)
  assert a[2] == 0.0 and np.isfinite(logp)
  two_d = 2 * (0.5 * math.log(2 * math.pi * math.e) + math.log(0.6))  # goal units
  np.testing.assert_allclose(learner.entropy(params, obs, 0.6), two_d, rtol=1e-6)


@pytest.mark.parametrize("head,expected", [("linear", 7.0), ("tanh", 3.0 * np.tanh(7.0))])
def test_gaussian_mean_head(head, expected):
  """The paper's Middle PPO mean is linear (unbounded, the caller clips the goal)."""
  net = ppo.make_ppo(2, 2, ppo.PPOConfig(hidden=SMALL, mean_head=head),
                     action_scale=jp.array([3.0, 3.0]))
  params = net.init(jax.random.PRNGKey(0)).params
  layers = params["actor"]["params"]
  last = sorted(layers)[-1]
  layers[last] = {"kernel": jp.zeros_like(layers[last]["kernel"]),
                  "bias": jp.full_like(layers[last]["bias"], 7.0)}
  np.testing.assert_allclose(net.mode(params, jp.ones((2,))), [expected] * 2, rtol=1e-6)
