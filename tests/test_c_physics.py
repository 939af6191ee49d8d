"""The ant on MuJoCo's C engine inside jit (``envs.c_physics``): the state that crosses to the
host is exact, a simulation does not depend on the batch it is stepped in, instability is
flagged, and the motion is MJX's (the accelerator path) within stated tolerances."""

from types import SimpleNamespace

import jax
import jax.numpy as jp
import mujoco
import numpy as np
import pytest

import envs
from envs import c_physics, rollout
from nonmono_jax.host import run

STEPS = 20


@pytest.fixture(scope="module")
def push():
  return envs.make("AntPush", physics="c")


def _rows(state):
  """The carried float64 rows of a (batched) CState."""
  bits = np.ascontiguousarray(np.asarray(state.pipeline_state.bits))
  return bits.view(np.float64).reshape(bits.shape[0], -1)


def _controls(n, steps, seed=0):
  return np.random.default_rng(seed).uniform(-30, 30, (n, steps, 8)).astype(np.float32)


def _run(env, states, controls):
  """The env stepped through ``controls`` (B, T, 8) in one jitted scan (a callback per step)."""
  def one(s, a):
    return rollout.unroll(env, s, lambda c, s, x: x, a)[0][0]
  return jax.jit(jax.vmap(one))(states, jp.asarray(controls))


def _mujoco(model, row, controls):
  """The same in plain MuJoCo: one MjData from ``row``, ``mj_step`` x 5 per control."""
  d = mujoco.MjData(model)
  full = np.zeros(mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_INTEGRATION))
  full[:row.size] = row
  mujoco.mj_setState(model, d, full, mujoco.mjtState.mjSTATE_INTEGRATION)
  for c in controls:
    d.ctrl[:] = c
    for _ in range(5):
      mujoco.mj_step(model, d)
  out = np.zeros_like(full)
  mujoco.mj_getState(model, d, out, mujoco.mjtState.mjSTATE_INTEGRATION)
  return out[:row.size]


def test_reset_rows_hold_the_reset_state(push):
  s = jax.jit(jax.vmap(push.reset))(jax.random.split(jax.random.PRNGKey(0), 3))
  rows, nq, nv = _rows(s), push.mj_model.nq, push.mj_model.nv
  assert rows.shape == (3, c_physics.CPhysics(push.mj_model, 5).width)
  np.testing.assert_array_equal(rows[:, 1:1 + nq], np.asarray(s.pipeline_state.qpos, np.float64))
  np.testing.assert_array_equal(rows[:, 1 + nq:1 + nq + nv], np.asarray(s.pipeline_state.qvel))
  np.testing.assert_array_equal(rows[:, 0], 0.0)  # time
  np.testing.assert_array_equal(rows[:, 1 + nq + nv:], 0.0)  # no warm start yet
  np.testing.assert_allclose(np.linalg.norm(rows[:, 4:8], axis=1), 1.0, rtol=1e-6)
  np.testing.assert_array_equal(np.asarray(s.obs[:, :15]),
                                np.asarray(s.pipeline_state.qpos[:, :15]))


def test_state_crossing_to_the_host_is_exact(push):
  """20 env steps with the state round-tripping through JAX each step equal 100 mj_step of one
  MjData bit for bit: the rows carry everything a step changes (the solver's warm start
  included; dropping it changes the result, so the test can tell)."""
  s0 = jax.jit(jax.vmap(push.reset))(jax.random.split(jax.random.PRNGKey(1), 2))
  controls = _controls(2, STEPS)
  s = _run(push, s0, controls)
  rows0, rows = _rows(s0), _rows(s)
  for i in range(2):
    np.testing.assert_array_equal(rows[i], _mujoco(push.mj_model, rows0[i], controls[i]))
  np.testing.assert_array_equal(np.asarray(s.pipeline_state.qpos), rows[:, 1:18].astype(np.float32))
  # Without the warm start carried over, the same steps end elsewhere.
  m = push.mj_model
  row = rows0[0].copy()
  for c in controls[0]:
    row[-m.nv:] = 0.0
    row = _mujoco(m, row, c[None])
  assert not np.array_equal(row, rows[0])


def test_a_simulation_does_not_depend_on_its_batch(push):
  """Seeds x envs are stepped together; each one's result is what it would be alone."""
  s0 = jax.jit(jax.vmap(push.reset))(jax.random.split(jax.random.PRNGKey(2), 5))
  controls = _controls(5, 5, seed=1)
  together = _rows(_run(push, s0, controls))
  alone = _rows(_run(push, jax.tree.map(lambda x: x[3:4], s0), controls[3:4]))
  np.testing.assert_array_equal(together[3], alone[0])


def test_unstable_simulation_is_flagged(push, tmp_path, monkeypatch):
  monkeypatch.chdir(tmp_path)  # MuJoCo logs its warning to MUJOCO_LOG.TXT there
  s0 = jax.jit(jax.vmap(push.reset))(jax.random.split(jax.random.PRNGKey(3), 2))
  nq = push.mj_model.nq
  rows = _rows(s0).copy()
  rows[1, 1 + nq + 6] = 1e12  # a joint spinning far beyond MuJoCo's limit
  bits = jp.asarray(rows.view(np.uint32).reshape(2, -1))
  s0 = s0.replace(pipeline_state=s0.pipeline_state.replace(bits=bits))
  s = jax.jit(jax.vmap(push.step))(s0, jp.zeros((2, 8)))
  np.testing.assert_array_equal(np.asarray(jax.vmap(push.unstable)(s)), [0.0, 1.0])
  # The trainer's check names the lane and where (run.first_unstable).
  chunk = lambda training, evaluation: SimpleNamespace(
      unstable_steps=np.array(training), unstable_evaluation=np.array(evaluation))
  assert run.first_unstable(chunk([0.0, 0.0, 3.0], [0.0, 0.0, 0.0])) == (2, "training")
  assert run.first_unstable(chunk([0.0, 0.0], [0.0, 1.0])) == (1, "evaluation")
  assert run.first_unstable(chunk([0.0, 0.0], [0.0, 0.0])) is None


def test_physics_option_is_checked_and_resolved():
  from envs import c_physics as c_lib, mjx_physics
  from nonmono_jax.host import plan

  with pytest.raises(ValueError, match="physics must be one of c, mjx"):
    envs.make("AntPush", physics="gpu")
  with pytest.raises(ValueError, match="plan resolves auto"):  # the plan alone resolves it
    envs.make("AntPush", physics="auto")
  assert plan.run_physics("AntFall", "auto") == plan.run_physics("AntFall", None) == "c"  # CPU
  with pytest.raises(ValueError, match="--physics must be one of auto, c, mjx"):
    plan.run_physics("AntPush", "gpu")
  c = envs.make("AntFall")
  assert c.physics == "c" and isinstance(c.engine, c_lib.CPhysics)  # no MJX system built
  assert not hasattr(c.engine, "sys") and not hasattr(c, "sys")
  mjx = envs.make("AntFall", physics="mjx")
  assert mjx.physics == "mjx" and isinstance(mjx.engine, mjx_physics.MjxPhysics)


def test_ant_falls_into_the_chasm_and_stands_on_platforms_in_the_c_env():
  """HIRO's Fall geometry through the env itself (test_ant_physics checks it in plain MuJoCo
  on the same model, which the C env steps bit for bit)."""
  env = envs.make("AntFall", physics="c")
  s = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), 2))
  qpos = np.asarray(s.pipeline_state.qpos, np.float64)
  qpos[1, :3] = (0.0, 16.0, 5.0)  # over the open chasm cell
  init = jax.jit(jax.vmap(env.pipeline_init))(jp.asarray(qpos, jp.float32),
                                             s.pipeline_state.qvel)
  s = s.replace(pipeline_state=init)
  s = _run(env, s, np.zeros((2, 20, 8), np.float32))  # 2 s of zero torques
  z = np.asarray(s.pipeline_state.qpos[:, 2])
  assert 4.2 < z[0] < 5.0  # at its start, on the platform
  assert z[1] < 1.0  # down on the ground, 4 below the platforms


def _random_torques(compiled, resets, steps):
  """xyz of the torso after each of ``steps`` random-torque steps, from ``resets`` x 2 resets
  (the session's compiled env of batch 2: no further compilation), (resets x 2, steps, 3)."""
  rng, out = np.random.default_rng(7), []
  for k in range(resets):
    s, xyz = compiled.reset(jax.random.split(jax.random.PRNGKey(k), 2)), []
    for a in rng.uniform(-30, 30, (steps, 2, 8)).astype(np.float32):
      s = compiled.step(s, jp.asarray(a))
      xyz.append(np.asarray(s.obs[:, :3]))
    out.append(np.stack(xyz, 1))
  return np.concatenate(out)


@pytest.mark.slow
def test_c_and_mjx_move_the_ant_alike(compiled_env):
  """From the same resets and random torques (16 envs, 6 s on AntPush): identical until the
  feet reach the floor, then apart by a few cm per step (MJX differs from MuJoCo C with
  pyramidal friction cones and violated joint limits, which HIRO's ankles are at rest; with
  either changed the two agree to < 1 mm), while the motion's statistics agree: mean speed,
  height and displacement. Measured 2026-12-02 over 10 s: 1 s apart at most 0.50 (AntPush) /
  0.35 (AntFall); mean speed 0.0515 vs 0.0504 per step, height 0.571 vs 0.570, displacement
  0.97 vs 0.92."""
  steps = 60
  c = _random_torques(compiled_env("AntPush", "c"), 8, steps)
  m = _random_torques(compiled_env("AntPush", "mjx"), 8, steps)
  err = np.linalg.norm(c - m, axis=-1)
  assert err[:, :2].max() < 5e-3  # before the first contact
  assert err[:, 9].max() < 0.6  # 1 s
  speed = lambda x: np.linalg.norm(np.diff(x[..., :2], axis=1), axis=-1).mean()
  assert speed(c) == pytest.approx(speed(m), rel=0.05)
  assert c[..., 2].mean() == pytest.approx(m[..., 2].mean(), abs=0.02)
  disp = lambda x: np.linalg.norm(x[:, -1, :2] - x[:, 0, :2], axis=-1).mean()
  assert disp(c) == pytest.approx(disp(m), abs=0.2)


@pytest.mark.slow
def test_mjx_matches_mujoco_c_with_elliptic_cones():
  """Why C and MJX part: on the same model with elliptic friction cones, one MJX step and one
  mj_step stay within 1 mm of each other over 1 s of random torques (pyramidal: 4-16 cm)."""
  from mujoco import mjx

  m = envs.make("AntPush", physics="c").mj_model
  m.opt.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
  d = mujoco.MjData(m)
  d.qpos[2] += 0.05
  mx = mjx.put_model(m)
  dx, step = mjx.put_data(m, d), jax.jit(lambda x, a: mjx.step(mx, x.replace(ctrl=a)))
  for a in np.random.default_rng(0).uniform(-30, 30, (10, 8)):
    d.ctrl[:] = a
    for _ in range(5):
      mujoco.mj_step(m, d)
      dx = step(dx, jp.asarray(a, jp.float32))
  np.testing.assert_allclose(np.asarray(dx.qpos[:3]), d.qpos[:3], atol=1e-3)
