"""Every registered env: names, bad input, observation layout, reset noise, reward, success,
the episode clock, and jit + vmap of reset and step (the MJX ant ones compile once per session).
"""

import jax
import jax.numpy as jp
import mujoco
import numpy as np
import pytest

import envs
from conftest import SMOKE_BATCH, SMOKE_EPISODE

ANT = [n for n in envs.NAMES if n.startswith("Ant")]
POINT = [n for n in envs.NAMES if n.startswith("Point")]


def test_registry_names():
  assert set(envs.NAMES) == {"AntPush", "AntFall", "AntMaze", "PointPush", "PointFall",
                             "PointMaze"}


def test_unknown_name_lists_valid_ones():
  with pytest.raises(ValueError) as e:
    envs.make("AntPsuh")
  for n in envs.NAMES:
    assert n in str(e.value)


def test_unknown_override_lists_valid_ones():
  with pytest.raises(ValueError) as e:
    envs.make("AntPush", episode_lenght=500)
  assert "episode_lenght" in str(e.value) and "episode_length" in str(e.value)
  with pytest.raises(ValueError, match="max_step"):
    envs.make("PointPush", optimised=False)  # an ant-only option
  with pytest.raises(ValueError, match="episode_length must be positive"):
    envs.make("PointPush", episode_length=-5)
  with pytest.raises(ValueError, match="solver_iterations"):
    envs.make("AntFall", solver_iterations=0)
  with pytest.raises(ValueError, match="max_geom_pairs"):
    envs.make("AntFall", max_geom_pairs=-3)


@pytest.mark.parametrize("name", envs.NAMES)
def test_env_exposes_task(name):
  env = envs.make(name, episode_length=500)
  assert env.episode_length == 500
  assert isinstance(env.mj_model, mujoco.MjModel)
  target = np.asarray(env.target)
  if name.startswith("Ant"):
    expected = {"AntPush": (0, 19, 0.5), "AntFall": (0, 27, 4.5), "AntMaze": (0, 16, 0.5)}[name]
    np.testing.assert_allclose(target, expected)
    assert env.success_radius == 5.0 and env.observation_size == 30 and env.action_size == 8
  else:
    assert env.success_radius == 2.5 and env.observation_size == 7 and env.action_size == 2
  assert isinstance(env, envs.MazeEnv)  # the agent's env contract (envs/base.py)


def test_unroll_is_the_step_loop():
  """envs.rollout.unroll: the policy sees each state and its carry; observe gets (s, s')."""
  from envs import rollout
  env = envs.make("PointMaze", episode_length=10)
  s0 = env.reset(jax.random.PRNGKey(0))
  act = lambda n, s, t: jp.array([1.0, 0.0]) * (t % 2)
  observe = lambda n, s, s2, t: (n + 1, (s.obs[0], s2.obs[0], n))
  (last, n), (x, x2, count) = jax.jit(lambda s: rollout.unroll(env, s, act, jp.arange(6), 0,
                                                               observe))(s0)
  s = s0
  for t in range(6):
    s = env.step(s, jp.array([1.0, 0.0]) * (t % 2))
  np.testing.assert_allclose(last.obs, s.obs, rtol=1e-6)
  np.testing.assert_array_equal(count, np.arange(6))
  np.testing.assert_allclose(x[1:], x2[:-1])
  assert int(n) == 6 and float(x2[-1] - x[0]) > 0


@pytest.mark.parametrize("name", ["AntPush", "AntFall", "PointFall"])
def test_reward_and_success_by_distance(name):
  env = envs.make(name)
  target = np.asarray(env.target)
  for offset, success in (((0, 0, 0), 1.0), ((3.0, 0, 0), float(env.success_radius >= 3)),
                          ((0, 4.9, 0), float(env.success_radius >= 4.9)), ((0, 0, 6.0), 0.0)):
    m = env.task_metrics(jp.asarray(target + np.array(offset), jp.float32))
    assert float(m["reward_task"]) == pytest.approx(-np.linalg.norm(offset), abs=1e-5)
    assert float(m["success"]) == success, offset


def _rollout(compiled, steps, key=0):
  env = compiled.env
  s = compiled.reset(jax.random.split(jax.random.PRNGKey(key), SMOKE_BATCH))
  lim = env.action_limit
  states = [s]
  for t in range(steps):
    a = jax.random.uniform(jax.random.PRNGKey(100 + t), (SMOKE_BATCH, env.action_size),
                           minval=-lim, maxval=lim)
    s = compiled.step(s, a)
    states.append(s)
  return states


def _check_clock_reward_and_obs(env, states):
  for t, s in enumerate(states):
    np.testing.assert_array_equal(np.asarray(s.steps), t)
    np.testing.assert_allclose(np.asarray(s.obs[:, -1]), t * 0.001, rtol=1e-6)
    trunc = float(t >= SMOKE_EPISODE)
    np.testing.assert_array_equal(np.asarray(s.truncation), trunc)
    np.testing.assert_array_equal(np.asarray(s.done), trunc)  # never terminates otherwise
    xyz = np.asarray(s.obs[:, :3])
    dist = np.linalg.norm(xyz - np.asarray(env.target), axis=-1)
    np.testing.assert_allclose(np.asarray(s.reward), -dist, rtol=1e-5)
    np.testing.assert_allclose(np.asarray(s.metrics["success"]), dist <= env.success_radius)
    np.testing.assert_array_equal(np.asarray(s.success), np.asarray(s.metrics["success"]))
    np.testing.assert_allclose(np.asarray(s.distance), dist, rtol=1e-5)
    assert np.all(np.isfinite(np.asarray(s.obs)))


@pytest.mark.parametrize("name", POINT)
def test_point_jit_vmap_smoke(compiled_env, name):
  c = compiled_env(name)
  states = _rollout(c, SMOKE_EPISODE + 1)
  _check_clock_reward_and_obs(c.env, states)
  # Seeds differ.
  assert not np.allclose(states[0].obs[0], states[0].obs[1])


# Every ant task on the default physics (MuJoCo C on a CPU); the two the MJX geometry tests
# below compile anyway, also on MJX.
ANT_PHYSICS = [(n, "c") for n in ANT] + [("AntPush", "mjx"), ("AntFall", "mjx")]


def _slow_if_mjx(params):
  return [pytest.param(*p, marks=pytest.mark.slow) if p[1] == "mjx" else p for p in params]


@pytest.mark.parametrize("name,physics", _slow_if_mjx(ANT_PHYSICS))
def test_ant_jit_vmap_smoke(compiled_env, name, physics):
  c = compiled_env(name, physics)
  assert c.env.physics == physics
  states = _rollout(c, SMOKE_EPISODE + 1)
  _check_clock_reward_and_obs(c.env, states)
  for s in states:
    qpos, qvel = np.asarray(s.pipeline_state.qpos), np.asarray(s.pipeline_state.qvel)
    np.testing.assert_allclose(np.asarray(s.obs[:, :15]), qpos[:, :15])
    np.testing.assert_allclose(np.asarray(s.obs[:, 15:29]), qvel[:, :14])
  assert not np.allclose(states[0].obs[0], states[0].obs[1])


@pytest.mark.parametrize("name,physics", _slow_if_mjx(ANT_PHYSICS))
def test_ant_reset_noise(compiled_env, name, physics):
  """HIRO: qpos0 + U(-0.1, 0.1) and qvel 0.1 N(0, 1) on the ant; blocks exactly at rest."""
  c = compiled_env(name, physics)
  qpos0 = np.asarray(c.env.mj_model.qpos0)
  qs, vs = [], []
  for k in range(8):
    s = c.reset(jax.random.split(jax.random.PRNGKey(k), SMOKE_BATCH))
    qs.append(np.asarray(s.pipeline_state.qpos))
    vs.append(np.asarray(s.pipeline_state.qvel))
  q, v = np.concatenate(qs), np.concatenate(vs)
  dq = q - qpos0
  not_quat = np.r_[0:3, 7:15]  # the noisy quaternion is renormalised, as MuJoCo does
  assert np.abs(dq[:, not_quat]).max() <= 0.1 + 1e-6 and dq[:, not_quat].std() > 0.03
  np.testing.assert_allclose(np.linalg.norm(q[:, 3:7], axis=1), 1.0, atol=1e-5)
  assert np.abs(dq[:, 3:7]).max() < 0.2 and dq[:, 4:7].std() > 0.02
  assert v[:, :14].std() == pytest.approx(0.1, rel=0.3)
  np.testing.assert_array_equal(dq[:, 15:], 0.0)
  np.testing.assert_array_equal(v[:, 14:], 0.0)


def _push_block(c, state, force, steps):
  """Step the compiled env with zero torques and a force on the block's centre."""
  m = c.env.mj_model
  block = [m.body(b).name for b in range(m.nbody) if m.body(b).name.startswith("block")][0]
  body = m.body(block).id
  xfrc = np.zeros((SMOKE_BATCH, m.nbody, 6), np.float32)
  xfrc[:, body, :3] = force
  zero = jp.zeros((SMOKE_BATCH, 8))
  for _ in range(steps):
    ps = state.pipeline_state.replace(xfrc_applied=jp.asarray(xfrc))
    state = c.step(state.replace(pipeline_state=ps), zero)
  return state


@pytest.mark.slow
def test_mjx_push_block_slides_when_pushed(compiled_env):
  """In the MJX program too (contact caps included), the Push block slides into (2, 3)."""
  c = compiled_env("AntPush", "mjx")
  s = c.reset(jax.random.split(jax.random.PRNGKey(0), SMOKE_BATCH))
  s = _push_block(c, s, (20.0, 0.0, 0.0), 30)  # 3 s
  x = np.asarray(c.env.block_positions(jax.tree.map(lambda v: v[0], s)))[0]
  assert 7.0 < x[0] < 8.5 and abs(x[1] - 8.0) < 0.2


@pytest.mark.slow
def test_mjx_fall_block_drops_into_the_chasm(compiled_env):
  c = compiled_env("AntFall", "mjx")
  s = c.reset(jax.random.split(jax.random.PRNGKey(0), SMOKE_BATCH))
  s = _push_block(c, s, (0.0, 0.5, 0.0), 30)  # a steady push, 3 s
  s = _push_block(c, s, (0.0, 0.0, 0.0), 30)  # let go, 3 s
  centre = np.asarray(c.env.block_positions(jax.tree.map(lambda v: v[0], s)))[0]
  np.testing.assert_allclose(centre, [8.0, 16.0, 2.0], atol=0.15)  # in the chasm, a bridge
