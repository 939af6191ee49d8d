"""The evaluation kinds (nonmono_jax/core/evaluate.py): the goals the Low is sent to, where an
episode's final distance is read, and that the vmapped scan judges episodes as the paper's
code's Python loop does (``hiro.evaluate``: a new Middle goal after every step, the episode
stopped at its first success)."""

import jax
import jax.numpy as jp
import numpy as np
import pytest
from flax import struct

from nonmono_jax.core import evaluate
from nonmono_jax.core.evaluate import KINDS

C, LENGTH, TARGET, RADIUS = 4, 12, np.array([3.0, 0.0, 0.0]), 1.0


@struct.dataclass
class _State:
  obs: jax.Array  # (x, y, z, t * 0.001)
  steps: jax.Array
  reward: jax.Array
  success: jax.Array
  distance: jax.Array


class _Line:
  """A point that moves by its action (x, y), the target 3 units away along x."""

  episode_length = LENGTH

  def _scored(self, obs, steps):
    d = jp.linalg.norm(obs[:3] - TARGET)
    return _State(obs=obs, steps=steps, reward=-d, success=(d <= RADIUS).astype(jp.float32),
                  distance=d)

  def reset(self, key):
    xy = jax.random.uniform(key, (2,), minval=-0.5, maxval=0.5)
    return self._scored(jp.array([xy[0], xy[1], 0.0, 0.0]), jp.zeros((), jp.int32))

  def step(self, s, a):
    steps = s.steps + 1
    obs = s.obs.at[:2].add(a).at[3].set(steps * 0.001)
    return self._scored(obs, steps)

  def block_positions(self, s):
    return jp.zeros((0, 3))

  def unstable(self, s):
    return jp.zeros(())


ENV = _Line()
LOW = lambda params, obs, g: jp.clip(g[:2] * params, -1.0, 1.0)  # towards s[:3] + g
# A Middle goal towards the target (shifted by ``params``), whose world point drifts along x
# with the step counter t (0.1 t), so that goals chosen at different steps differ.
TOWARDS = lambda params, obs, key: (jp.asarray(TARGET) - obs[:3] + params
                                    + jp.array([100.0, 0.0, 0.0]) * obs[3])


@pytest.mark.parametrize("kind", ["held", "requery"])
def test_the_goal_the_low_is_sent_to(kind):
  """held: the Middle's goal at s_0, s_c, ..., kept in world space in between; requery: N(0, I)
  first (the code's randn(3)), then the Middle's goal at every new state."""
  key = jax.random.PRNGKey(0)
  s0, r = jax.jit(evaluate.make_episode(ENV, C, LOW, TOWARDS, kind))(0.25, 0.5, key)
  states = np.concatenate([np.asarray(s0.obs)[None, :3], np.asarray(r["pos"])])  # s_0 .. s_T
  world = np.asarray(r["goal"])  # s_t[:3] + g_t, the point the Low heads for in step t
  drift = lambda t: TARGET + 0.5 + np.array([0.1 * t, 0.0, 0.0])
  for t in range(LENGTH):
    if kind == "held":  # chosen at the segment's first state s_{t - t % c}
      np.testing.assert_allclose(world[t], drift(t - t % C), atol=1e-5)
    elif t == 0:
      first = np.asarray(jax.random.normal(jax.random.fold_in(key, 1), (3,)))
      np.testing.assert_allclose(world[0], states[0] + first, atol=1e-6)
    else:  # chosen at s_t
      np.testing.assert_allclose(world[t], drift(t), atol=1e-5)
  assert not np.allclose(states[1], states[0])


def test_the_final_distance_is_read_where_the_codes_episode_stops():
  records = {"success": jp.array([0.0, 0.0, 1.0, 1.0, 0.0]),
             "distance": jp.array([5.0, 4.0, 3.0, 2.0, 6.0]),
             "reward": -jp.array([5.0, 4.0, 3.0, 2.0, 6.0]), "unstable": jp.zeros(5)}
  for kind in ("requery", "ppo"):
    assert _values(evaluate.outcome(records, kind)) == [1.0, 3.0, -12.0, 0.0]
  assert _values(evaluate.outcome(records, "held")) == [1.0, 6.0, -20.0, 0.0]
  never = {**records, "success": jp.zeros(5)}
  assert _values(evaluate.outcome(never, "requery")) == [0.0, 6.0, -20.0, 0.0]


def _values(o: evaluate.Outcome) -> list[float]:
  return [float(o.success), float(o.distance), float(o.return_), float(o.unstable)]


def _code_loop(low_scale, goal_shift, key):
  """The paper's code's ``evaluate`` episode, as a Python loop over the same env: success and
  the distance where it stops."""
  s = ENV.reset(key)
  goal = jax.random.normal(jax.random.fold_in(key, 1), (3,))
  done, t = False, 0
  while not done and t < LENGTH:
    t += 1
    s = ENV.step(s, LOW(low_scale, s.obs, goal))
    done = bool(s.success)
    goal = TOWARDS(goal_shift, s.obs, None)
  return float(done), float(s.distance)


def test_the_scan_judges_episodes_as_the_codes_loop():
  """From the same start states and first goals, the vmapped evaluation's success and final
  distance equal the code's loop's, episode by episode (some succeed, some do not)."""
  keys = jax.random.split(jax.random.PRNGKey(3), 8)
  run = jax.jit(lambda low, shift, k: evaluate.outcome(
      evaluate.make_episode(ENV, C, LOW, TOWARDS, "requery")(low, shift, k)[1], "requery"))
  judged = []
  for low, shift in ((0.5, 0.0), (0.05, 0.0), (0.5, -2.5)):
    for k in keys:
      got = run(low, shift, k)
      want = _code_loop(low, shift, k)
      assert float(got.success) == want[0]
      assert float(got.distance) == pytest.approx(want[1], abs=1e-5)
      judged.append(want[0])
  assert 0 < np.mean(judged) < 1


def test_one_call_runs_each_kind_from_the_same_starts():
  ppo = lambda params, obs, key: jp.clip(TOWARDS(0.0, obs, None)
                                         + jax.random.normal(key, (3,)) * params, -2.0, 2.0)
  ev = evaluate.make_evaluate(ENV, C, LOW, lambda p, o: TOWARDS(p, o, None), 6,
                              target_networks=False, main="requery", extra=KINDS,
                              ppo_act=ppo)
  assert ev.kinds == ("requery", "held", "ppo")

  low = jp.asarray(0.5)
  out = jax.jit(lambda k: ev(low, jp.asarray(0.0), jp.asarray(0.1), k))(jax.random.PRNGKey(1))
  assert out.by_kind.shape == (3,)
  assert float(out.success) == float(out.by_kind[evaluate.KINDS.index("requery")])
  alone = evaluate.make_evaluate(ENV, C, LOW, lambda p, o: TOWARDS(p, o, None), 6,
                                 target_networks=False, main="requery")
  assert alone.kinds == ("requery",)
  lone = jax.jit(lambda k: alone(low, jp.asarray(0.0), None, k))(jax.random.PRNGKey(1))
  assert float(lone.success) == float(out.success)  # the main kind's keys do not move
  assert float(lone.by_kind[0]) == 0.0 and float(lone.by_kind[2]) == 0.0

