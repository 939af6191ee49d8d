"""Parity with the paper's own PyTorch code, on numbers recorded once from it.

``tests/data/reference_fixtures.npz`` was written by ``python -m reference.fixtures`` in the
reference venv (docs/reference.md, "Parity fixtures"); these tests need neither torch nor the
fetched code. Each builds ours from the same numbers (nn.Linear's (out, in) weights as flax's
(in, out) kernels; the same batches and rollouts; the code's random draws fed where ours
draws), runs it and compares. Where ours differs on purpose (docs/fidelity.md), a test shows
ours equal to the code under the code's setting and the default differing, naming the row.

Tolerances, and why:

* networks: forward passes, TD3 losses and y to a relative 1e-5 (float32 sums in another
  order: XLA's dot against MKL's addmm); TD3 weights after 3 updates to an absolute 5e-6 (they
  move by up to 3 Adam steps of 1e-4 (actor) or 1e-3 (critic); Adam's epsilon sits in the same
  place in optax and torch, ``m_hat / (sqrt(v_hat) + eps)``, but where a gradient is near
  eps = 1e-8 its float32 rounding moves that entry's first step by a part of the learning rate;
  measured 8e-7 (Low) and 2.2e-6 (Middle critic));
* PPO: the K-epoch mean losses to a relative 2e-4 (the surrogate is a mean of terms that
  cancel, and each epoch starts from weights that drifted by the last: measured 5e-5); weights
  after 20 Adam steps to an absolute 2e-5 (measured 9.5e-6);
* the env: observations to 1e-6 (the float64 physics is the same, bit for bit on HIRO's
  literal model; ours hands float32 observations); the optimised build (merged walls, 8 solver
  iterations instead of 100 / 50) the same until the contact solve needs more than 8
  iterations, after which the path is chaotic: checked over the 5-step cases and the path's
  first 50 steps.
"""

import functools
import pathlib
from unittest import mock

import jax
import jax.numpy as jp
import numpy as np
import pytest

import envs
import reference
from reference import fixtures
from nonmono_jax.core import agent as agent_lib
from nonmono_jax.core import hierarchy, low as low_lib, middle as middle_lib, lanes, ppo
from nonmono_jax.core import modes as modes_lib
from nonmono_jax.core import relabel, td3
from nonmono_jax.core.modes import top as top_lib
from nonmono_jax.host import methods
from tests.tests_support import ROOT

DATA = pathlib.Path(ROOT) / "tests" / "data" / "reference_fixtures.npz"
TARGET = jp.asarray(fixtures.TARGET, jp.float32)
GOAL_RANGE = np.array(fixtures.MAX_GOAL, np.float32)
# The code's Top modes are 0 PPO, 1 TD3, 2 RANDOM; ours TD3, PPO, RANDOM (hierarchy.MODES).
# The permutation is its own inverse: ours = PERMUTE[code] and code = PERMUTE[ours].
PERMUTE = np.array([1, 0, 2])
WEIGHTS_ATOL = 5e-6
PPO_WEIGHTS_ATOL = 2e-5
RTOL = 1e-5


@pytest.fixture(scope="module")
def fx():
  arrays, meta = fixtures.read(DATA)
  return arrays


def ant_config(overrides=None):
  return methods.build_config("paper", "ours", "AntPush", overrides)[0]


# ----- weights: the code's nn.Linear layers as flax params -------------------------------------

def flax_mlp(layers, out_perm=None):
  """[(W (out, in), b), ...] -> flax MLP params ({"params": {"dense_i": kernel (in, out)}});
  ``out_perm`` reorders the last layer's outputs (the Top's modes)."""
  params = {}
  for i, (w, b) in enumerate(layers):
    if out_perm is not None and i == len(layers) - 1:
      w, b = w[out_perm], b[out_perm]
    params[f"dense_{i}"] = {"kernel": jp.asarray(w.T), "bias": jp.asarray(b)}
  return {"params": params}


def flax_critic(nets):
  """Two Q networks -> ours' twin critic (stacked on a leading axis of 2)."""
  return jax.tree.map(lambda a, b: jp.stack([a, b]), flax_mlp(nets[0]), flax_mlp(nets[1]))


def code_layers(fx, prefix, n_nets, n_layers=3):
  return [[(fx[f"{prefix}/{n}/{i}/W"], fx[f"{prefix}/{n}/{i}/b"]) for i in range(n_layers)]
          for n in range(n_nets)]


def our_layers(params, n_nets=1, out_perm=None):
  """Ours' params back as [[(W (out, in), b), ...] per network]."""
  nets = []
  for n in range(n_nets):
    layers = []
    for i in range(len(params["params"])):
      d = params["params"][f"dense_{i}"]
      w, b = np.asarray(d["kernel"]), np.asarray(d["bias"])
      if n_nets > 1:
        w, b = w[n], b[n]
      if out_perm is not None and i == len(params["params"]) - 1:
        w, b = w[:, out_perm], b[out_perm]
      layers.append((w.T, b))
    nets.append(layers)
  return nets


def assert_layers_close(ours, code, atol, moved_from=None):
  """Every weight within ``atol``; and (``moved_from``) the updates moved them by more than
  that, so that the check says something."""
  for n, (our_net, code_net) in enumerate(zip(ours, code)):
    for i, ((w, b), (cw, cb)) in enumerate(zip(our_net, code_net)):
      np.testing.assert_allclose(w, cw, rtol=0, atol=atol, err_msg=f"net {n} layer {i} W")
      np.testing.assert_allclose(b, cb, rtol=0, atol=atol, err_msg=f"net {n} layer {i} b")
  if moved_from is not None:
    moved = max(np.abs(cw - w0).max() for net, net0 in zip(code, moved_from)
                for (cw, _), (w0, _) in zip(net, net0))
    assert moved > 30 * atol


def test_fixtures_metadata_and_the_weights_recipe(fx):
  """The fixtures name the pinned commit and torch; ``mlp_weights`` makes the weights the
  code was given (their float64 sums, recorded with them)."""
  _, meta = fixtures.read(DATA)
  assert meta["code"]["commit"] == reference.COMMIT
  assert meta["packages"]["torch"].startswith("2.")
  assert meta["command"].startswith("python -m reference.fixtures")
  for level in ("low", "middle"):
    for name in ("actor", "critic", "target_actor", "target_critic"):
      np.testing.assert_array_equal(fixtures.checksum(fixtures.network(f"{level}_{name}")),
                                    fx[f"{level}/checksum/{name}"])
  for kind in ("ppo", "top"):
    for name in ("actor", "critic"):
      np.testing.assert_array_equal(fixtures.checksum(fixtures.network(f"{kind}_{name}")),
                                    fx[f"{kind}/checksum/{name}"])
  assert DATA.stat().st_size < 6e6


# ----- a. the env ------------------------------------------------------------------------------

OBS_ATOL = 1e-6
_envs = {}


def _env_run(physics, optimised):
  """Ours' env (MuJoCo C) run from given qpos/qvel at episode step t under scripted actions:
  (observations, task reward, success) of every state, start state first."""
  key = (physics, optimised)
  if key not in _envs:
    env = envs.make("AntPush", physics="c", optimised=optimised, contacts=physics)

    def run(qpos, qvel, t, actions):
      start = env._state(env.pipeline_init(qpos, qvel), t)

      def step(state, action):
        state = env.step(state, action)
        return state, (state.obs, state.reward, state.success)

      _, path = jax.lax.scan(step, start, actions)
      first = (start.obs, start.reward, start.success)
      return tuple(jp.concatenate([a[None], b]) for a, b in zip(first, path))

    _envs[key] = jax.jit(jax.vmap(run))
  return _envs[key]


def _as32(*arrays):
  return [jp.asarray(a, jp.float32) for a in arrays]


@pytest.mark.parametrize("optimised", [False, True], ids=["literal", "optimised"])
@pytest.mark.parametrize("physics", fixtures.PHYSICS)
def test_env_follows_the_codes_maze_env(fx, physics, optimised):
  """From 20 start states x 5 scripted steps and along a 100-step path: the observations, the
  task reward -||xyz - target|| and success (<= 5) of each state. On HIRO's literal model the
  whole path agrees to float32 rounding; the optimised build until its 8-iteration contact
  solve stops short of the 100-iteration one (after step 50 of the path under ``mujoco200``),
  from where the ant's motion is chaotic."""
  run = _env_run(physics, optimised)
  obs, reward, success = run(*_as32(fx["env/qpos"], fx["env/qvel"]), jp.asarray(fx["env/t"]),
                             jp.asarray(fx["env/actions"]))
  np.testing.assert_allclose(obs, fx[f"env/{physics}/obs"], rtol=0, atol=OBS_ATOL)
  np.testing.assert_allclose(reward, fx[f"env/{physics}/reward"], rtol=RTOL, atol=0)
  np.testing.assert_array_equal(success, fx[f"env/{physics}/success"])
  path = run(*_as32(fx["env/path_qpos"][None], fx["env/path_qvel"][None]), jp.zeros(1, int),
             jp.asarray(fx["env/path_actions"][None]))
  steps = 101 if not optimised else 51
  np.testing.assert_allclose(path[0][0, :steps], fx[f"env/{physics}/path_obs"][:steps], rtol=0,
                             atol=OBS_ATOL)
  np.testing.assert_allclose(path[1][0, :steps], fx[f"env/{physics}/path_reward"][:steps],
                             rtol=RTOL)
  assert fx[f"env/{physics}/success"].sum() == 0  # the start cell is far from the target
  if optimised and physics == "mujoco200":
    assert np.abs(path[0][0, 100, :3] - fx[f"env/{physics}/path_obs"][100, :3]).max() > 1e-3


@pytest.mark.parametrize("physics", fixtures.PHYSICS)
def test_env_reset_observation_normalises_the_quaternion_the_code_does_not(fx, physics):
  """Not in docs/fidelity.md until these fixtures: the code's reset (``reset_model``) adds
  U(-0.1, 0.1) to all 15 of the ant's qpos, the torso's quaternion included, and observes it
  unnormalised (|q| from 0.94 to 1.05 here); ours normalises it (``pipeline_init``, as MJX's
  forward pass leaves it). Only that observation differs: MuJoCo normalises the quaternion
  wherever it uses it, so the next states agree (to the float32 rounding of the code's
  float64 reset state)."""
  code_obs = fx[f"env/{physics}/reset_obs"]
  run = _env_run(physics, False)
  obs, _, _ = run(*_as32(fx[f"env/{physics}/reset_qpos"], fx[f"env/{physics}/reset_qvel"]),
                  jp.zeros(3, int), jp.asarray(fx["env/actions"][:3]))
  norms = np.linalg.norm(code_obs[:, 0, 3:7], axis=1)
  assert np.abs(norms - 1).max() > 0.03
  np.testing.assert_allclose(np.linalg.norm(obs[:, 0, 3:7], axis=1), 1.0, atol=1e-6)
  np.testing.assert_allclose(obs[:, 0, 3:7] * norms[:, None], code_obs[:, 0, 3:7], atol=1e-6)
  np.testing.assert_allclose(obs[:, 1:], code_obs[:, 1:], rtol=0, atol=1e-5)


# ----- b, c. the Low and Middle TD3 updates ----------------------------------------------------

def _td3(level, config):
  """Ours' TD3 of a level as the agent builds it (the Middle's actor on s alone, its critic on
  (s, g); the Low's on (s, g)), at the code's weights and fresh Adam states."""
  if level == "low":
    learner = low_lib.make_low(30, 8, 30.0, config).td3
  else:
    low = low_lib.make_low(30, 8, 30.0, config)
    learner = middle_lib.make_middle(30, 8, TARGET, config, low.td3.act).td3
  state = learner.init(jax.random.PRNGKey(0))  # Adam's moments are zeros, as torch's
  params = td3.TD3Params(
      actor=flax_mlp(fixtures.network(f"{level}_actor")[0]),
      critic=flax_critic(fixtures.network(f"{level}_critic")),
      target_actor=flax_mlp(fixtures.network(f"{level}_target_actor")[0]),
      target_critic=flax_critic(fixtures.network(f"{level}_target_critic")))
  return learner, state.replace(params=params)


def _td3_batch(fx, level, k):
  """The code's batch k as ours' Transition: the Middle's reward is 0.1 x the stored segment
  sum (ours stores R_M scaled; the code scales it in y: the same float32 product)."""
  b = [fx[f"{level}/{k}/batch/{i}"] for i in range(7 if level == "low" else 5)]
  if level == "low":
    s, g, a, r, s2, g2, d = b
    return td3.Transition(obs=s, context=g, action=a, reward=r[:, 0], next_obs=s2,
                          next_context=g2, done=d[:, 0])
  s, g, r, s2, d = b
  none = np.zeros((len(s), 0), np.float32)
  reward = np.float32(hierarchy.MIDDLE_REWARD_SCALE) * r[:, 0]
  return td3.Transition(obs=s, context=none, action=g, reward=reward, next_obs=s2,
                        next_context=none, done=d[:, 0])


def _with_noise(learner, hp):
  """``learner.update`` with ``jax.random.normal`` replaced by the code's draw (its standard
  normals z), broadcast to whatever shape ours asks for; the shapes asked are recorded."""
  shapes = []

  def update(state, batch, z):
    def normal(key, shape, dtype=jp.float32):
      shapes.append(tuple(shape))
      return jp.broadcast_to(z, shape).astype(dtype)

    with mock.patch.object(jax.random, "normal", normal):
      return learner.update(state, batch, jax.random.PRNGKey(1), True, hp)

  return jax.jit(update), shapes


@pytest.mark.parametrize("level", ["low", "middle"])
def test_td3_updates_follow_the_codes_step_updates(fx, level):
  """Three updates of the Low TD3 (``hiro.step_update_l``) and of the Middle TD3
  (``step_update_h``) from the same weights and fresh Adam states, on the code's batches:
  y, both losses at each update, and the weights after the third (the targets' Polyak step on
  a 5 % sample of their entries). The Low's target smoothing is fed the code's draw: one
  vector of 8 standard normals per batch, x 0.2, clipped at 0.5."""
  config = ant_config()
  pp = fx[f"{level}/params"]  # the code's numbers (train_param_hiro.csv)
  c = getattr(config, level)
  assert (c.lr_actor, c.lr_critic, c.gamma, c.tau, c.policy_noise, c.noise_clip) == (
      pytest.approx(pp[0]), pytest.approx(pp[1]), pytest.approx(pp[2]), pytest.approx(pp[3]),
      pytest.approx(pp[4] * pp[5]), pytest.approx(pp[6]))
  assert c.target_smoothing == (level == "low") and c.policy_delay == 1
  learner, state = _td3(level, config)
  update, shapes = _with_noise(learner, lanes.of(c))
  for k in range(fixtures.TD3_UPDATES):
    z = jp.asarray(fx[f"{level}/{k}/noise"].astype(np.float32))
    state, m = update(state, _td3_batch(fx, level, k), z)
    np.testing.assert_allclose(m["target_q"], fx[f"{level}/{k}/y"].mean(), rtol=RTOL)
    np.testing.assert_allclose(m["critic_loss"], fx[f"{level}/{k}/critic_loss"], rtol=RTOL)
    np.testing.assert_allclose(m["actor_loss"], fx[f"{level}/{k}/actor_loss"], rtol=RTOL)
  assert shapes == ([(8,)] if level == "low" else [])  # one draw per batch, as the code
  p = state.params
  start = [fixtures.network(f"{level}_actor"), fixtures.network(f"{level}_critic")]
  assert_layers_close(our_layers(p.actor), code_layers(fx, f"{level}/after/actor", 1),
                      WEIGHTS_ATOL, moved_from=start[0])
  assert_layers_close(our_layers(p.critic, 2), code_layers(fx, f"{level}/after/critic", 2),
                      WEIGHTS_ATOL, moved_from=start[1])
  for name, tree, n_nets in (("target_actor", p.target_actor, 1),
                             ("target_critic", p.target_critic, 2)):
    for n, net in enumerate(our_layers(tree, n_nets)):
      for i, (w, b) in enumerate(net):
        for key, a in (("W", w), ("b", b)):
          prefix = f"{level}/after/{name}/{n}/{i}/{key}"
          np.testing.assert_allclose(a.reshape(-1)[fx[prefix + "i"]], fx[prefix], rtol=0,
                                     atol=1e-7)


def test_low_target_noise_is_one_draw_per_batch_in_the_code(fx):
  """Not in docs/fidelity.md until these fixtures: the code draws the Low's target-policy
  noise once per update, ``np.random.normal(size=action_dim)``, shared by the batch's 100
  samples; TD3 (and ours by default, ``target_noise="sample"``) draws it per sample. The Ant
  presets take the code's (``low.target_noise="batch"``): with the same draw both compute the
  same y, and the default asks for (100, 8) numbers, not 8."""
  assert ant_config().low.target_noise == "batch"
  assert methods.build_config("paper", "ours", "PointPush")[0].low.target_noise == "sample"
  config = ant_config({"low.target_noise": "sample"})
  learner, state = _td3("low", config)
  update, shapes = _with_noise(learner, lanes.of(config.low))
  z = jp.asarray(fx["low/0/noise"].astype(np.float32))
  _, m = update(state, _td3_batch(fx, "low", 0), z)
  assert shapes == [(100, 8)]
  # fed the same vector in every row, the per-sample path computes the code's y too
  np.testing.assert_allclose(m["target_q"], fx["low/0/y"].mean(), rtol=RTOL)
  key = jax.random.PRNGKey(3)
  batch = _td3_batch(fx, "low", 0)
  per_sample = learner.critic_loss(state.params.critic, state.params, batch, key,
                                   lanes.of(config.low))[1]["target_q"]
  batch_config = ant_config()
  batch_learner, _ = _td3("low", batch_config)
  per_batch = batch_learner.critic_loss(state.params.critic, state.params, batch, key,
                                        lanes.of(batch_config.low))[1]["target_q"]
  assert float(per_sample) != float(per_batch)


# ----- c. the off-policy correction ------------------------------------------------------------

N_CORRECTION = 9  # cases 0-7: segments of the env path; 8: a Low actor blind to the goal
CODE_ORDER = np.array([2, 3, 4, 5, 6, 7, 8, 9, 1, 0])  # the code's candidates in ours' indices


def _correction(fx, i, ties):
  """Ours' relabelling of case i (``Middle.relabelled``'s call) under the Low's target actor,
  with the code's standard normals for the random candidates: (candidates, their scores, the
  chosen goal, its index in ours' order)."""
  low = low_lib.make_low(30, 8, 30.0, ant_config())
  layers = fixtures.network("low_target_actor")[0]
  if i == N_CORRECTION - 1:
    layers = [layers[0], layers[1], (np.zeros_like(layers[2][0]), layers[2][1])]
  params = flax_mlp(layers)
  policy = lambda s, g: low.td3.act(td3.TD3Params(params, None, None, None), s, g)
  states, actions = fx[f"correction/{i}/states"], fx[f"correction/{i}/actions"]
  goal = fx[f"correction/{i}/goal"]
  z = jp.asarray(fx[f"correction/{i}/z"].astype(np.float32))
  with mock.patch.object(jax.random, "normal", lambda key, shape: jp.broadcast_to(z, shape)):
    key = jax.random.PRNGKey(0)
    cands = relabel.candidates(key, goal, states[0], states[-1], GOAL_RANGE)
    chosen, index = relabel.relabel(key, policy, states, actions, goal, GOAL_RANGE, ties=ties)
  scores = jax.vmap(lambda g: relabel.action_log_likelihood(policy, states[:-1], actions, g))(
      cands)
  return np.asarray(cands), np.asarray(scores), np.asarray(chosen), int(index)


@pytest.mark.parametrize("i", range(N_CORRECTION))
def test_off_policy_correction_follows_the_codes(fx, i):
  """``off_policy_correction``: the 10 candidates (ours' order: the goal, s_c - s_0, the 8
  random ones; the code's: the random ones, s_c - s_0, the goal), their scores (ours
  -1/2 sum ||a - pi_L||^2 = 40 x the code's -mse_loss over 10 steps x 8 torques, the same
  ordering) and the chosen goal, with the Ant preset's tie rule. Case 8's Low actor ignores
  the goal: all ten tie, and the code keeps its first candidate, a random one."""
  cands, scores, chosen, index = _correction(fx, i, ant_config().relabel_ties)
  code_cands = fx[f"correction/{i}/candidates"]
  np.testing.assert_allclose(cands[CODE_ORDER], code_cands, rtol=1e-6, atol=1e-6)
  np.testing.assert_allclose(scores[CODE_ORDER] / 40.0, fx[f"correction/{i}/scores"],
                             rtol=RTOL)
  np.testing.assert_allclose(chosen, fx[f"correction/{i}/goal_hat"], rtol=1e-6, atol=1e-6)
  assert CODE_ORDER[int(fx[f"correction/{i}/index"])] == index


def test_correction_ties_go_to_the_original_goal_by_default(fx):
  """Not in docs/fidelity.md until these fixtures: under exact ties ours' default keeps the
  original goal (HIRO's candidate order), the code a random candidate (its order); the Ant
  presets take the code's (``relabel_ties="random"``). Without ties both rules agree."""
  assert ant_config().relabel_ties == "random"
  assert methods.build_config("paper", "ours", "PointPush")[0].relabel_ties == "original"
  tie = N_CORRECTION - 1
  _, scores, chosen, index = _correction(fx, tie, "original")
  assert np.all(scores == scores[0]) and index == 0
  np.testing.assert_array_equal(chosen, fx[f"correction/{tie}/goal"])
  assert not np.allclose(chosen, fx[f"correction/{tie}/goal_hat"])
  for i in range(N_CORRECTION - 1):
    assert _correction(fx, i, "original")[3] == _correction(fx, i, "random")[3]


# ----- d, e. the Middle and Top PPO updates ----------------------------------------------------

def _ppo_state(learner, kind, out_perm=None):
  state = learner.init(jax.random.PRNGKey(0))  # Adam's moments zeros, as the code's first
  params = {"actor": flax_mlp(fixtures.network(f"{kind}_actor")[0], out_perm),
            "critic": flax_mlp(fixtures.network(f"{kind}_critic")[0])}
  return state.replace(params=params)


def _assert_ppo_losses(m, code_losses):
  """The code's K-epoch means: total, surrogate, 0.5 x mse, -0.01 x entropy."""
  ours = [m["loss"], m["policy_loss"], 0.5 * m["value_loss"], -0.01 * m["entropy"]]
  np.testing.assert_allclose(np.array(ours, np.float64), code_losses, rtol=2e-4, atol=1e-6)


def test_middle_ppo_updates_follow_the_codes_train(fx):
  """Two ``PPO.train`` calls (10 epochs each, std 0.55 then 0.5) on rollouts of 3 from the
  same weights: the mean losses of each and the weights after both. Ours stores the Middle
  reward R_M = 0.1 x the segment's sum where the code stores the sum: the returns are
  normalised, so only the normaliser's 1e-7 sees the scale."""
  config = ant_config()
  middle_ppo = middle_lib.make_middle(30, 8, TARGET, config, None).ppo
  state = _ppo_state(middle_ppo.learner, "ppo")
  hp = lanes.of(config.middle_ppo)
  assert float(middle_ppo.std(0)) == pytest.approx(float(fx["ppo/0/std"]))
  assert float(middle_ppo.std(250_000)) == pytest.approx(float(fx["ppo/1/std"]))
  update = jax.jit(middle_ppo.learner.update)
  for k in range(2):
    rollout = ppo.Rollout(
        obs=fx[f"ppo/{k}/states"], action=fx[f"ppo/{k}/actions"].reshape(3, 3),
        log_prob=fx[f"ppo/{k}/logprobs"].reshape(3),
        reward=np.float32(hierarchy.MIDDLE_REWARD_SCALE) * fx[f"ppo/{k}/rewards"],
        done=fx[f"ppo/{k}/terminals"])
    logp = middle_ppo.learner.log_prob(state.params, rollout.obs, rollout.action,
                                 fx[f"ppo/{k}/std"])
    # the code's log pi_old of its samples: at the start weights to 1e-5; after the first
    # update ours' weights are the code's to ~1e-5, a sample 2.5 std out moves by 4e-5
    np.testing.assert_allclose(logp, rollout.log_prob, rtol=RTOL if k == 0 else 0,
                               atol=0 if k == 0 else 1e-4)
    state, m = update(state, rollout, fx[f"ppo/{k}/std"], jp.ones(3), hp)
    _assert_ppo_losses(m, fx[f"ppo/{k}/losses"])
  for part in ("actor", "critic"):
    assert_layers_close(our_layers(state.params[part]), code_layers(fx, f"ppo/after/{part}", 1),
                        PPO_WEIGHTS_ATOL, moved_from=[fixtures.network(f"ppo_{part}")[0]])


def _top(weighting):
  config = ant_config({"top.ppo.value_weighting": weighting})
  return top_lib.make_top(30, TARGET, config), lanes.of(config).top


def _top_rollout(fx, k, alpha):
  """The code's Top rollout k in ours' terms: modes in ours' order, the rewards formed by
  ours' reward modification with ``alpha`` (ours' mode order) from the raw R_m."""
  modes = PERMUTE[fx[f"top/{k}/actions"].astype(int)]
  reward = top_lib.modified_reward(jp.asarray(fx[f"top/{k}/raw_rewards"]), jp.asarray(alpha),
                                     jp.asarray(modes))
  return ppo.Rollout(obs=fx[f"top/{k}/states"], action=jp.asarray(modes, jp.int32),
                     log_prob=fx[f"top/{k}/logprobs"], reward=reward,
                     done=fx[f"top/{k}/terminals"])


def _top_updates(fx, weighting):
  """Ours' Top from the same weights (its output units permuted to ours' mode order) through
  the code's two rollouts; the metrics of each update and the final weights."""
  top, hp = _top(weighting)
  state = _ppo_state(top.ppo, "top", out_perm=PERMUTE)
  update = jax.jit(top.update)
  metrics = []
  for k in range(2):
    rollout = _top_rollout(fx, k, (0.0, 0.5, 1.0))
    state, m = update(state, rollout, jp.float32(fx[f"top/{k}/s_e"]), hp)
    metrics.append(m)
  return state, metrics


def test_top_ppo_updates_follow_the_codes_train(fx):
  """Two ``PPOM.train`` calls on rollouts of 8, the Top's rewards formed per mode, its loss
  modified per sample by S_E (1 + S_E in PPO and RANDOM, 1 - S_E in TD3): with S_E = 0, then
  0.4. Ours under the Ant preset (``top.ppo.value_weighting="batch"``) and with the code's
  reward multipliers: the losses of both and the weights after."""
  assert ant_config().top.ppo.value_weighting == "batch"
  for k in range(2):
    rollout = _top_rollout(fx, k, (0.0, 0.5, 1.0))
    np.testing.assert_array_equal(rollout.reward, fx[f"top/{k}/rewards"])
  state, metrics = _top_updates(fx, "batch")
  for k in range(2):
    _assert_ppo_losses(metrics[k], fx[f"top/{k}/losses"])
  assert_layers_close(our_layers(state.params["actor"], out_perm=PERMUTE),
                      code_layers(fx, "top/after/actor", 1), PPO_WEIGHTS_ATOL,
                      moved_from=[fixtures.network("top_actor")[0]])
  assert_layers_close(our_layers(state.params["critic"]), code_layers(fx, "top/after/critic", 1),
                      PPO_WEIGHTS_ATOL, moved_from=[fixtures.network("top_critic")[0]])


def test_top_loss_weights_the_batch_value_loss_in_the_code(fx):
  """Not in docs/fidelity.md until these fixtures: the code's PPOM adds the rollout's mean
  value loss to every sample's loss and then weights each sample by 1 +- S_E, so the value
  loss is weighted by the mean weight; ours by default weights each sample's own value error
  (``value_weighting="sample"``). With S_E = 0 (weights of 1) both agree; with S_E = 0.4 the
  critic's update differs."""
  ours, metrics = _top_updates(fx, "sample")
  _assert_ppo_losses(metrics[0], fx["top/0/losses"])  # S_E = 0: the same update
  for part in ("actor", "critic"):
    layers = our_layers(ours.params[part], out_perm=PERMUTE if part == "actor" else None)
    diff = max(np.abs(w - cw).max() for (w, _), (cw, _) in
               zip(layers[0], code_layers(fx, f"top/after/{part}", 1)[0]))
    assert diff > 30 * PPO_WEIGHTS_ATOL, part  # the critic's, and through it the advantages


def test_top_reward_multipliers_are_the_codes_1_5_and_2_not_the_texts_alpha(fx):
  """docs/fidelity.md, "Top alpha (Ant Push)": the code multiplies R_m by 1.5 (PPO) and 2
  (RANDOM), alpha (0, 0.5, 1.0); the text, which the preset follows, says (0, 0.4, 0.7). With
  the code's alpha ours' ``modified_reward`` gives the code's stored rewards exactly."""
  assert ant_config().top.alpha == (0.0, 0.4, 0.7)
  for k in range(2):
    code = fx[f"top/{k}/rewards"]
    np.testing.assert_array_equal(_top_rollout(fx, k, (0.0, 0.5, 1.0)).reward, code)
    text = np.asarray(_top_rollout(fx, k, ant_config().top.alpha).reward)
    explore = PERMUTE[fx[f"top/{k}/actions"].astype(int)] != hierarchy.TD3
    assert np.all(text[explore] != code[explore])
    np.testing.assert_array_equal(text[~explore], code[~explore])


# ----- f. the goal transition and the Low's reward ---------------------------------------------

@pytest.mark.parametrize("sequence", ["path", "near"])
def test_goal_transition_low_reward_and_task_scores_follow_the_codes(fx, sequence):
  """Along a scripted state sequence, goals set every 10 steps and carried by the goal
  transition between: g' (``h_function``), the Low's reward (``intrinsic_reward_simple``), its
  done on the step's goal ``||g|| <= 1.5`` (``done_judge_low``; the Ant preset's
  ``low_done_goal="current"``; norms of exactly 1.5 included), the task reward and success of
  the state before the step (``dense_reward``, ``success_judge``: one state exactly 5 away)."""
  config = ant_config()
  assert config.low_done_goal == "current" and config.scored_state == "current"
  low = low_lib.make_low(30, 8, 30.0, config)
  task = envs.base.MazeTask()
  task.target, task.success_radius = TARGET, 5.0
  states, decisions = fx[f"goals/{sequence}/states"], fx[f"goals/{sequence}/decisions"]
  rows, goal = [], None
  for t in range(len(states) - 1):
    goal = jp.asarray(decisions[t // 10]) if t % 10 == 0 else goal
    tr = low.transition(states[t], goal, jp.zeros(8), states[t + 1])
    scores = task.task_metrics(jp.asarray(states[t, :3]))
    rows.append(np.concatenate([goal, tr.next_context, [tr.reward, tr.done,
                                                        scores["reward_task"],
                                                        scores["success"]]]))
    goal = tr.next_context
  rows, code = np.array(rows), fx[f"goals/{sequence}/rows"]
  np.testing.assert_allclose(rows[:, :6], code[:, :6], rtol=1e-6, atol=1e-6)
  np.testing.assert_allclose(rows[:, 6], code[:, 6], rtol=1e-6)
  np.testing.assert_array_equal(rows[:, 7], code[:, 7])
  np.testing.assert_allclose(rows[:, 8], code[:, 8], rtol=1e-6)
  np.testing.assert_array_equal(rows[:, 9], code[:, 9])
  assert code[0, 7] == 1.0 and code[10, 7] == 1.0  # |g| = 1.5 exactly: done
  if sequence == "near":
    assert code[7, 9] == 1.0 and code[7, 8] == -5.0 and 0 < code[:, 9].sum() < len(code)


# ----- g. the mode switch's accounting ---------------------------------------------------------

def _scripted(params, mode):
  """The Top's params with its last layer forced: logits 0 but 50 for ``mode`` (its sample
  is ``mode`` but for a chance of e^-50)."""
  actor = params["actor"]["params"]
  last = f"dense_{len(actor) - 1}"
  forced = {"kernel": jp.zeros_like(actor[last]["kernel"]),
            "bias": 50.0 * jax.nn.one_hot(mode, 3)}
  return {**params, "actor": {"params": {**actor, last: forced}}}


def _our_accounting(fx, modes_ran):
  """Ours' Top chooser (``modes.TopChooser``: ``accumulate`` every step, ``decide`` at every
  Middle decision, ``update`` on its clock) through the scripted run, its samples forced to
  ``modes_ran`` (ours' order, one per horizon from the warm-up's end), with the code's
  settings: no starting mode, alpha (0, 0.5, 1.0). Per Top boundary after warm-up: its stored
  mode, reward and done, and S_O; per counted decision its mode; the steps it trained."""
  start, steps = int(fx["switch/start"]), len(fx["switch/reward_h"])
  config = ant_config({"warmup_steps": start, "top.starting_steps": 0,
                       "top.alpha": (0.0, 0.5, 1.0), "top.ppo.hidden": (8,)})
  hp = lanes.of(config)
  chooser = modes_lib.make_chooser(config, 30, TARGET, None)
  keys = agent_lib.InitKeys.split(jax.random.PRNGKey(0))
  state, mode = chooser.init(keys, jp.zeros((1, 30)), None)
  accumulate = jax.jit(chooser.accumulate)
  update = jax.jit(lambda s, t: chooser.update(s, t, t >= start, jp.float32(0.0), hp))

  @jax.jit
  def decide(state, mode, t, forced):
    learner = state.learner.replace(params=_scripted(state.learner.params, forced))
    d = modes_lib.Decision(t=t, episode_end=(t + 1) % 1000 == 0, obs=jp.zeros((1, 30)),
                           s_c=jp.zeros((1, 30)), reward=jp.zeros(1), middle=None)
    return chooser.decide(state.replace(learner=learner), mode, d,
                          agent_lib.StepKeys.split(jax.random.PRNGKey(1)), hp)

  horizons, decisions, trains = [], [], []
  for t in range(steps):
    state = accumulate(state, fx["switch/reward_h"][t][None], fx["switch/done_h"][t][None])
    state, m = update(state, t)
    trains += [t] if float(m["top/updated"].value) else []
    if t % 10 == 9:
      forced = modes_ran[min(max(0, (t + 1 - start) // 50), len(modes_ran) - 1)]
      state, mode, m = decide(state, mode, t, forced)
      if t % 50 == 49 and t >= start:
        slot = (t // 50) % config.top.rollout_length
        r = jax.tree.map(lambda x: np.asarray(x[0, slot]), state.rollout)
        horizons.append((t, float(m["horizon/s_o_m"].value), float(r.done), int(r.action),
                         float(r.reward)))
      if t + 1 >= start:  # agent._end_segment counts a decision from the warm-up's last step
        decisions.append((t, int(mode[0])))
  return np.array(horizons), np.array(decisions), np.array(trains)


def test_top_accounting_and_mode_counts_follow_the_codes_loop(fx):
  """The Top's bookkeeping of ``hiro.train`` (transcribed in ``reference.fixtures.
  code_top_accounting``) on a scripted run: each horizon's S_O = Done_m / Count_m, done_m at
  0.6 (30 of 50 steps: done), the reward multiplied per the mode that ran, when the Top acts
  and trains, and the on/off/random counts of Middle decisions. Ours with the code's settings
  (no starting mode, alpha (0, 0.5, 1.0)) and its samples forced to the modes the code ran.
  Two boundary differences show: the code stores a fresh sample (``tmp_action_m``) as its first
  Top transition's action where its RANDOM ran (docs/fidelity.md, "Other choices"), and ours
  counts the Middle decision at the warm-up's last step (the mode's goal for the first
  segment after warm-up; the code's is a warm-up goal) ("Warm-up's last decision")."""
  code_h, code_d, code_trains = (fx["switch/horizons"], fx["switch/decisions"],
                                 fx["switch/trains"])
  ran = PERMUTE[code_h[:, 4].astype(int)]
  horizons, decisions, trains = _our_accounting(fx, ran)
  np.testing.assert_array_equal(horizons[:, 0], code_h[:, 0])  # the Top acts at the same steps
  np.testing.assert_allclose(horizons[:, 1], code_h[:, 1], rtol=1e-6)  # S_O
  np.testing.assert_array_equal(horizons[:, 2], code_h[:, 2])  # done_m
  assert set(code_h[:, 1]) >= {0.58, 0.6, 0.62} and code_h[code_h[:, 1] == 0.6, 2].all()
  np.testing.assert_allclose(horizons[:, 4], code_h[:, 6], rtol=1e-6)  # the stored reward
  stored = PERMUTE[code_h[:, 3].astype(int)]
  np.testing.assert_array_equal(horizons[1:, 3], stored[1:])
  assert horizons[0, 3] == ran[0] == hierarchy.RANDOM  # ours: the mode that ran
  assert code_h[0, 3] == fx["switch/samples"][0]  # the code: its leftover sample
  np.testing.assert_array_equal(trains, code_trains)
  start = int(fx["switch/start"])
  assert decisions[0, 0] == start - 1 and code_d[0, 0] == start + 9
  np.testing.assert_array_equal(decisions[1:, 0], code_d[:, 0])
  np.testing.assert_array_equal(decisions[1:, 1], PERMUTE[code_d[:, 1]])
  counts = [np.sum(decisions[1:, 1] == m) for m in (hierarchy.PPO, hierarchy.TD3,
                                                    hierarchy.RANDOM)]
  np.testing.assert_array_equal(counts, code_d[-1, 2:])  # on, off, random


def test_update_schedule_after_warm_up(fx):
  """When each learner first updates after the warm-up (``hiro.train``'s conditions,
  transcribed in ``reference.fixtures.code_schedule``), against ours' agent (a tiny point
  agent with the same warm-up, c, Top horizon and rates: the gates are the same code for every
  task). The Low and the Top PPO agree at every step. Not in docs/fidelity.md until these
  fixtures ("Warm-up's end"): the code's Middle TD3 starts 30 steps after the warm-up (ours
  right after it: 3 more updates) and its Middle PPO first trains 30 steps later than ours (at
  warm-up + 50, on the 5 segments since the warm-up; ours at warm-up + 20 on 3), once a run."""
  start, code = int(fx["switch/start"]), fx["switch/schedule"]
  steps = start + 410  # past the Top's first update, at warm-up + 400
  small = {"hidden": (8,), "batch_size": 4, "buffer_size": 1000}
  config = methods.build_config("paper", "ours", "PointPush", {
      "warmup_steps": start, "top.starting_steps": 0, "eval_every": 100_000,
      "eval_episodes": 1, **{f"low.{k}": v for k, v in small.items()},
      **{f"middle.{k}": v for k, v in small.items()}, "middle_ppo.hidden": (8,),
      "top.ppo.hidden": (8,)})[0]
  assert (config.c, config.middle_ppo_every, config.top.horizon, config.top.train_every) == (
      10, 30, 50, 400)
  agent = agent_lib.make_agent(envs.make("PointPush", episode_length=100), config)
  step = jax.jit(functools.partial(agent.step, hp=lanes.of(config)))
  state = agent.init(jax.random.PRNGKey(0))
  ours = []
  for t in range(steps):
    state, m = step(state, t)
    ours.append([float(m[f"{name}/updated"].value)
                 for name in ("low", "middle", "middle_ppo", "top")])
  ours = np.array(ours).T
  np.testing.assert_array_equal(ours[0], code[0, :steps])  # the Low
  np.testing.assert_array_equal(ours[3], code[3, :steps])  # the Top (first at warm-up + 400)
  assert ours[3].sum() == 1
  first = lambda row: int(np.nonzero(row)[0][0]) - start
  assert (first(ours[1]), first(code[1])) == (9, 39)  # the Middle TD3
  assert (first(ours[2]), first(code[2])) == (19, 49)  # the Middle PPO
  np.testing.assert_array_equal(ours[1:3, start + 40:], code[1:3, start + 40:steps])
