"""Parity fixtures: numbers recorded once from the paper's own PyTorch code.

    REFERENCE_HOME=/work/reference-home python -m reference.fixtures \\
        --out tests/data/reference_fixtures.npz

Runs in the reference venv (``reference.setup``; the command re-executes itself there, as
``reference.run`` does), imports the code's modules from its folder with the ``mujoco_py`` and
``wandb`` stand-ins first on ``sys.path``, and records with fixed seeds, at the real sizes
(300-300 networks, batches of 100, rollouts of 3 and 8):

* ``env/<physics>/...``: the code's maze env (``create_maze_env("AntPush")``) from given
  qpos/qvel under scripted torques, 20 start states x 5 steps and one 100-step path, for
  ``mujoco3`` (the model as is) and ``mujoco200`` (``reference.physics``): observations, the
  task reward (``dense_reward``) and success (``success_judge``) of each state; and three of
  the env's own resets (seeded) followed by 5 steps;
* ``low/...``: three Low TD3 updates (``hiro.step_update_l``) from given weights and fresh
  Adam states, on given batches, with the code's target-policy noise (one draw of 8 numbers per
  batch, shared by its 100 samples): y, losses, and the weights after the third;
* ``middle/...``: the same for the Middle TD3 (``hiro.step_update_h``);
* ``correction/...``: ``off_policy_correction`` on given segments under a given Low actor: the
  code's standard normals, its 10 candidates (8 random, s_c - s_0, the goal), their
  ``-mse_loss`` values and the chosen goal; the last case under a Low actor blind to the goal
  (its last layer's weights zero: so are actions saturated in float32 tanh alike for every
  candidate), where all 10 candidates tie;
* ``ppo/...``: two Middle PPO updates (``ppo/PPO.py`` ``PPO.train``, std 0.55 then 0.5) on
  rollouts of 3: the code's samples and log-probabilities, losses, the weights after;
* ``top/...``: two Top PPO updates (``ppo/PPOM.py`` ``PPOM.train``) on rollouts of 8 whose
  rewards are formed per mode as ``hiro.train`` forms them (x 1.5 PPO, x 2 RANDOM), the first
  with S_E = 0, the second with S_E = 0.4 (the loss modification);
* ``goals/...``: ``h_function``, ``intrinsic_reward_simple``, ``done_judge_low``,
  ``dense_reward`` and ``success_judge`` along scripted state sequences;
* ``switch/...``: the Top's horizon accounting and the mode counts of ``hiro.train`` on a
  scripted run, and when it updates each learner. That logic is inline in ``hiro.train``;
  ``code_top_accounting`` and ``code_schedule`` below transcribe it line by line (the line
  numbers are the pinned commit's ``hiro.py``).

Network weights are not stored: ``mlp_weights(seed, sizes)`` makes them (PyTorch's
``nn.Linear`` ranges from numpy's frozen ``RandomState`` stream) here and in the tests, and each
is checked against the float64 sums recorded with it. Everything else is stored, float32 as the
code holds it (environment observations float64). The numbers come from the code; the code
itself is not in this file or the repository.
"""

import argparse
import contextlib
import datetime
import io
import json
import os
import pathlib
import platform
import shlex
import sys
import time

import numpy as np

import reference

OUT = reference.PACKAGE.parent / "tests" / "data" / "reference_fixtures.npz"
OBS, GOAL, ACT = 30, 3, 8
TARGET = (0.0, 19.0, 0.5)
MAX_GOAL = (10.0, 10.0, 0.5)
# (input, hidden, hidden, output) of every network, as the code builds them
SIZES = {
    "low_actor": (OBS + GOAL, 300, 300, ACT), "low_critic": (OBS + GOAL + ACT, 300, 300, 1),
    "middle_actor": (OBS, 300, 300, GOAL), "middle_critic": (OBS + GOAL, 300, 300, 1),
    "ppo_actor": (OBS + GOAL, 300, 300, GOAL), "ppo_critic": (OBS + GOAL, 300, 300, 1),
    "top_actor": (OBS + GOAL, 300, 300, 3), "top_critic": (OBS + GOAL, 300, 300, 1),
}
# The seed of each network's weights (a TD3 critic's second Q network: seed + 100)
SEEDS = {"low_actor": 10, "low_critic": 11, "low_target_actor": 13, "low_target_critic": 14,
         "middle_actor": 20, "middle_critic": 21, "middle_target_actor": 23,
         "middle_target_critic": 24, "ppo_actor": 30, "ppo_critic": 31, "top_actor": 40,
         "top_critic": 41}
TD3_UPDATES = 3
PHYSICS = ("mujoco3", "mujoco200")


# ----- shared with the tests (numpy only) ------------------------------------------------------

def mlp_weights(seed, sizes):
  """[(W (out, in), b (out,)), ...] float32, each entry U(-1/sqrt(in), 1/sqrt(in)) (the range
  of PyTorch's ``nn.Linear`` default) from ``np.random.RandomState(seed)``, layer by layer."""
  rs = np.random.RandomState(seed)
  layers = []
  for fan_in, fan_out in zip(sizes[:-1], sizes[1:]):
    bound = 1.0 / np.sqrt(fan_in)
    w = rs.uniform(-bound, bound, (fan_out, fan_in)).astype(np.float32)
    b = rs.uniform(-bound, bound, fan_out).astype(np.float32)
    layers.append((w, b))
  return layers


def network(name):
  """The weights of a named network (``SEEDS``); a critic is two Q networks."""
  kind = name.replace("target_", "")
  sizes, seed = SIZES[kind], SEEDS[name]
  if kind.endswith("critic") and not kind.startswith(("ppo", "top")):
    return [mlp_weights(seed, sizes), mlp_weights(seed + 100, sizes)]
  return [mlp_weights(seed, sizes)]


def checksum(nets):
  """float64 sums of every array of ``network(name)``: the tests' check of the recipe."""
  return np.array([float(np.sum(a, dtype=np.float64)) for net in nets for layer in net
                   for a in layer])


def target_subset(shape, seed=0, fraction=0.05):
  """Flat indices of the entries of a target network recorded (targets move by tau = 0.005
  per update: a sample shows the Polyak step; the online weights are recorded whole)."""
  n = int(np.prod(shape))
  rs = np.random.RandomState(seed + n)
  return np.sort(rs.choice(n, max(1, int(n * fraction)), replace=False))


# ----- the code, imported ----------------------------------------------------------------------

class _Recorder:
  """Stands for a module in the code's namespace, recording some calls' results."""

  def __init__(self, module, calls):
    self._module, self.calls = module, calls

  def __getattr__(self, name):
    return getattr(self._module, name)


def _numpy_proxy(calls):
  """numpy for ``hiro``: ``random.normal`` results recorded; ``argmax`` of a list of 0-d
  tensors that require grad taken on their float values (numpy 2 refuses them, numpy 1.18 took
  them as scalars: reference.harness)."""
  from reference.harness import _NumpyProxy

  class Random(_Recorder):
    def normal(self, *args, **kwargs):
      out = np.random.normal(*args, **kwargs)
      self.calls.append(np.array(out, dtype=np.float64))
      return out

  class Numpy(_Recorder):
    argmax = staticmethod(_NumpyProxy.argmax)

  proxy = Numpy(np, calls)
  proxy.random = Random(np.random, calls)
  return proxy


def _functional_proxy(calls):
  """torch.nn.functional for ``hiro``: ``mse_loss`` values recorded (the correction's
  candidates are scored by ``-mse_loss``)."""
  import torch.nn.functional as F

  class Functional(_Recorder):
    def mse_loss(self, *args, **kwargs):
      out = F.mse_loss(*args, **kwargs)
      self.calls.append(float(out.detach()))
      return out

  return Functional(F, calls)


class Code:
  """The code's modules, imported from its folder as the harness does."""

  def __init__(self, folder):
    sys.path[:0] = [str(reference.STANDINS), str(folder)]
    os.chdir(folder)  # maze_env.py finds its XML under os.getcwd(); run.py reads ./*.csv
    import torch
    torch.set_num_threads(1)
    self.torch = torch
    sys.argv = ["run.py", "--alg", "hiro_train", "--param_id", "1", "--seed", "0"]
    with contextlib.redirect_stdout(io.StringIO()):
      import hiro
      import mujoco_py
      import run
      import utils
      from ppo import PPO, PPOM
      self.params, _ = run.load_params(1)
    self.hiro, self.utils, self.mujoco_py = hiro, utils, mujoco_py
    self.PPO, self.PPOM = PPO.PPO, PPOM.PPOM
    self.normal_calls, self.mse_calls = [], []
    hiro.np = _numpy_proxy(self.normal_calls)
    hiro.functional = _functional_proxy(self.mse_calls)
    quiet = lambda *args, **kwargs: None
    for module in (hiro, utils, run, PPO, PPOM):
      module.print = quiet

  def tensor(self, x):
    return self.torch.tensor(np.asarray(x, np.float32))


def _load(module, layers):
  """Copy [(W, b), ...] into the Linear layers of an nn.Sequential, in order."""
  import torch
  linears = [m for m in module if isinstance(m, torch.nn.Linear)]
  assert len(linears) == len(layers)
  for linear, (w, b) in zip(linears, layers):
    linear.weight.data.copy_(torch.from_numpy(w))
    linear.bias.data.copy_(torch.from_numpy(b))


def _dump(module):
  import torch
  return [(m.weight.detach().numpy().copy(), m.bias.detach().numpy().copy())
          for m in module if isinstance(m, torch.nn.Linear)]


def _put(out, prefix, nets, subset=False):
  """Store a list of networks' layers under ``prefix/<net>/<layer>/{W,b}`` (whole, or the
  ``target_subset`` entries as ``Wi``/``bi`` index and ``W``/``b`` values)."""
  for n, net in enumerate(nets):
    for i, (w, b) in enumerate(net):
      for name, a in (("W", w), ("b", b)):
        key = f"{prefix}/{n}/{i}/{name}"
        if subset:
          index = target_subset(a.shape)
          out[key + "i"] = index.astype(np.int32)
          out[key] = a.reshape(-1)[index]
        else:
          out[key] = a


# ----- a. the env ------------------------------------------------------------------------------

def start_states(rs, n=20):
  """``n`` (qpos (17,), qvel (16,), t) start states of Ant Push: the ant around its start
  cell, some against the block's face (y up to 3), a few with the block moved; the torso's
  quaternion a unit one in float32 (ours normalises it in float32)."""
  qpos = np.zeros((n, 17))
  qpos[:, 0] = rs.uniform(-3.0, 3.0, n)
  qpos[:, 1] = rs.uniform(-2.0, 3.0, n)
  qpos[:, 2] = rs.uniform(0.5, 0.8, n)
  quat = np.array([1.0, 0.0, 0.0, 0.0]) + rs.uniform(-0.15, 0.15, (n, 4))
  quat = quat.astype(np.float32)
  qpos[:, 3:7] = quat / np.linalg.norm(quat, axis=1, keepdims=True)
  qpos[:, 7:15] = np.tile([0, 1, 0, -1, 0, -1, 0, 1], (n, 1)) * 0.7 + rs.uniform(-0.4, 0.4,
                                                                                 (n, 8))
  qpos[n - 4:, 15:17] = rs.uniform(-1.5, 1.5, (4, 2))  # the block moved
  qvel = rs.normal(0.0, 0.5, (n, 16))
  qvel[:, 14:] = 0.0
  qvel[n - 2:, 14:] = rs.normal(0.0, 0.3, (2, 2))  # and moving
  t = rs.randint(0, 900, n)
  return qpos.astype(np.float32).astype(np.float64), qvel.astype(np.float32).astype(
      np.float64), t


def _run_env(code, env, qpos, qvel, t0, actions):
  """From (qpos, qvel) at episode step t0, step the scripted actions; (obs (T+1, 30) float64,
  reward and success (T+1,) of each state, by the code's dense_reward and success_judge)."""
  hiro, target = code.hiro, code.tensor(TARGET)
  env.reset()
  env.wrapped_env.set_state(qpos, qvel)
  env.t = int(t0)
  obs = [env._get_obs()]
  for a in actions:
    obs.append(env.step(np.asarray(a, np.float32))[0])
  obs = np.array(obs)
  reward = [float(hiro.dense_reward(code.tensor(o), GOAL, target)) for o in obs]
  success = [float(hiro.success_judge(code.tensor(o), GOAL, target)[0]) for o in obs]
  return obs, np.array(reward, np.float32), np.array(success, np.float32)


def _record_resets(env, actions, out, prefix):
  """The code's own resets (``reset_model``: qpos0 + U(-0.1, 0.1) on all 15 of the ant's
  qpos, its quaternion included, not normalised), the ant seeded, then scripted steps: the
  reset qpos and qvel, and the observations."""
  qpos, qvel, obs = [], [], []
  for i, steps in enumerate(actions):
    env.wrapped_env.seed(1000 + i)
    states = [env.reset()]
    qpos.append(env.wrapped_env.sim.data.qpos.copy())
    qvel.append(env.wrapped_env.sim.data.qvel.copy())
    states += [env.step(a)[0] for a in steps]
    obs.append(states)
  out.update({prefix + "_qpos": np.array(qpos), prefix + "_qvel": np.array(qvel),
              prefix + "_obs": np.array(obs)})


def record_env(code, out):
  """a. 20 start states x 5 steps and a 100-step path, under each engine setting."""
  from reference import physics
  rs = np.random.RandomState(1)
  qpos, qvel, t0 = start_states(rs)
  actions = rs.uniform(-30.0, 30.0, (len(t0), 5, ACT)).astype(np.float32)
  path_qpos = np.zeros(17)
  path_qpos[2] = 0.75
  path_qpos[3] = 1.0
  path_qpos[:15] += rs.uniform(-0.1, 0.1, 15)  # the code's reset_model
  quat = path_qpos[3:7].astype(np.float32)
  path_qpos[3:7] = quat / np.linalg.norm(quat)
  path_qpos = path_qpos.astype(np.float32).astype(np.float64)
  path_qvel = np.zeros(16)
  path_qvel[:14] = (rs.normal(0.0, 1.0, 14) * 0.1).astype(np.float32)
  path_actions = rs.uniform(-30.0, 30.0, (100, ACT)).astype(np.float32)
  out.update({"env/qpos": qpos, "env/qvel": qvel, "env/t": t0, "env/actions": actions,
              "env/path_qpos": path_qpos, "env/path_qvel": path_qvel,
              "env/path_actions": path_actions})
  for name in PHYSICS:
    code.mujoco_py.set_model_hook(physics.hook(name))
    env = code.utils.create_maze_env("AntPush")
    runs = [_run_env(code, env, q, v, t, a) for q, v, t, a in zip(qpos, qvel, t0, actions)]
    for i, key in enumerate(("obs", "reward", "success")):
      out[f"env/{name}/{key}"] = np.stack([r[i] for r in runs])
    path = _run_env(code, env, path_qpos, path_qvel, 0, path_actions)
    for i, key in enumerate(("obs", "reward", "success")):
      out[f"env/{name}/path_{key}"] = path[i]
    _record_resets(env, actions[:3], out, f"env/{name}/reset")
  code.mujoco_py.set_model_hook(None)
  return out["env/mujoco3/path_obs"]


# ----- b, c. the Low and Middle TD3 updates ----------------------------------------------------

class _GivenBatch:
  """Stands for the code's replay buffer: ``sample`` returns the given batch."""

  def __init__(self, tensors):
    self.tensors = tensors

  def sample(self, batch_size):
    assert batch_size == len(self.tensors[0])
    return self.tensors


def low_batch(rs, n=100):
  """(s, g, a, r, s', g', done) as the Low buffer holds them: r = -||g'||, g' = h(s, g, s'),
  done = ||g|| <= 1.5 (a fifth of the goals are within it)."""
  s = rs.normal(0.0, 1.0, (n, OBS))
  s[:, :3] = rs.uniform(-10.0, 20.0, (n, 3))
  s_next = s + rs.normal(0.0, 0.3, (n, OBS))
  g = rs.uniform(-10.0, 10.0, (n, GOAL)) * np.array([1.0, 1.0, 0.05])
  g[: n // 5] *= 0.1
  a = rs.uniform(-30.0, 30.0, (n, ACT))
  g_next = s[:, :3] + g - s_next[:, :3]
  r = -np.linalg.norm(g_next, axis=1, keepdims=True)
  done = (np.linalg.norm(g, axis=1, keepdims=True) <= 1.5).astype(np.float64)
  return [x.astype(np.float32) for x in (s, g, a, r, s_next, g_next, done)]


def middle_batch(rs, n=100):
  """(s_0, g, R (the sum of 10 task rewards, unscaled), s_c, done = success at s_c)."""
  s = rs.normal(0.0, 1.0, (n, OBS))
  s[:, :3] = rs.uniform(-10.0, 20.0, (n, 3))
  s_end = s + rs.normal(0.0, 0.5, (n, OBS))
  g = rs.uniform(-1.0, 1.0, (n, GOAL)) * np.array(MAX_GOAL)
  r = -10.0 * np.linalg.norm(s[:, :3] - np.array(TARGET), axis=1, keepdims=True)
  done = (rs.uniform(size=(n, 1)) < 0.2).astype(np.float64)
  return [x.astype(np.float32) for x in (s, g, r, s_end, done)]


def _td3_nets(code, level):
  """The code's actor, critic and their targets for a level, with the recipe's weights."""
  hiro, pp = code.hiro, code.params.policy_params
  if level == "low":
    make_actor = lambda: hiro.ActorLow(OBS, GOAL, ACT, pp.max_action)
    make_critic = lambda: hiro.CriticLow(OBS, GOAL, ACT)
  else:
    make_actor = lambda: hiro.ActorHigh(OBS, GOAL, pp.max_goal, "cpu")
    make_critic = lambda: hiro.CriticHigh(OBS, GOAL)
  nets = {}
  for name, make in (("actor", make_actor), ("critic", make_critic),
                     ("target_actor", make_actor), ("target_critic", make_critic)):
    module = make()
    layers = network(f"{level}_{name}")
    if name.endswith("critic"):
      _load(module.fc1, layers[0])
      _load(module.fc2, layers[1])
    else:
      _load(module.fc, layers[0])
    nets[name] = module
  return nets


def _dump_td3(module):
  if hasattr(module, "fc1"):
    return [_dump(module.fc1), _dump(module.fc2)]
  return [_dump(module.fc)]


def record_td3(code, out, level):
  """b (Low, ``step_update_l``) and c (Middle, ``step_update_h``): TD3_UPDATES updates from
  fresh Adam states (``create_rl_components``'s optimisers), each on a given batch."""
  torch, hiro, pp = code.torch, code.hiro, code.params.policy_params
  nets = _td3_nets(code, level)
  actor_opt = torch.optim.Adam(nets["actor"].parameters(), lr=pp.actor_lr)
  critic_opt = torch.optim.Adam(nets["critic"].parameters(), lr=pp.critic_lr)
  update = hiro.step_update_l if level == "low" else hiro.step_update_h
  rs = np.random.RandomState(2 if level == "low" else 3)
  np.random.seed(4 if level == "low" else 5)
  total_it = [0]
  for name in ("actor", "critic", "target_actor", "target_critic"):
    out[f"{level}/checksum/{name}"] = checksum(network(f"{level}_{name}"))
  for k in range(TD3_UPDATES):
    batch = low_batch(rs) if level == "low" else middle_batch(rs)
    code.normal_calls.clear()
    y, critic_loss, actor_loss = update(
        _GivenBatch([torch.from_numpy(x) for x in batch]), len(batch[0]), total_it,
        nets["actor"], nets["target_actor"], nets["critic"], nets["target_critic"],
        critic_opt, actor_opt, code.params)
    for i, x in enumerate(batch):
      out[f"{level}/{k}/batch/{i}"] = x
    out[f"{level}/{k}/noise"] = np.array(code.normal_calls[:1]).reshape(-1)  # Low only
    out[f"{level}/{k}/y"] = y.numpy().reshape(-1)
    out[f"{level}/{k}/critic_loss"] = np.float32(critic_loss)
    out[f"{level}/{k}/actor_loss"] = np.float32(actor_loss)
  _put(out, f"{level}/after/actor", _dump_td3(nets["actor"]))
  _put(out, f"{level}/after/critic", _dump_td3(nets["critic"]))
  _put(out, f"{level}/after/target_actor", _dump_td3(nets["target_actor"]), subset=True)
  _put(out, f"{level}/after/target_critic", _dump_td3(nets["target_critic"]), subset=True)
  out[f"{level}/params"] = np.array([pp.actor_lr, pp.critic_lr, pp.discount, pp.tau,
                                     pp.policy_noise_std, pp.policy_noise_scale,
                                     pp.policy_noise_clip, pp.reward_scal_l,
                                     pp.reward_scal_h, pp.max_action], np.float64)


# ----- c. the off-policy correction ------------------------------------------------------------

def _correction_segments(code, path_obs, actor, rs):
  """Segments (10 + 1 states, 10 Low actions, the goal): from the env path's states, with
  actions the Low actor's for the goal (+ N(0, 1)), for s_c - s_0, for a third goal, or
  random torques; so that the chosen candidate varies."""
  torch = code.torch
  segments = []
  for case in range(8):
    start = 10 * case
    states = path_obs[start:start + 11].astype(np.float32)
    goal = (rs.uniform(-1.0, 1.0, GOAL) * np.array(MAX_GOAL)).astype(np.float32)
    kind = case % 4
    if kind == 3:
      actions = rs.uniform(-30.0, 30.0, (10, ACT)).astype(np.float32)
    else:
      explained = {0: goal, 1: states[10, :3] - states[0, :3],
                   2: (rs.uniform(-1.0, 1.0, GOAL) * np.array(MAX_GOAL)).astype(np.float32)}
      g = explained[kind] + states[0, :3] - states[:10, :3]
      with torch.no_grad():
        a = actor(torch.from_numpy(states[:10]), torch.from_numpy(g.astype(np.float32)))
      actions = np.clip(a.numpy() + rs.normal(0.0, 1.0, (10, ACT)), -30, 30).astype(np.float32)
    segments.append((states, actions, goal))
  return segments


def record_correction(code, out, path_obs):
  """``off_policy_correction`` under the Low's target actor (the recipe's
  ``low_target_actor``), each call after ``np.random.seed(100 + i)``."""
  torch, hiro = code.torch, code.hiro
  actor = _td3_nets(code, "low")["target_actor"]
  blind = _td3_nets(code, "low")["target_actor"]
  blind.fc[4].weight.data.zero_()  # actions that do not depend on the goal: every candidate ties
  max_goal = code.tensor(MAX_GOAL)
  rs = np.random.RandomState(6)
  segments = _correction_segments(code, path_obs, actor, rs)
  segments.append(segments[3])
  for i, (states, actions, goal) in enumerate(segments):
    actor = blind if i == len(segments) - 1 else actor
    np.random.seed(100 + i)
    code.normal_calls.clear()
    code.mse_calls.clear()
    goal_hat, updated = hiro.off_policy_correction(
        actor, [torch.from_numpy(a) for a in actions], [torch.from_numpy(s) for s in states[:10]],
        GOAL, torch.from_numpy(goal), torch.from_numpy(states[10]), max_goal, "cpu")
    draws = np.stack(code.normal_calls)  # 8 x np.random.normal(loc=mean, scale=std, size=3)
    mean = states[10, :3] - states[0, :3]
    z = (draws - mean.astype(np.float64)) / (0.5 * np.array(MAX_GOAL, np.float32))
    np.random.seed(100 + i)
    z_drawn = np.random.standard_normal((8, GOAL))  # the same stream: loc + scale * gauss
    assert np.allclose(z, z_drawn, rtol=0, atol=1e-6), "the draws are not loc + scale * z"
    bound = np.array(MAX_GOAL, np.float32)
    randoms = np.clip(draws.astype(np.float32), -bound, bound)
    candidates = np.concatenate([randoms, mean[None], goal[None]])
    index = int(np.argmax([-v for v in code.mse_calls]))  # ties: the first, as the code
    assert np.array_equal(goal_hat.numpy(), candidates[index]), "candidates transcribed wrong"
    assert bool(updated) == (index != 9)
    for key, value in (("states", states), ("actions", actions), ("goal", goal),
                       ("z", z_drawn), ("candidates", candidates),
                       ("scores", -np.array(code.mse_calls, np.float32)),
                       ("index", np.int32(index)), ("goal_hat", goal_hat.numpy())):
      out[f"correction/{i}/{key}"] = value


# ----- d, e. the Middle and Top PPO updates ----------------------------------------------------

def ppo_states(rs, n):
  """(n, 33) PPO inputs (s, target) as the code concatenates them."""
  s = rs.normal(0.0, 1.0, (n, OBS))
  s[:, :3] = rs.uniform(-10.0, 20.0, (n, 3))
  return np.concatenate([s, np.tile(TARGET, (n, 1))], axis=1).astype(np.float32)


def code_top_reward(r_m, action_m):
  """The Top's stored reward for a horizon run in the code's mode ``action_m`` (0 PPO, 1 TD3,
  2 RANDOM): ``hiro.train``, lines 719-729, transcribed."""
  r = np.float32(r_m)
  if action_m == 0:
    return r + 0.5 * r
  if action_m == 2:
    return r + r
  return r


def _ppo_agent(code, kind):
  """The code's Middle PPO (``hiro.train``: PPO(30, 3, 3, 3e-4, 1e-3, 0.99, 10, 0.2, True,
  0.6)) or Top PPO (PPOM(30, 3, 3, ..., False, 0.6)), with the recipe's weights."""
  if kind == "ppo":
    agent = code.PPO(OBS, GOAL, GOAL, 3e-4, 1e-3, 0.99, 10, 0.2, True, 0.6)
  else:
    agent = code.PPOM(OBS, 3, GOAL, 3e-4, 1e-3, 0.99, 10, 0.2, False, 0.6)
  _load(agent.policy.actor, network(f"{kind}_actor")[0])
  _load(agent.policy.critic, network(f"{kind}_critic")[0])
  agent.policy_old.load_state_dict(agent.policy.state_dict())
  return agent


def _rollout(code, agent, states, rewards, terminals, success_rate=None):
  """Fill the agent's buffer as ``hiro.train`` does (``select_action`` per state: the code's
  own sample and log-probability; ``rewards`` a list, or a function of the sampled actions),
  then ``train``; the actions, log-probabilities, rewards and the 4 mean losses."""
  for s in states:
    agent.select_action(s)
  actions = code.torch.stack(agent.buffer.actions).numpy()
  logprobs = code.torch.stack(agent.buffer.logprobs).numpy()
  if callable(rewards):
    rewards = rewards(actions)
  agent.buffer.rewards.extend(rewards)
  agent.buffer.is_terminals.extend(terminals)
  if success_rate is not None:
    agent.buffer.success_rates.extend(success_rate)
  losses = np.array(agent.train(), np.float64)  # total, surrogate, value (0.5 mse), entropy
  return actions, logprobs, np.array(rewards, np.float32), losses


def record_ppo(code, out):
  """d. Two Middle PPO updates on rollouts of 3 (every 30 env steps): std 0.55 (the code's
  0.6 decayed at t = 0), then 0.5 (its decay at 250K). Rewards are segment sums of 10 task
  rewards, unscaled (the code's); terminal = success."""
  code.torch.manual_seed(7)
  rs = np.random.RandomState(7)
  agent = _ppo_agent(code, "ppo")
  for k in range(2):
    agent.decay_action_std(0.05, 0.1)
    states = ppo_states(rs, 3)
    rewards = list((-10.0 * rs.uniform(5.0, 20.0, 3)).astype(np.float32))
    terminals = [False, k == 0, False]
    actions, logprobs, rewards, losses = _rollout(code, agent, states, rewards, terminals)
    for key, value in (("states", states), ("actions", actions), ("logprobs", logprobs),
                       ("rewards", rewards),
                       ("terminals", np.array(terminals, np.float32)),
                       ("std", np.float32(agent.action_std)), ("losses", losses)):
      out[f"ppo/{k}/{key}"] = value
  out["ppo/checksum/actor"] = checksum(network("ppo_actor"))
  out["ppo/checksum/critic"] = checksum(network("ppo_critic"))
  _put(out, "ppo/after/actor", [_dump(agent.policy.actor)])
  _put(out, "ppo/after/critic", [_dump(agent.policy.critic)])


def record_top(code, out):
  """e. Two Top PPO updates on rollouts of 8 (every 400 env steps, a horizon of 50): rewards
  R_m (sums of 50 task rewards) formed per mode (``code_top_reward``), done_m as stored; the
  first with S_E = 0 stored for every transition, the second with S_E = 0.4."""
  code.torch.manual_seed(8)
  rs = np.random.RandomState(8)
  agent = _ppo_agent(code, "top")
  for k, s_e in enumerate((0.0, 0.4)):
    states = ppo_states(rs, 8)
    raw = (-50.0 * rs.uniform(3.0, 20.0, 8)).astype(np.float32)
    terminals = list(rs.uniform(size=8) < 0.25)
    # the stored action is the mode that ran the horizon (the first one stored after warm-up
    # is the leftover tmp_action_m: not modelled here), its reward formed for that mode
    formed = lambda actions: [code_top_reward(r, int(m)) for r, m in zip(raw, actions)]
    actions, logprobs, rewards, losses = _rollout(code, agent, states, formed, terminals,
                                                  [s_e] * 8)
    for key, value in (("states", states), ("actions", actions), ("logprobs", logprobs),
                       ("raw_rewards", raw), ("rewards", rewards),
                       ("terminals", np.array(terminals, np.float32)),
                       ("s_e", np.float32(s_e)), ("losses", losses)):
      out[f"top/{k}/{key}"] = value
  out["top/checksum/actor"] = checksum(network("top_actor"))
  out["top/checksum/critic"] = checksum(network("top_critic"))
  _put(out, "top/after/actor", [_dump(agent.policy.actor)])
  _put(out, "top/after/critic", [_dump(agent.policy.critic)])


# ----- f. the goal transition and the Low's reward ---------------------------------------------

def _goal_run(code, states, decisions):
  """Along ``states`` (T + 1, 30): a scripted goal at each Middle decision (every 10 steps),
  ``h_function`` between them (``hiro.train`` lines 677 and 880); per step the code's
  h_function, intrinsic_reward_simple, done_judge_low (the step's goal, line 679),
  dense_reward and success_judge (the state before the step, lines 673-674)."""
  hiro, target = code.hiro, code.tensor(TARGET)
  rows, goal = [], None
  for t in range(len(states) - 1):
    s, s_next = code.tensor(states[t]), code.tensor(states[t + 1])
    if t % 10 == 0:
      goal = code.tensor(decisions[t // 10])
    g_next = hiro.h_function(s, goal, s_next, GOAL)
    rows.append(np.concatenate([
        goal.numpy(), g_next.numpy(),
        [float(hiro.intrinsic_reward_simple(s, goal, s_next, GOAL)),
         float(hiro.done_judge_low(goal)[0]), float(hiro.dense_reward(s, GOAL, target)),
         float(hiro.success_judge(s, GOAL, target)[0])]]))
    goal = g_next
  return np.array(rows, np.float32)


def record_goals(code, out, path_obs):
  """f. Two scripted sequences: the env path (100 steps), and 40 states random-walking near
  the target (one exactly 5 from it). Decision goals include norms of exactly 1.5."""
  rs = np.random.RandomState(9)
  near = np.tile(rs.normal(0.0, 1.0, OBS), (41, 1)).astype(np.float32)
  near[:, :3] = np.array(TARGET) + np.cumsum(rs.normal(0.0, 1.5, (41, 3)), axis=0)
  near[7, :3] = (0.0, 14.0, 0.5)  # exactly 5 from the target
  sequences = {"path": path_obs.astype(np.float32), "near": near}
  for name, states in sequences.items():
    n = (len(states) - 1 + 9) // 10
    decisions = (rs.uniform(-1.0, 1.0, (n, GOAL)) * np.array(MAX_GOAL)).astype(np.float32)
    decisions[0] = (1.5, 0.0, 0.0)
    decisions[1] = (0.0, 0.0, 1.5)
    decisions[2] *= 0.05
    out[f"goals/{name}/states"] = states
    out[f"goals/{name}/decisions"] = decisions
    out[f"goals/{name}/rows"] = _goal_run(code, states, decisions)


# ----- g. the mode switch's accounting ---------------------------------------------------------

def code_top_accounting(reward_h, done_h, samples, start, episode_len, c=10, c_m=50,
                        update_m=400):
  """The Top's horizon accounting and the mode counts of ``hiro.train``, transcribed line by
  line (it is inline in the loop; line numbers of the pinned ``hiro.py``). ``reward_h[t]``,
  ``done_h[t]``: the task reward and success of the state before step t (lines 673-674);
  ``samples``: what ``ppom_agent.select_action`` returns, in call order. Returns one row per
  Top boundary (t, S_O ratio, done_m, the action stored with this transition, the mode that
  ran, R_m, the stored reward), one per counted Middle decision (t, action_m, on_policy_count,
  off_policy_count, random_policy_count) and the steps at which the Top trains."""
  sample = iter(samples)
  action_m, m_flag = 2, False  # lines 589, 637
  reward_m, count_m, done_count_m = np.float32(0), 0, 0  # lines 634-636
  on = off = rnd = 0  # lines 584-586
  episode_timestep_h = 1  # line 655
  horizons, decisions, trains = [], [], []
  for t in range(len(reward_h)):
    reward_m = np.float32(reward_m + np.float32(reward_h[t]))  # line 693
    done_count_m += int(done_h[t] != 0)  # lines 695-696
    count_m += 1  # line 697
    if (t + 1) % c_m == 0 and t > 0:  # line 709
      if t >= start:  # line 710
        ratio = done_count_m / count_m  # line 711
        done_m = ratio >= 0.6  # line 712
        stored = action_m
        if not m_flag:  # lines 716-718: the first stored action is a fresh sample
          stored, m_flag = next(sample), True
        reward = code_top_reward(reward_m, action_m)  # lines 720-729
        if (t + 1) >= start + update_m and (t + 1) % update_m == 0:  # line 734
          trains.append(t)
        horizons.append((t, ratio, done_m, stored, action_m, reward_m, reward))
        action_m = next(sample)  # line 749
      reward_m, count_m, done_count_m = np.float32(0), 0, 0  # lines 751-753
    if (t + 1) % c == 0 and t > 0 and t >= start:  # lines 755, 758: the mode's goal, counted
      on, off, rnd = on + (action_m == 0), off + (action_m == 1), rnd + (action_m == 2)
      decisions.append((t, action_m, on, off, rnd))
    if episode_timestep_h >= episode_len:  # line 915: the episode's end
      reward_m, count_m, done_count_m = np.float32(0), 0, 0  # line 926
      episode_timestep_h = 0
    episode_timestep_h += 1  # line 929
  return (np.array(horizons, np.float64), np.array(decisions, np.int64),
          np.array(trains, np.int64))


def code_schedule(start, steps, c=10, middle_ppo_every=30, top_every=400):
  """When ``hiro.train`` updates each learner (lines 883, 901, 777, 734): the steps t of the
  Low TD3, Middle TD3, Middle PPO and Top PPO updates, each as a 0/1 row over ``steps``."""
  t = np.arange(steps)
  return np.stack([t >= start,  # line 883
                   (t >= start + middle_ppo_every) & ((t + 1) % c == 0),  # line 901
                   (t + 1 >= start + middle_ppo_every) & ((t + 1) % middle_ppo_every == 0)
                   & (t >= start),  # lines 758, 777 (in the branch of t >= start)
                   (t + 1 >= start + top_every) & ((t + 1) % top_every == 0)
                   & (t >= start)]).astype(np.int8)  # lines 710, 734


def record_switch(out):
  """g. A scripted run of 2,800 steps after a warm-up of 400 (a multiple of the Top's 400, as
  the code's 100K is), 1,000-step episodes: each Top horizon given a number of successes (0,
  29, 30 = 0.6 exactly, 31, 50, or random) and rewards; random Top samples."""
  rs = np.random.RandomState(10)
  start, steps, episode_len = 400, 3200, 1000
  successes = rs.choice([0, 29, 30, 31, 50, 10, 45], steps // 50)
  done_h = np.zeros(steps, np.float32)
  for h, k in enumerate(successes):
    done_h[h * 50 + rs.choice(50, k, replace=False)] = 1.0
  reward_h = (-np.abs(rs.normal(10.0, 5.0, steps))).astype(np.float32)
  samples = rs.randint(0, 3, steps // 50 + 1)
  horizons, decisions, trains = code_top_accounting(reward_h, done_h, samples, start,
                                                    episode_len)
  out.update({"switch/reward_h": reward_h, "switch/done_h": done_h, "switch/samples": samples,
              "switch/start": np.int64(start), "switch/episode_len": np.int64(episode_len),
              "switch/horizons": horizons, "switch/decisions": decisions,
              "switch/trains": trains, "switch/schedule": code_schedule(start, steps)})


# ----- the command -----------------------------------------------------------------------------

def record(code_folder, out_path, command):
  """Record every case into one compressed ``.npz`` with its metadata (key ``meta``)."""
  start = time.time()
  code = Code(code_folder)
  out = {}
  path_obs = record_env(code, out)
  for level in ("low", "middle"):
    record_td3(code, out, level)
  record_correction(code, out, path_obs)
  record_ppo(code, out)
  record_top(code, out)
  record_goals(code, out, path_obs)
  record_switch(out)
  import gym
  import mujoco
  meta = {"command": command, "code": {"upstream": reference.UPSTREAM,
                                       "commit": reference.COMMIT, "folder": reference.FOLDER},
          "packages": {"torch": code.torch.__version__, "numpy": np.__version__,
                       "gym": gym.__version__, "mujoco": mujoco.__version__,
                       "python": platform.python_version()},
          "torch_threads": code.torch.get_num_threads(), "cpu": platform.processor(),
          "date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
          "seconds": round(time.time() - start, 1), "sizes": SIZES, "seeds": SEEDS,
          "physics": PHYSICS, "td3_updates": TD3_UPDATES}
  out["meta"] = np.array(json.dumps(meta))
  out_path.parent.mkdir(parents=True, exist_ok=True)
  np.savez_compressed(out_path, **out)
  print(f"{out_path}: {len(out)} arrays, {out_path.stat().st_size / 1e6:.2f} MB, "
        f"{meta['seconds']} s")


def read(path=OUT):
  """The fixtures as a dict of arrays, and their metadata."""
  with np.load(path) as data:
    arrays = {k: data[k] for k in data.files}
  return arrays, json.loads(str(arrays.pop("meta")))


def main(argv=None):
  argv = sys.argv[1:] if argv is None else argv
  p = argparse.ArgumentParser(prog="python -m reference.fixtures", description=__doc__,
                              formatter_class=argparse.RawDescriptionHelpFormatter)
  p.add_argument("--out", default=str(OUT), help="the .npz to write")
  p.add_argument("--venv", default=os.environ.get("REFERENCE_VENV"),
                 help="the reference venv (default: $REFERENCE_VENV or reference/.code/venv)")
  p.add_argument("--code", default="", help="the code folder (default: the fetched one)")
  p.add_argument("--in-venv", action="store_true", help=argparse.SUPPRESS)
  args = p.parse_args(argv)
  out = pathlib.Path(args.out).resolve()
  folder = pathlib.Path(args.code).resolve() if args.code else reference.code_dir()
  if not (folder / "hiro.py").exists():
    raise SystemExit("the paper's code is not fetched: run python -m reference.setup first")
  if args.in_venv:
    record(folder, out, os.environ.get("FIXTURES_COMMAND", ""))
    return 0
  venv = pathlib.Path(args.venv) if args.venv else reference.default_venv()
  python = venv / "bin" / "python"
  if not python.exists():
    raise SystemExit(f"no reference venv at {venv}: run python -m reference.setup first")
  command = "python -m reference.fixtures " + shlex.join(argv)
  env = dict(os.environ, PYTHONPATH=str(reference.PACKAGE.parent), FIXTURES_COMMAND=command)
  os.execve(str(python), [str(python), "-m", "reference.fixtures", "--in-venv", "--out",
                          str(out), "--code", str(folder)], env)


if __name__ == "__main__":
  sys.exit(main())
