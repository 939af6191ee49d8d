"""Hand-worked values of the formulas linking the levels."""

import jax.numpy as jp
import numpy as np

from nonmono_jax.core import hierarchy as h


def test_goal_transition_and_low_reward():
  s = jp.array([1.0, 2.0, 0.5, 9.0])
  s_next = jp.array([2.0, 4.0, 0.5, -9.0])
  g = jp.array([3.0, 3.0, 0.0])
  np.testing.assert_allclose(h.goal_transition(s, g, s_next), [2.0, 1.0, 0.0])
  np.testing.assert_allclose(h.low_reward(s, g, s_next), -np.sqrt(5.0), rtol=1e-6)
  # The goal stays put in world space: s + g == s' + g'.
  np.testing.assert_allclose(s[:3] + g, s_next[:3] + h.goal_transition(s, g, s_next))


def test_low_done_threshold():
  np.testing.assert_array_equal(
      h.low_done(jp.array([[1.0, 1.0, 0.0], [1.5, 0.0, 0.0], [1.2, 1.0, 0.0]])), [1, 1, 0])


def test_middle_reward_is_a_tenth_of_the_sum():
  np.testing.assert_allclose(h.middle_reward(jp.full((10,), -7.0)), -7.0, rtol=1e-6)
