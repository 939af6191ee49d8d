"""HIRO off-policy goal correction: it picks the candidate that explains the low actions."""

import jax
import jax.numpy as jp
import numpy as np

from nonmono_jax.core import relabel

GOAL_RANGE = jp.array([10.0, 10.0, 0.5])


def _low_policy(states, goals):
  """A toy goal-conditioned low policy: the action is a fixed linear map of the goal."""
  w = jp.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.5, 0.5, 2.0], [0.0, -1.0, 1.0]])
  return goals @ w.T + 0.1 * states[:, 3:4]


def _segment(key, goal, c=10):
  """States moving a random walk; actions the toy policy takes toward ``goal``."""
  steps = jax.random.normal(key, (c, 5)) * 0.3
  states = jp.concatenate([jp.zeros((1, 5)), jp.cumsum(steps, axis=0)])
  actions = _low_policy(states[:-1], relabel.goal_sequence(goal, states[:-1]))
  return states, actions


def test_goal_sequence_is_the_goal_transition():
  states = jp.array([[0.0, 0, 0], [1.0, 2, 0], [3.0, 1, 0.5]])
  g = jp.array([5.0, 5.0, 0.0])
  seq = relabel.goal_sequence(g, states)
  np.testing.assert_allclose(seq, [[5, 5, 0], [4, 3, 0], [2, 4, -0.5]])
  # Recursively: g_{t+1} = s_t + g_t - s_{t+1}.
  np.testing.assert_allclose(seq[1:], states[:-1] + seq[:-1] - states[1:])


def test_candidates_layout_and_range():
  s0, s1 = jp.zeros(5), jp.array([3.0, -4.0, 0.2, 9.0, 9.0])
  g = jp.array([1.0, 1.0, 0.0])
  c = relabel.candidates(jax.random.PRNGKey(0), g, s0, s1, GOAL_RANGE)
  assert c.shape == (10, 3)
  np.testing.assert_allclose(c[0], g)
  np.testing.assert_allclose(c[1], [3.0, -4.0, 0.2])
  assert bool(jp.all(jp.abs(c[2:]) <= GOAL_RANGE))
  assert float(jp.std(c[2:, 0])) > 1.0  # 0.5 * range spread


def test_keeps_the_original_goal_when_it_explains_the_actions():
  g = jp.array([4.0, -2.0, 0.3])
  states, actions = _segment(jax.random.PRNGKey(1), g)
  new, idx = relabel.relabel(jax.random.PRNGKey(2), _low_policy, states, actions, g, GOAL_RANGE)
  assert int(idx) == 0
  np.testing.assert_allclose(new, g)


def test_picks_the_achieved_offset_when_the_actions_followed_it():
  states, _ = _segment(jax.random.PRNGKey(3), jp.zeros(3))
  achieved = states[-1, :3] - states[0, :3]
  actions = _low_policy(states[:-1], relabel.goal_sequence(achieved, states[:-1]))
  wrong = jp.array([-8.0, 8.0, -0.4])
  new, idx = relabel.relabel(jax.random.PRNGKey(4), _low_policy, states, actions, wrong,
                             GOAL_RANGE)
  assert int(idx) == 1
  np.testing.assert_allclose(new, achieved, rtol=1e-6)


def test_picks_the_best_random_candidate_otherwise():
  key = jax.random.PRNGKey(5)
  states, _ = _segment(key, jp.zeros(3))
  cands = relabel.candidates(key, jp.zeros(3), states[0], states[-1], GOAL_RANGE)
  true = cands[6]  # the actions were taken toward random candidate 6
  actions = _low_policy(states[:-1], relabel.goal_sequence(true, states[:-1]))
  new, idx = relabel.relabel(key, _low_policy, states, actions, jp.zeros(3), GOAL_RANGE)
  assert int(idx) == 6
  np.testing.assert_allclose(new, true)


def test_relabel_vmaps_over_a_batch():
  goals = jp.array([[4.0, -2.0, 0.3], [1.0, 1.0, -0.1]])
  segs = [_segment(jax.random.PRNGKey(i), g) for i, g in enumerate(goals)]
  states = jp.stack([s for s, _ in segs])
  actions = jp.stack([a for _, a in segs])
  fn = jax.jit(jax.vmap(lambda k, s, a, g: relabel.relabel(k, _low_policy, s, a, g, GOAL_RANGE)))
  new, idx = fn(jax.random.split(jax.random.PRNGKey(0), 2), states, actions, goals)
  np.testing.assert_array_equal(idx, [0, 0])
  np.testing.assert_allclose(new, goals)
