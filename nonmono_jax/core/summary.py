"""A chunk's summary: what the rows of ``metrics.csv`` say, per lane, in typed fields.

The step returns free-form metrics by name (``metrics.Metric``; every one reaches
``metrics.jsonl`` and TensorBoard). The rows read a fixed set of them and a few counters of the
train state: ``summarise(states, metrics)`` picks those here, in the core, where the metrics
are named, into a ``Summary``. The host formats it (``host/rows.py``) and looks no metric or
state field up by name, so a metric renamed in the core fails here, in the core's own tests,
not in a run.

    summary = trainer.summarise(states, metrics)   # jitted; per lane, (lanes,) or (lanes, 3)
    summary.steps[:, hierarchy.PPO], summary.losses.top, summary.updates.top

A learner's metric is looked up where its level has one (``<level>/updated``, which a level
that exists always reports): a renamed loss is a KeyError, not an empty column. A metric a
method does not have (HIRO's Top) is zero, with zero updates: the rows leave it empty.
"""

from __future__ import annotations

import jax
import jax.numpy as jp
from flax import struct

from nonmono_jax.core import hierarchy
from nonmono_jax.core.evaluate import KINDS


@struct.dataclass
class Losses:
  """Each learner's losses, averaged over the steps of the chunk where it updated."""

  low_critic: jax.Array
  low_actor: jax.Array
  middle_critic: jax.Array
  middle_actor: jax.Array
  middle_ppo: jax.Array
  top: jax.Array


@struct.dataclass
class Updates:
  """The steps of the chunk where each learner updated (0: its losses are not values)."""

  low: jax.Array
  middle: jax.Array
  middle_ppo: jax.Array
  top: jax.Array


@struct.dataclass
class Summary:
  """A chunk of every lane: (lanes,) or, per mode (``hierarchy.MODES``) or evaluation kind
  (``evaluate.KINDS``), (lanes, 3)."""

  # the chunk, from its metrics
  reward: jax.Array  # mean task reward per env step
  success: jax.Array  # mean success per env step
  distance: jax.Array  # mean distance to the target
  steps: jax.Array  # (lanes, modes) int32 env steps run in each mode after warm-up
  decisions: jax.Array  # (lanes, modes) int32 Middle decisions in each mode after warm-up
  mode_probs: jax.Array  # (lanes, modes) pi_T(m | s_0), mean over the Top horizons ended
  horizons: jax.Array  # Top horizons ended (0: mode_probs are not values)
  losses: Losses
  updates: Updates
  low_reward: jax.Array  # the Low's mean reward per env step
  subgoal_distance: jax.Array  # ||g_c|| at segment ends
  subgoal_reached: jax.Array  # ||g_c|| <= 1.5 at segment ends
  subgoal_progress: jax.Array  # ||g_0|| - ||g_c|| at segment ends
  evaluates: jax.Array  # (lanes, kinds) 1.0 for each evaluation kind the program runs
  unstable_steps: jax.Array  # training env steps whose physics went unstable
  unstable_evaluation: jax.Array  # evaluation env steps whose physics went unstable
  # the train state after the chunk
  cum_steps: jax.Array  # (lanes, modes) env steps per mode since warm-up
  cum_decisions: jax.Array  # (lanes, modes) Middle decisions per mode since warm-up
  cum_steps_after_start: jax.Array  # (lanes, modes) the same after the starting mode
  cum_decisions_after_start: jax.Array  # (lanes, modes)
  s_e: jax.Array  # the latest evaluation's S_E (0 before the first)
  eval_distance: jax.Array  # its mean final distance
  eval_return: jax.Array  # its mean return
  eval_by_kind: jax.Array  # (lanes, kinds) the latest S_E of each evaluation kind
  # the NaN check: per learner (``SeedState.learner_params``), every parameter finite; per
  # metric of a learner (and the reward), every value finite; (lanes,) bool each
  params_finite: dict
  metrics_finite: dict


def summarise(states, metrics: dict) -> Summary:
  """The ``Summary`` of a chunk: ``states`` after it (``agent.SeedState``s, one per lane),
  ``metrics`` its reduced metrics (``train.reduce_chunk``)."""
  lanes = metrics["reward"]
  get = lambda name: metrics[name] if name in metrics else jp.zeros_like(lanes)
  # a level's metric where the level exists (it reports its updates), else zero
  of_level = lambda name: (metrics[name] if f"{name.split('/')[0]}/updated" in metrics
                           else jp.zeros_like(lanes))
  per_mode = lambda prefix: jp.stack([metrics[f"{prefix}/{m}"] for m in hierarchy.MODES], -1)
  return Summary(
      reward=metrics["reward"], success=metrics["success"], distance=metrics["distance"],
      steps=per_mode("count"), decisions=per_mode("decisions"),
      mode_probs=jp.stack([of_level(f"horizon/p_{m}") for m in hierarchy.MODES], -1),
      horizons=get("horizon/updated"),
      losses=Losses(low_critic=of_level("low/critic_loss"), low_actor=of_level("low/actor_loss"),
                    middle_critic=of_level("middle/critic_loss"),
                    middle_actor=of_level("middle/actor_loss"),
                    middle_ppo=of_level("middle_ppo/loss"), top=of_level("top/loss")),
      updates=Updates(low=get("low/updated"), middle=get("middle/updated"),
                      middle_ppo=get("middle_ppo/updated"), top=get("top/updated")),
      low_reward=metrics["low/reward"], subgoal_distance=metrics["low/subgoal_distance"],
      subgoal_reached=metrics["low/subgoal_reached"],
      subgoal_progress=metrics["low/subgoal_progress"],
      evaluates=jp.stack([jp.full_like(lanes, f"eval/success_{k}" in metrics) for k in KINDS],
                         -1),
      unstable_steps=get("physics/unstable"), unstable_evaluation=get("eval/unstable"),
      cum_steps=states.mode_steps, cum_decisions=states.mode_decisions,
      cum_steps_after_start=states.mode_steps_after_start,
      cum_decisions_after_start=states.mode_decisions_after_start, s_e=states.s_e,
      eval_distance=states.eval_distance, eval_return=states.eval_return,
      eval_by_kind=states.eval_by_kind, params_finite=params_finite(states),
      metrics_finite=metrics_finite(states, metrics))


def _all_finite(tree) -> jax.Array:
  """Per lane: every value of ``tree`` (leading lane axis) finite."""
  per_leaf = jax.tree.map(lambda x: jp.all(jp.isfinite(x), axis=tuple(range(1, x.ndim))), tree)
  return jax.tree.reduce(jp.logical_and, per_leaf, jp.bool_(True))


def params_finite(states) -> dict:
  """Per learner the seed has, by level name: every parameter finite, per lane."""
  return {level: _all_finite(params) for level, params in states.learner_params().items()}


def metrics_finite(states, metrics: dict) -> dict:
  """Per metric of a learner (named ``<level>/...``) and the reward: every value finite."""
  levels = set(states.learner_params())
  return {name: _all_finite(value) for name, value in metrics.items()
          if name.split("/")[0] in levels or name == "reward"}
