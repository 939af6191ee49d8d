"""The worker: the paper's ``hiro.train`` run in this process, hooked from outside.

Run inside the reference venv by ``reference.run`` (``python -m reference.harness
CONFIG.json``). Nothing of the code's source is edited; the harness replaces module
attributes after importing it:

* ``utils.create_maze_env``: each env made (the run's first by ``run.load_params``, the
  training env, each evaluation's and each video rollout's) gets its ant's ``np_random`` and
  its action space's generator seeded from (seed, how many envs were made before it);
* ``environments.maze_env.tempfile``: the model file each env writes is removed once the env
  has loaded it, and its descriptor closed (``_XmlFiles``; the code leaves both);
* ``hiro.np`` (numpy seen through a proxy) and ``gym.spaces.Box.sample``: the first call of
  each loop iteration (the Low's exploration noise, or the warm-up's random action) calls the
  harness's loop hook first, which writes rows and checkpoints, or on resume restores one;
* ``hiro.create_rl_components``: on resume, the loop starts at the checkpoint's ``t``;
* ``hiro.evaluate`` / ``hiro.evaluate_higher_policy``: timed, and each episode's last torso
  position recorded (or the batched evaluation used, ``reference.evaluation``);
* ``hiro.intrinsic_reward_simple``: summed for the Low's mean intrinsic reward per window;
* ``hiro.save_checkpoint`` (the code's is a no-op): its call after the loop saves the final
  weights and ends the run there (skipping the code's three closing video rollouts, which
  log nothing);
* ``print`` in the code's modules: discarded, or written to ``--code-output``.
"""

import builtins
import contextlib
import dataclasses
import json
import os
import pathlib
import platform
import random
import subprocess
import sys
import tempfile
import time

import numpy as np

import reference
from reference import logs as logs_lib

STANDINS = reference.STANDINS
TORCH_DEFAULT_SEED = 67280421310721  # torch 1.x's default CPU generator seed


@dataclasses.dataclass
class Config:
  """One run's settings (saved as the folder's config.json)."""

  out: str
  seed: int = 0
  steps: int = 1_100_000  # the code's max_timestep (the Low buffer is sized for it)
  start_timestep: int = 100_000
  evaluation_interval: int = 10_000
  episode_len: int = 0  # 0: the CSV's (1000); tests only
  threads: int = 1
  seeded: bool = True
  physics: str = "as-is"
  eval: str = "code"  # "code", "batched" (the TD3 evaluation batched), "batched-td3" (no PPO's)
  eval_episodes: int = 50  # tests only: fewer episodes (the code still divides by 50)
  checkpoint_every: int = 10_000
  window: int = 5_000
  stop_at: int = 0  # tests: stop at the top of this iteration, after its checkpoint
  warnings: str = "raise"  # MuJoCo warnings: "raise" (mujoco_py's behaviour) or "count"
  code_output: str = ""  # a file for the code's prints ("" discards them)
  code: str = ""  # the code folder (holding run.py); "" = reference.code_dir()
  command: str = ""

  # Fields a resumed run may change (``out``: where the folder lies now, so that a folder
  # copied or moved with its checkpoint resumes where it is).
  FREE = ("out", "stop_at", "command", "code_output", "steps", "warnings")


class Stop(BaseException):
  """Ends the run at ``stop_at`` (not caught by the code's ``except Exception``)."""


class Finished(BaseException):
  """Ends the run after the loop, once the final weights are saved."""


def _physics_hook(name):
  """The function applied to each loaded MjModel for ``--physics NAME``."""
  from reference import physics
  return physics.hook(name)


class _RandomProxy:
  """numpy.random for hiro: ``normal`` called from hiro.train's frame runs the loop hook."""

  def __init__(self, harness):
    self._harness = harness

  def __getattr__(self, name):
    return getattr(np.random, name)

  def normal(self, *args, **kwargs):
    frame = sys._getframe(1)
    if frame.f_code is self._harness.train_code:
      self._harness.top(frame)
    return np.random.normal(*args, **kwargs)


class _NumpyProxy:
  """numpy for hiro, with ``random`` replaced by ``_RandomProxy`` and ``argmax`` taking a list
  of 0-d tensors that require grad, as numpy < 1.20 did."""

  def __init__(self, harness):
    self.random = _RandomProxy(harness)

  def __getattr__(self, name):
    return getattr(np, name)

  @staticmethod
  def argmax(a, *args, **kwargs):
    """``off_policy_correction`` calls ``np.argmax(list of 0-d grad tensors)``.
    ``Tensor.__array__`` refuses tensors that require grad; numpy 1.18 (the code's) ignored
    that error while coercing the list and took the tensors as scalars, numpy 2 raises it.
    The argmax of their float values (ties: the first index)."""
    if isinstance(a, list) and a and hasattr(a[0], "detach"):
      a = [float(x.detach()) for x in a]
    return np.argmax(a, *args, **kwargs)


def _cpu():
  try:
    out = subprocess.run(["lscpu"], capture_output=True, text=True).stdout
    return {k.strip(): v.strip() for k, v in (l.split(":", 1) for l in out.splitlines()
                                              if ":" in l)}
  except OSError:
    return {"Model name": platform.processor()}


class Harness:
  """Hooks, counters and files of one run of the code."""

  def __init__(self, config: Config):
    self.config = config
    self.out = pathlib.Path(config.out)
    self.code = pathlib.Path(config.code or reference.code_dir())
    self.checkpoint_path = self.out / "checkpoint.pt"
    self.t = None  # the loop iteration now running
    self.resume = None  # the checkpoint to restore at the first loop iteration
    self.envs_made = 0
    self.xml_files = _XmlFiles()
    self.recording = None  # while evaluating: the list of each episode's last xyz
    self.evals = {}
    self.window = _new_window()
    self.clock = {"start": time.time(), "busy": 0.0, "mark": None, "mark_t": None,
                  "eval_mark": None, "eval_mark_t": None, "cpu_mark": None, "cpu_busy": 0.0}

  # ----- setup -------------------------------------------------------------------------------

  def install(self):
    """Import the code (its run.py with the run's arguments) and install every hook."""
    c = self.config
    sys.path[:0] = [str(STANDINS), str(self.code)]
    os.chdir(self.code)  # maze_env.py finds its XML under os.getcwd(); run.py reads ./*.csv
    import torch
    torch.set_num_threads(c.threads)
    if c.seeded:
      # hiro.train builds the TD3 networks before its torch.manual_seed(seed). torch 1.4 (the
      # code's) started every process from the fixed default seed below, so those weights were
      # the same in every run; torch >= 2 starts from a random seed. Restore torch 1.4's.
      torch.manual_seed(TORCH_DEFAULT_SEED)
      random.seed(c.seed)  # not drawn from by the code; seeded so that checkpoints agree
    import mujoco_py
    import wandb
    mujoco_py.set_model_hook(_physics_hook(c.physics))
    mujoco_py.set_warning_mode(c.warnings)
    self.mujoco_py = mujoco_py
    wandb.sinks.append(self.on_log)
    wandb.keep = False
    import gym.spaces
    import utils
    utils.create_maze_env = self._env_factory(utils.create_maze_env)
    sys.modules["environments.maze_env"].tempfile = self.xml_files
    import hiro
    self.hiro = hiro
    self.train_code = hiro.train.__code__
    argv = ["run.py", "--alg", "hiro_train", "--param_id", "1", "--seed", str(c.seed),
            "--max_timestep", str(c.steps), "--start_timestep", str(c.start_timestep),
            "--evaluation_interval", str(c.evaluation_interval)]
    if c.episode_len:
      argv += ["--episode_len", str(c.episode_len)]
    sys.argv = argv
    import run as code_run
    self.code_run = code_run
    self._hook_loop(hiro, gym.spaces.Box)
    self._hook_evaluations(hiro)
    self._quiet([hiro, utils, code_run] + [sys.modules[m] for m in ("ppo.PPO", "ppo.PPOM",
                                                                    "ppo.config")])

  def _env_factory(self, create):
    def create_seeded(*args, **kwargs):
      try:
        env = create(*args, **kwargs)
      finally:
        self.xml_files.remove()
      index, self.envs_made = self.envs_made, self.envs_made + 1
      if self.config.seeded:
        ant_seed, space_seed = np.random.SeedSequence([self.config.seed, index]).generate_state(2)
        env.wrapped_env.seed(int(ant_seed))
        env.wrapped_env.action_space.seed(int(space_seed))
      if self.recording is not None:
        self._record(env, self.recording)
      return env
    return create_seeded

  @staticmethod
  def _record(env, episodes):
    reset, step = env.reset, env.step

    def recorded_reset():
      obs = reset()
      episodes.append(np.array(obs[:3], dtype=np.float64))
      return obs

    def recorded_step(action):
      out = step(action)
      episodes[-1] = np.array(out[0][:3], dtype=np.float64)
      return out
    env.reset, env.step = recorded_reset, recorded_step

  def _hook_loop(self, hiro, box):
    harness = self
    hiro.np = _NumpyProxy(self)
    sample = box.sample

    def hooked_sample(space):
      frame = sys._getframe(1)
      if frame.f_code is harness.train_code:
        harness.top(frame)
      return sample(space)
    box.sample = hooked_sample
    create = hiro.create_rl_components

    def create_at_resume(params, device):
      made = create(params, device)
      if self.resume is not None:
        made[0] = self.resume["t"]
      return made
    hiro.create_rl_components = create_at_resume
    reward = hiro.intrinsic_reward_simple

    def summed_reward(*args):
      r = reward(*args)
      self.window["reward"] += float(r)
      self.window["n"] += 1
      return r
    hiro.intrinsic_reward_simple = summed_reward
    hiro.off_policy_correction = self._observed_correction(hiro.off_policy_correction)
    hiro.save_checkpoint = self._save_checkpoint_call
    hiro.ExperienceBufferLow = _one_row_more(hiro.ExperienceBufferLow)

  def _hook_evaluations(self, hiro):
    from reference import evaluation
    td3 = self.code_evaluate = hiro.evaluate
    if self.config.eval in ("batched", "batched-td3"):
      td3 = evaluation.batched_evaluate(hiro, self)
    ppo = hiro.evaluate_higher_policy
    if self.config.eval == "batched-td3":
      ppo = _left_out  # its 'higher success rate' is read by nothing in the algorithm
    hiro.evaluate = self._evaluation("td3", td3)
    hiro.evaluate_higher_policy = self._evaluation("ppo", ppo)

  def _quiet(self, modules):
    path = self.config.code_output
    if path:
      stream = open(path, "a")

      def to_file(*args, **kwargs):
        kwargs.pop("file", None)
        builtins.print(*args, file=stream, **kwargs)
      sink = to_file
    else:
      def sink(*args, **kwargs):
        pass
    for module in modules:
      module.print = sink

  # ----- the run -----------------------------------------------------------------------------

  def run(self):
    """Run the code's ``cmd_run`` (wandb.init, then hiro.train) until done or stopped."""
    self.out.mkdir(parents=True, exist_ok=True)
    if (self.out / "done.json").exists():
      print(f"{self.out}: finished already")
      return 0
    self.install()  # before reading a checkpoint: its pickles name the code's modules
    if self.checkpoint_path.exists():
      from reference import state
      self.resume = state.read(self.checkpoint_path)
      if 0 < self.config.stop_at <= self.resume["t"]:
        print(f"{self.out}: at t={self.resume['t']}, stopped already (--stop-at "
              f"{self.config.stop_at})")
        return 3
      print(f"resuming {self.out} at t={self.resume['t']}", flush=True)
    t0 = 0 if self.resume is None else self.resume["t"]
    self.logs = logs_lib.Logs(str(self.out), t0)
    self._provenance()
    params, _ = self.code_run.load_params(1)
    try:
      self.code_run.cmd_run(params)
    except Stop:
      print(f"stopped at t={self.t} (checkpoint {self.checkpoint_path})")
      return 3
    except Finished:
      print(f"finished at t={self.config.steps}: {self.out / 'final.pt'}")
      return 0
    finally:
      self.logs.close()
    raise RuntimeError("hiro.train returned without the harness's final save")

  # ----- the loop hook -----------------------------------------------------------------------

  def top(self, frame):
    """Called at the top of every loop iteration, before anything of it ran."""
    if self.t is None:
      self._first(frame)
      return
    self.t += 1
    t = self.t
    if t % self.config.window == 0:
      self._window_row(frame, t)
    if t % self.config.checkpoint_every == 0 or t == self.config.stop_at:
      self._checkpoint(frame, t)
    if t == self.config.stop_at:
      raise Stop()

  def _first(self, frame):
    self.t = frame.f_locals["t"]
    if self.resume is not None:
      from reference import state
      blob, self.resume = self.resume, None
      state.restore(frame, blob)
      saved = blob["harness"]
      self.envs_made = saved["envs_made"]
      self.window = {**_new_window(), **saved["window"]}  # a checkpoint of an older harness
      self.evals = saved["evals"]
      self.mujoco_py.warning_counts.update(saved["warnings"])
      self.clock["wall_before"] = saved["wall"]
    now = time.time()
    self.clock.update(mark=now, mark_t=self.t, eval_mark=now, eval_mark_t=self.t, busy=0.0,
                      eval_busy=0.0, cpu_mark=time.process_time(), cpu_busy=0.0)

  def _wall(self):
    return round(self.clock.get("wall_before", 0.0) + time.time() - self.clock["start"], 1)

  def _rate(self, key_mark, key_t, key_busy):
    """Training env steps/s since a mark, leaving out evaluation and checkpoint time."""
    now = time.time()
    seconds = now - self.clock[key_mark] - self.clock[key_busy]
    steps = self.t - self.clock[key_t]
    self.clock[key_mark], self.clock[key_t], self.clock[key_busy] = now, self.t, 0.0
    return _per(steps, seconds)

  def _window_rates(self):
    """(training env steps per wall-second, per CPU-second of this process, all its threads)
    since the last window, leaving out evaluations and checkpoints. The CPU rate is not
    stretched by other processes' preemption (``benchmarks.paper_code`` reads it)."""
    now = time.process_time()
    cpu_seconds = now - self.clock["cpu_mark"] - self.clock["cpu_busy"]
    cpu = _per(self.t - self.clock["mark_t"], cpu_seconds)  # before _rate moves the mark
    self.clock["cpu_mark"], self.clock["cpu_busy"] = now, 0.0
    return self._rate("mark", "mark_t", "busy"), cpu

  def _observed_correction(self, correction):
    """The code's ``off_policy_correction``, called at every segment's end with s_0 (the
    state sequence's first), g_0 and s_c: the Low's subgoal statistics of the segment, summed
    into the window (nothing drawn, nothing changed), then the code's own call."""
    def observed(actor, action_sequence, state_sequence, goal_dim, goal, end_state, *rest):
      import torch
      with torch.no_grad():
        s0 = state_sequence[0].detach().cpu()[:goal_dim]
        g0, sc = goal.detach().cpu(), end_state.detach().cpu()[:goal_dim]
        start, end = float(torch.norm(g0)), float(torch.norm(s0 + g0 - sc))
      w = self.window
      w["segments"] += 1
      w["start"], w["distance"] = w["start"] + start, w["distance"] + end
      w["reached"] += float(end <= 1.5)
      w["progress"] += start - end
      return correction(actor, action_sequence, state_sequence, goal_dim, goal, end_state,
                        *rest)
    return observed

  def _window_row(self, frame, t):
    local = frame.f_locals
    n, w = self.window["n"], self.window
    k = w["segments"]
    wall_rate, cpu_rate = self._window_rates()
    row = {
        "t": t, "step": t - self.config.start_timestep,
        "low_intrinsic_reward_mean": repr(self.window["reward"] / n) if n else "",
        "low_reward_steps": n, "segments": k,
        **{f"subgoal_{name}": repr(w[name] / k) if k else ""
           for name in ("start", "distance", "reached", "progress")},
        "on_policy_count": local["on_policy_count"],
        "off_policy_count": local["off_policy_count"],
        "random_policy_count": local["random_policy_count"],
        "episode_num_h": local["episode_num_h"],
        "success_rate": local["success_rate"],
        "higher_success_rate": local["higher_success_rate"],
        "mujoco_warnings": sum(self.mujoco_py.warning_counts.values()),
        "train_steps_per_cpu_s": cpu_rate, "train_steps_per_s": wall_rate,
        "wall_s": self._wall()}
    self.window = _new_window()
    self.logs.window(row)
    print(f"t={t} step={row['step']} steps/s={row['train_steps_per_s']} "
          f"S_E={row['success_rate']} S_E(ppo)={row['higher_success_rate']} "
          f"modes(ppo,td3,random)=({row['on_policy_count']},{row['off_policy_count']},"
          f"{row['random_policy_count']}) wall={row['wall_s']}s", flush=True)

  def _checkpoint(self, frame, t):
    from reference import state
    start, cpu = time.time(), time.process_time()
    if frame.f_locals["t"] != t:
      raise RuntimeError(f"the harness counted t={t}, the loop is at {frame.f_locals['t']}")
    self.logs.flush()
    harness = {"envs_made": self.envs_made, "window": self.window, "evals": self.evals,
               "warnings": dict(self.mujoco_py.warning_counts), "wall": self._wall(),
               "config": dataclasses.asdict(self.config)}
    state.write(self.checkpoint_path, state.capture(frame, t, harness))
    self._busy(time.time() - start, time.process_time() - cpu)

  def _busy(self, seconds, cpu_seconds):
    self.clock["busy"] += seconds
    self.clock["eval_busy"] += seconds
    self.clock["cpu_busy"] += cpu_seconds

  # ----- evaluations, logging, the end -------------------------------------------------------

  def _evaluation(self, key, evaluate):
    def timed(*args, **kwargs):
      start, cpu = time.time(), time.process_time()
      episodes = []
      self.recording = episodes
      limit = self.config.eval_episodes
      if limit != 50:
        self.hiro.range = _limited_range(limit)
      try:
        rate = evaluate(*args, **kwargs)
      finally:
        self.recording = None
        self.hiro.__dict__.pop("range", None)
      seconds = time.time() - start
      self._busy(seconds, time.process_time() - cpu)
      target = np.asarray(args[3].cpu().numpy(), dtype=np.float64)  # both evaluations' 4th
      distances = [float(np.linalg.norm(xyz - target)) for xyz in episodes]
      self.evals[key] = {"rate": rate, "distances": distances, "seconds": seconds}
      if key == "ppo":
        self._evaluation_row()
      return rate
    return timed

  def _evaluation_row(self):
    td3, ppo = self.evals["td3"], self.evals["ppo"]
    row = {
        "t": self.t, "step": self.t - self.config.start_timestep,
        "success_rate": td3["rate"],
        "higher_success_rate": "" if ppo["rate"] != ppo["rate"] else ppo["rate"],
        "final_distance": _mean(td3["distances"]),
        "final_distance_ppo": _mean(ppo["distances"]) if ppo["distances"] else "",
        "successes": sum(d <= 5.0 for d in td3["distances"]),
        "successes_ppo": sum(d <= 5.0 for d in ppo["distances"]) if ppo["distances"] else "",
        "eval_mode": self.config.eval, "eval_s": round(td3["seconds"], 2),
        "eval_ppo_s": round(ppo["seconds"], 2),
        "train_steps_per_s": self._rate("eval_mark", "eval_mark_t", "eval_busy"),
        "wall_s": self._wall()}
    self.logs.evaluation(row)
    print(f"evaluation t={self.t}: success rate {row['success_rate']} (final distance "
          f"{row['final_distance']:.2f}), higher success rate {row['higher_success_rate']} "
          f"({row['eval_s']} s + {row['eval_ppo_s']} s)", flush=True)

  def on_log(self, record, step):
    """The wandb stand-in's sink: one JSONL line per ``wandb.log`` call."""
    self.logs.wandb(self.t, step, record)

  def _save_checkpoint_call(self, step, *args, **kwargs):
    frame = sys._getframe(1)
    if frame.f_code is not self.train_code or step != frame.f_locals["max_timestep"]:
      return  # the code's in-loop call, a no-op as in the code
    import torch
    local = frame.f_locals
    weights = {}
    for name, value in local.items():
      if isinstance(value, (torch.nn.Module, torch.optim.Optimizer)):
        weights[name] = value.state_dict()
    for name in ("ppo_agent", "ppom_agent"):
      agent = local[name]
      for part in ("policy", "policy_old", "optimizer"):
        weights[f"{name}.{part}"] = getattr(agent, part).state_dict()
    from reference import state
    state.write(self.out / "final.pt", {"t": step, "weights": weights, "rng": state.rng_state()})
    self.logs.flush()
    (self.out / "done.json").write_text(json.dumps({"t": step, "wall_s": self._wall()}) + "\n")
    raise Finished()

  def _provenance(self):
    path = self.out / "provenance.json"
    data = json.loads(path.read_text()) if path.exists() else {}
    if not data:
      import gym
      import mujoco
      import torch
      patches = self.code.parent / "PATCHES.json"
      data = {
          "code": {"upstream": reference.UPSTREAM, "commit": reference.COMMIT,
                   "folder": reference.FOLDER, "path": str(self.code),
                   "patches": json.loads(patches.read_text()) if patches.exists() else None},
          "packages": {"python": platform.python_version(), "torch": torch.__version__,
                       "numpy": np.__version__, "gym": gym.__version__,
                       "mujoco": mujoco.__version__,
                       "mujoco_py": "stand-in (reference/standins/mujoco_py)",
                       "wandb": "stand-in (reference/standins/wandb)"},
          "cpu": {k: v for k, v in _cpu().items() if k in (
              "Architecture", "Model name", "CPU family", "Model", "CPU(s)", "Flags")},
          "harness": _harness_commit(),
          "host": platform.node(), "config": dataclasses.asdict(self.config), "sessions": []}
    # Each session's own commit and machine: a run may resume at another commit or on
    # another machine (the top-level entries are its first session's).
    data["sessions"].append({"started": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
                             "command": self.config.command, "threads": self.config.threads,
                             "resume_t": None if self.resume is None else self.resume["t"],
                             "harness": _harness_commit(), "host": platform.node(),
                             "cpu": _cpu().get("Model name")})
    path.write_text(json.dumps(data, indent=1) + "\n")


class _XmlFiles:
  """The code's ``maze_env`` writes each env's model to ``tempfile.mkstemp(suffix='.xml')``
  and neither closes the descriptor nor removes the file (an evaluation makes a new env:
  over 100 files in the temp folder a run, and as many descriptors). Stands in for its
  ``tempfile``: the descriptor is closed at once (the code writes through the path) and the
  file removed once the env has loaded it."""

  def __init__(self):
    self.paths = []

  def __getattr__(self, name):
    return getattr(tempfile, name)

  def mkstemp(self, *args, **kwargs):
    fd, path = tempfile.mkstemp(*args, **kwargs)
    os.close(fd)
    self.paths.append(path)
    return fd, path

  def remove(self):
    for path in self.paths:
      with contextlib.suppress(FileNotFoundError):
        os.remove(path)
    self.paths.clear()


def _one_row_more(buffer_class):
  """ExperienceBufferLow with one row more than asked. Its ``sample`` draws indices in
  ``[0, offset]`` (one past the filled rows: a zero row); with the buffer sized at
  ``max_timestep`` the last iteration's index ``max_timestep`` is out of bounds (an
  IndexError with probability ``batch_size / (max_timestep + 1)``). One more row keeps every
  draw what it is in a longer run: the zero row."""
  class ExperienceBufferLow(buffer_class):
    def __init__(self, capacity, *args, **kwargs):
      super().__init__(capacity + 1, *args, **kwargs)
  return ExperienceBufferLow


def _harness_commit():
  """The project's commit and whether reference/ has uncommitted changes (None: no git)."""
  root = str(reference.PACKAGE.parent)
  try:
    head = subprocess.run(["git", "-C", root, "rev-parse", "HEAD"], capture_output=True,
                          text=True, check=True).stdout.strip()
    dirty = subprocess.run(["git", "-C", root, "status", "--porcelain", "reference"],
                           capture_output=True, text=True, check=True).stdout.strip()
  except (OSError, subprocess.CalledProcessError):
    return None
  return {"commit": head, "reference_dirty": bool(dirty)}


def _per(steps, seconds):
  """A rate rounded for the CSV, or empty where there is nothing to divide."""
  return round(steps / seconds, 2) if seconds > 0 and steps > 0 else ""


def _new_window():
  """The sums of a window: the Low's reward and steps; per segment (at its end, the code's
  call of the correction) ||g_0||, ||g_c||, ||g_c|| <= 1.5 and ||g_0|| - ||g_c||."""
  return {"reward": 0.0, "n": 0, "segments": 0, "start": 0.0, "distance": 0.0,
          "reached": 0.0, "progress": 0.0}


def _left_out(*args, **kwargs):
  """The Middle PPO's evaluation under ``--eval batched-td3``: not run; its rate is NaN (the
  code logs it to wandb; the CSV's column stays empty)."""
  return float("nan")


def _mean(values):
  return float(np.mean(values)) if values else float("nan")


def _limited_range(episodes):
  """``range`` for hiro's evaluations with fewer than 50 episodes (tests only)."""
  def limited(*args):
    if args == (10,):
      return builtins.range(-(-episodes // 5))
    if args == (5,):
      return builtins.range(min(5, episodes))
    return builtins.range(*args)
  return limited


def main(argv=None):
  argv = sys.argv[1:] if argv is None else argv
  config = Config(**json.loads(pathlib.Path(argv[0]).read_text()))
  return Harness(config).run()


if __name__ == "__main__":
  sys.exit(main())
