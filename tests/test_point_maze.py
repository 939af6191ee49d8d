"""The pure-JAX point robot: walls, pushing blocks, the chasm, and scripted solutions."""

import jax
import jax.numpy as jp
import numpy as np
import pytest

import envs


def _run(env, actions, key=0):
  """Roll a scripted action list through a jitted step; returns the states."""
  step = jax.jit(env.step)
  s = env.reset(jax.random.PRNGKey(key))
  out = [s]
  for a in actions:
    s = step(s, jp.asarray(a, jp.float32))
    out.append(s)
  return out


def _go(direction, n):
  return [direction] * n


UP, DOWN, LEFT, RIGHT = (0, 1), (0, -1), (-1, 0), (1, 0)


@pytest.fixture(scope="module")
def point_envs():
  return {n: envs.make(f"Point{n}", reset_noise_scale=0.0) for n in ("Push", "Fall", "Maze")}


def test_walls_stop_the_point(point_envs):
  env = point_envs["Maze"]  # start cell (1, 1): walls above (y < -2), left (x < -2), below
  for direction, axis, bound in ((DOWN, 1, -2.0), (LEFT, 0, -2.0), (UP, 1, 2.0)):
    s = _run(env, _go(direction, 10))[-1]
    pos = float(s.pipeline_state.pos[axis])
    assert pos == pytest.approx(bound - np.sign(bound) * 0.5, abs=1e-4), direction


def test_push_block_moves_and_target_needs_a_detour(point_envs):
  env = point_envs["Push"]  # block at (0, 4) fills the corridor to the target (0, 9.5)
  # Straight for the target: the point pushes the block down the corridor into the dead end
  # and gets stuck behind it, short of the target.
  s = _run(env, _go(UP, 30))[-1]
  assert float(s.pipeline_state.blocks[0, 1]) > 3.0  # the block moved in y
  assert float(s.metrics["success"]) == 0.0
  # HIRO's solution: go left, down, push the block right (x), come back up and go down.
  plan = _go(LEFT, 4) + _go(UP, 4) + _go(RIGHT, 4) + _go(DOWN, 1) + _go(RIGHT, 1) + \
      _go(UP, 10)
  states = _run(env, plan)
  blocks = np.array([st.pipeline_state.blocks[0] for st in states])
  assert blocks[:, 0].max() > 3.0  # pushed in x
  assert float(states[-1].metrics["success"]) == 1.0
  assert float(states[-1].reward) > -env.success_radius


def test_fall_block_bridges_the_chasm(point_envs):
  env = point_envs["Fall"]
  # Walking straight into the chasm (cell (3, 1)) drops the point to the ground for good.
  s = _run(env, _go(UP, 12))[-1]
  assert float(s.pipeline_state.pos[2]) == pytest.approx(0.5)
  s2 = _run(env, _go(UP, 12) + _go(DOWN, 12))[-1]
  assert float(s2.pipeline_state.pos[2]) == pytest.approx(0.5)
  assert float(s2.pipeline_state.pos[1]) > 6.0 - 1e-4  # the trench walls keep it in
  # Push the block (x 4, y 4) down into the chasm, then walk over it to the target.
  plan = _go(RIGHT, 4) + _go(UP, 6) + _go(UP, 6) + _go(LEFT, 4) + _go(UP, 8)
  states = _run(env, plan)
  blk = states[-1].pipeline_state.blocks[0]
  assert float(blk[1]) == pytest.approx(4.0) and float(blk[2]) == pytest.approx(-2.0)
  assert float(states[-1].pipeline_state.pos[2]) == pytest.approx(2.5)  # never fell
  assert max(float(st.metrics["success"]) for st in states) == 1.0


def test_maze_solution_reaches_target(point_envs):
  env = point_envs["Maze"]
  plan = _go(RIGHT, 8) + _go(UP, 8) + _go(LEFT, 8)
  states = _run(env, plan)
  assert float(states[-1].metrics["success"]) == 1.0
  assert float(states[-1].metrics["distance"]) < 1.0


def test_point_obs_layout_and_reset_noise():
  env = envs.make("PointPush")
  states = jax.vmap(env.reset)(jax.random.split(jax.random.PRNGKey(0), 512))
  obs = np.asarray(states.obs)
  assert obs.shape == (512, env.observation_size) == (512, 7)
  np.testing.assert_allclose(obs[:, :3], np.asarray(states.pipeline_state.pos))
  assert np.abs(obs[:, :2]).max() <= 0.1 and obs[:, :2].std() > 0.04
  assert np.all(obs[:, 2] == 0.5) and np.all(obs[:, 6] == 0.0)
  s = env.step(jax.tree.map(lambda x: x[0], states), jp.array([0.3, 0.0]))
  np.testing.assert_allclose(s.obs[3:6], [0.3, 0.0, 0.0], atol=1e-6)
  assert float(s.obs[6]) == pytest.approx(0.001)
