"""Learning on the point robot's maze: HIRO and ours beat a random policy in CPU minutes.

The evaluation (in the training program, every 2K steps) runs Middle TD3 + Low TD3 without
noise, so a Low that stopped learning (goals not followed) or a Middle that stopped learning
(goals not leading to the target) fails it; for ours the modes must also have been used.
PointMaze is a U: greedy progress towards the target ends against a wall 6.5-6.7 from it,
and only exploration finds the way round: ours must get there in some seeds, while HIRO
(Gaussian goal noise) must at least learn the greedy approach to the wall.
"""

import jax
import numpy as np
import pytest

import envs
from experiments import random_baseline
from nonmono_jax.core import train
from nonmono_jax.host import methods
from tests_support import OPTIMISED

STEPS = 40_000
CHUNK = 4_000


def _train(method: str, seeds: int, steps: int = STEPS):
  env = envs.make("PointMaze", episode_length=methods.TASKS["PointMaze"].episode_length)
  config = methods.build_config("paper", method, "PointMaze")[0]
  trainer = train.make_trainer(env, config, num_seeds=seeds, chunk_steps=CHUNK,
                               compiler_options=OPTIMISED)
  states = trainer.init(jax.random.PRNGKey(0))
  for t0 in range(0, steps, CHUNK):
    states, metrics = trainer.chunk(states, t0)
  return states, jax.tree.map(np.asarray, metrics)


@pytest.fixture(scope="module")
def random_policy():
  rand = random_baseline.run("PointMaze", episodes=256, episode_length=100)
  assert rand["success_rate"] < 0.1
  return rand


@pytest.mark.slow
def test_ours_learns_point_maze(random_policy):
  states, metrics = _train("ours", 8)
  s_e, dist = np.asarray(states.s_e), np.asarray(states.eval_distance)
  print("ours S_E", s_e, "distance", dist, "modes", np.asarray(states.mode_steps))
  # Measured on an Intel Xeon 6/167 (2026-12-02): S_E = 0, 0, 1, 1, 1, 1, 0, 1 at 40K steps
  # (the 40-seed follow-up: 33 of 40 by 100K). Which seeds solve moves with the CPU type
  # (XLA:CPU rounds differently); at a per-seed rate near 0.6, 2 or more of 8 fail to solve
  # less than 1 % of the time, where 2 of 4 did 18 % of the time.
  assert (s_e >= 0.8).sum() >= 2, s_e
  assert s_e.mean() > random_policy["success_rate"] + 0.2  # 2 of 8: 0.25
  assert np.all(metrics["top/updated"] > 0) and np.all(metrics["middle_ppo/updated"] > 0)
  modes = np.asarray(states.mode_steps)
  assert np.all(modes > 0)  # every mode ran


@pytest.mark.slow
def test_hiro_learns_point_maze(random_policy):
  states, metrics = _train("hiro", 4, steps=20_000)
  dist = np.asarray(states.eval_distance)
  print("hiro S_E", np.asarray(states.s_e), "distance", dist)
  # HIRO's goal noise rarely finds the way round the U within CPU budgets (1 of 8 seeds at 40K
  # steps), but its Low follows goals and its Middle aims them at the target: the evaluation
  # ends against the wall 6.5-6.7 from the target. Measured (this CPU, 2026-11-23) at 20K
  # steps: distances 6.62, 6.67, 6.63, 7.04 (at 40K: 6.60, 6.67, 9.62, 6.96), against a
  # random policy's 8.79.
  assert np.median(dist) < random_policy["final_distance"] - 1.5, (dist, random_policy)
  assert np.all(metrics["low/critic_loss"] > 0)
