"""TD3 and the replay buffer: hand-worked targets, invariants, a toy problem, real branches."""

import dataclasses
import functools

import jax
import jax.numpy as jp
import numpy as np
import pytest

from nonmono_jax.core import buffers, networks, lanes, td3

SMALL = td3.TD3Config(hidden=(32, 32), batch_size=64)


def _batch(key, n=64, obs=3, ctx=2, act=2):
  ks = jax.random.split(key, 6)
  return td3.Transition(
      obs=jax.random.normal(ks[0], (n, obs)), context=jax.random.normal(ks[1], (n, ctx)),
      action=jax.random.uniform(ks[2], (n, act), minval=-1, maxval=1),
      reward=jax.random.normal(ks[3], (n,)), next_obs=jax.random.normal(ks[4], (n, obs)),
      next_context=jax.random.normal(ks[5], (n, ctx)), done=jp.zeros((n,)))


def test_td_target_by_hand():
  y = td3.td_target(jp.array([1.0, -2.0]), jp.array([0.0, 1.0]), jp.array([3.0, 5.0]),
                    jp.array([4.0, 1.0]), 0.9)
  np.testing.assert_allclose(y, [1.0 + 0.9 * 3.0, -2.0])


def test_polyak_by_hand():
  out = td3.polyak({"w": jp.array([1.0, 2.0])}, {"w": jp.array([3.0, 6.0])}, 0.25)
  np.testing.assert_allclose(out["w"], [1.5, 3.0])


def test_critic_loss_matches_manual_target():
  for smoothing in (False, True):
    cfg = dataclasses.replace(SMALL, target_smoothing=smoothing)
    agent = td3.make_td3(3, 2, 2, 1.0, cfg)
    state = agent.init(jax.random.PRNGKey(0))
    p = state.params
    batch = _batch(jax.random.PRNGKey(1))
    key = jax.random.PRNGKey(2)
    loss, _ = agent.critic_loss(p.critic, p, batch, key, lanes.of(cfg))
    a_next = agent.act(td3.TD3Params(p.target_actor, p.critic, p.target_actor, p.target_critic),
                       batch.next_obs, batch.next_context)
    if smoothing:
      noise = jp.clip(0.2 * jax.random.normal(key, a_next.shape), -0.5, 0.5)
      a_next = jp.clip(a_next + noise, -1, 1)
    qn = agent.q_values(p.target_critic, batch.next_obs, batch.next_context, a_next)
    y = batch.reward + 0.99 * jp.minimum(qn[0], qn[1])
    q = agent.q_values(p.critic, batch.obs, batch.context, batch.action)
    manual = jp.mean((q[0] - y) ** 2) + jp.mean((q[1] - y) ** 2)
    np.testing.assert_allclose(loss, manual, rtol=1e-5)
    # Without smoothing the target does not depend on the key.
    loss2, _ = agent.critic_loss(p.critic, p, batch, jax.random.PRNGKey(3), lanes.of(cfg))
    assert (loss2 == loss) == (not smoothing)


def test_delayed_actor_and_polyak_targets():
  agent = td3.make_td3(3, 2, 2, 1.0, SMALL)
  s0 = agent.init(jax.random.PRNGKey(0))
  batch = _batch(jax.random.PRNGKey(1))
  hp = lanes.of(SMALL)
  s1, m = agent.update(s0, batch, jax.random.PRNGKey(2), False, hp)
  same = jax.tree.map(lambda a, b: bool(jp.all(a == b)), s0.params.actor, s1.params.actor)
  assert all(jax.tree.leaves(same)) and float(m["actor_loss"]) == 0.0
  assert all(jax.tree.leaves(jax.tree.map(lambda a, b: bool(jp.all(a == b)),
                                          s0.params.target_critic, s1.params.target_critic)))
  changed = jax.tree.map(lambda a, b: bool(jp.any(a != b)), s0.params.critic, s1.params.critic)
  assert all(jax.tree.leaves(changed))
  s2, _ = agent.update(s1, batch, jax.random.PRNGKey(3), True, hp)
  expect = td3.polyak(s1.params.target_actor, s2.params.actor, SMALL.tau)
  for a, b in zip(jax.tree.leaves(expect), jax.tree.leaves(s2.params.target_actor)):
    np.testing.assert_allclose(a, b, rtol=1e-6)
  expect = td3.polyak(s1.params.target_critic, s2.params.critic, SMALL.tau)
  for a, b in zip(jax.tree.leaves(expect), jax.tree.leaves(s2.params.target_critic)):
    np.testing.assert_allclose(a, b, rtol=1e-6)


def test_actor_gate_stays_a_branch_under_vmap():
  """The delayed-actor gate is unbatched, so vmap over seeds keeps a real cond."""
  agent = td3.make_td3(3, 2, 2, 1.0, SMALL)
  states = jax.vmap(agent.init)(jax.random.split(jax.random.PRNGKey(0), 4))
  batch = jax.vmap(_batch)(jax.random.split(jax.random.PRNGKey(1), 4))
  keys = jax.random.split(jax.random.PRNGKey(2), 4)
  upd = jax.vmap(functools.partial(agent.update, hp=lanes.of(SMALL)), in_axes=(0, 0, 0, None))
  jaxpr = str(jax.make_jaxpr(upd)(states, batch, keys, jp.array(True)))
  assert "cond[" in jaxpr
  out, _ = jax.jit(upd)(states, batch, keys, jp.array(True))
  w = jax.tree.leaves(out.params.actor)[0]
  assert not np.allclose(w[0], w[1])  # seeds differ


def test_td3_solves_a_contextual_bandit():
  """r = -(a - c)^2, one step: Q approaches the true value and pi(c) approaches c."""
  cfg = dataclasses.replace(SMALL, lr_actor=1e-3, policy_delay=2)
  agent = td3.make_td3(1, 1, 1, 1.0, cfg)

  def batch(key):
    k1, k2 = jax.random.split(key)
    c = jax.random.uniform(k1, (128, 1), minval=-0.8, maxval=0.8)
    a = jax.random.uniform(k2, (128, 1), minval=-1, maxval=1)
    z = jp.zeros((128, 1))
    return td3.Transition(obs=z, context=c, action=a, reward=-((a - c)[:, 0] ** 2),
                          next_obs=z, next_context=c, done=jp.ones((128,)))

  def body(state, i):
    k = jax.random.PRNGKey(i)
    state, m = agent.update(state, batch(k), jax.random.fold_in(k, 1), i % 2 == 0,
                            lanes.of(cfg))
    return state, m["critic_loss"]

  state, losses = jax.jit(lambda s: jax.lax.scan(body, s, jp.arange(1500)))(
      agent.init(jax.random.PRNGKey(0)))
  c = jp.linspace(-0.6, 0.6, 7)[:, None]
  z = jp.zeros_like(c)
  a = agent.act(state.params, z, c)
  np.testing.assert_allclose(a, c, atol=0.1)
  q = agent.q_values(state.params.critic, z, c, c)
  np.testing.assert_allclose(q, 0.0, atol=0.05)  # the best action is worth 0
  assert float(losses[-100:].mean()) < 0.1 * float(losses[:100].mean())


def test_explore_clips_to_action_scale():
  agent = td3.make_td3(3, 2, 2, 30.0, SMALL)
  s = agent.init(jax.random.PRNGKey(0))
  a = agent.explore(s.params, jp.zeros((1000, 3)), jp.zeros((1000, 2)), jax.random.PRNGKey(1),
                    100.0)
  assert float(jp.abs(a).max()) == 30.0 and float(a.std()) > 10


def test_config_validation_names_the_field():
  for field, bad in (("lr_actor", 0.0), ("tau", 2.0), ("batch_size", 0), ("noise_clip", -1.0)):
    with pytest.raises(ValueError, match=field):
      td3.TD3Config(**{field: bad})


def test_replay_buffer_ring_and_sampling():
  buf = buffers.init({"x": jp.zeros(2), "r": jp.zeros(())}, capacity=5)
  assert buf.capacity == 5 and int(buf.size) == 0
  add = jax.jit(buffers.add)
  for i in range(3):
    buf = add(buf, {"x": jp.full((2, 2), i, jp.float32), "r": jp.full((2,), i, jp.float32)})
  # 6 written into 5 slots: the oldest (first 0) is overwritten by the last 2.
  np.testing.assert_array_equal(buf.data["r"], [2, 0, 1, 1, 2])
  assert int(buf.size) == 5 and int(buf.position) == 1
  batch = buffers.sample(buf, jax.random.PRNGKey(0), 1000)
  assert set(np.unique(batch["r"])) == {0.0, 1.0, 2.0}
  np.testing.assert_array_equal(batch["x"][:, 0], batch["r"])
  part = buffers.add(buffers.init({"r": jp.zeros(())}, 10), {"r": jp.ones((3,))})
  assert set(np.unique(buffers.sample(part, jax.random.PRNGKey(1), 200)["r"])) == {1.0}
  with pytest.raises(ValueError, match="capacity"):
    buffers.init({"r": jp.zeros(())}, 0)


def test_replay_buffer_vmaps_over_seeds():
  bufs = jax.vmap(lambda _: buffers.init({"r": jp.zeros(())}, 4))(jp.arange(3))
  bufs = jax.vmap(buffers.add)(bufs, {"r": jp.arange(6.0).reshape(3, 2)})
  np.testing.assert_array_equal(bufs.data["r"][:, :2], [[0, 1], [2, 3], [4, 5]])
  np.testing.assert_array_equal(bufs.size, [2, 2, 2])


def test_mlp_concatenates_inputs():
  net = networks.make_mlp(5, (8,), 3)
  p = net.init(jax.random.PRNGKey(0))
  x = jax.random.normal(jax.random.PRNGKey(1), (4, 5))
  np.testing.assert_allclose(net.apply(p, x[:, :2], x[:, 2:]), net.apply(p, x), rtol=1e-6)
  assert net.apply(p, x).shape == (4, 3)
