"""Each side's evaluation of the other's trained actors: the side-by-side study's swap (a),
and its mirror.

    python -m reference.cross_eval RUN [--method ours] [--step N] [--seeds 0 1 ...]
        [--draws 1] [--draw-seed 0] [--episodes 50] [--json FILE]

* RUN a run folder of ours on Ant Push, with its checkpoints: **the code's evaluation of our
  actors**. At the checkpoint of ``--step`` (default: the newest) each seed's Low TD3 and
  Middle TD3 actors, the ones its own S_E evaluated at that step (the target actors where
  ``eval_target_networks``, the Ant presets'), go into the code's ``ActorLow`` and
  ``ActorHigh`` and the code's evaluation runs them on the code's env with the run's engine
  settings (its ``contacts``, ``reference/physics.py``), beside the run's own evaluation at
  that step (its metrics.csv row: ``eval_success``, ``eval_distance``). Summary: the mean over
  seeds of the difference in mean final distance, code - ours, with a 95 % bootstrap interval
  over seeds.
* RUN a run folder of the code's (``reference.run``): **our evaluation of the code's actors**.
  Its target actors (``final.pt``, else ``checkpoint.pt``) run in our evaluation (the Ant
  preset's: ``eval_goal="requery"``, MuJoCo C, the run's ``--physics`` as our ``contacts``),
  beside the code's evaluation of the same actors run here again; ``--literal-model``: ours on
  HIRO's literal model (the code's) instead of the optimised build our runs train on
  (``envs/ant.py``). Summary: the difference in mean final distance, ours - code, with a
  95 % bootstrap interval over episodes (both samples resampled).

The code's evaluation is its 'success rate' (the Middle re-queried every env step from a first
goal ``randn(3)``, 50 episodes stopped at their first success), batched, bit for bit the
code's (``reference/evaluation.py``). Before evaluating, the receiving side's actors must act
as the giving side's on 64 random inputs (within float32 rounding) and have the same scales
(the code's max_action 30 and max_goal (10, 10, 0.5)): a check that the weights went across
in the right order.

Start states: the code draws each evaluation's reset states and first goals from the
harness's env seeds and torch's generator (``--draw-seed`` seeds both; every evaluation gets a
fresh env); ours from ``jax.random.fold_in(PRNGKey(draw seed), draw)``. The two sides of a
comparison see different episodes and agree only as two samples of one distribution do.

Two processes: the project's venv (JAX, our checkpoints, our evaluation) and the reference
venv (``reference.setup``: torch, the code), exchanging a ``.npz`` of weights in
``nn.Linear``'s layout and a ``.json`` of results, as ``reference.run`` re-executes itself.
"""

import argparse
import json
import os
import pathlib
import subprocess
import sys
import tempfile

import numpy as np

import reference

PROBES = 64  # random inputs on which both sides' actors must agree
TOLERANCE = 1e-5  # of the action scale: float32 sums in another order differ by about 1e-7
HIDDEN = (300, 300)  # the code's actors


def parse(argv):
  p = argparse.ArgumentParser(prog="python -m reference.cross_eval", description=__doc__,
                              formatter_class=argparse.RawDescriptionHelpFormatter)
  p.add_argument("run", nargs="?", default="", help="a run folder of ours or of the code's")
  p.add_argument("--method", default=None, help="ours: default the run's first")
  p.add_argument("--step", type=int, default=None, help="ours: default the newest checkpoint")
  p.add_argument("--seeds", type=int, nargs="*", default=None, help="ours: default all")
  p.add_argument("--draws", type=int, default=1, help="evaluations per seed (50 episodes each)")
  p.add_argument("--draw-seed", type=int, default=0)
  p.add_argument("--episodes", type=int, default=50, help="tests: fewer (still divided by 50)")
  p.add_argument("--episode-len", type=int, default=0, help="tests: shorter episodes")
  p.add_argument("--literal-model", action="store_true",
                 help="the code's actors in ours: on HIRO's literal model (optimised=False), "
                      "not the optimised build our runs train on")
  p.add_argument("--json", default="", help="also write the results here")
  p.add_argument("--threads", type=int, default=1)
  p.add_argument("--venv", default=os.environ.get("REFERENCE_VENV"))
  p.add_argument("--weights", default="", help=argparse.SUPPRESS)  # the reference venv's side
  p.add_argument("--code-checkpoint", default="", help=argparse.SUPPRESS)
  return p.parse_args(argv)


# ----- the project's venv: our actors as arrays, and our evaluation ----------------------------


def torch_layout(actor) -> list[np.ndarray]:
  """A flax MLP's params (``networks.MLP``) as [w0, b0, w1, b1, ...] in ``nn.Linear``'s
  layout: weight (out, in), bias (out,)."""
  dense = actor["params"]
  out = []
  for i in range(len(dense)):
    layer = dense[f"dense_{i}"]
    out += [np.asarray(layer["kernel"], np.float32).T, np.asarray(layer["bias"], np.float32)]
  return out


def flax_layout(weights) -> dict:
  """``torch_layout``'s inverse: the params of a ``networks.MLP``."""
  return {"params": {f"dense_{i // 2}": {"kernel": np.asarray(weights[i]).T,
                                         "bias": np.asarray(weights[i + 1])}
                     for i in range(0, len(weights), 2)}}


def check_config(config):
  """Refuses a config whose actors cannot be the code's: 300-300 MLPs, the Middle's seeing s
  only (the Ant presets')."""
  for name in ("low", "middle"):
    hidden = tuple(getattr(config, name).hidden)
    if hidden != HIDDEN:
      raise ValueError(f"{name}.hidden is {hidden}: the code's actors are 300-300")
  if config.middle_td3_input != "state":
    raise ValueError(f"middle_td3_input is {config.middle_td3_input!r}: the code's ActorHigh "
                     "sees s only ('state')")


def _probes(obs_size):
  rng = np.random.default_rng(0)
  return (rng.normal(size=(PROBES, obs_size)).astype(np.float32),
          (rng.normal(size=(PROBES, 3)) * 3).astype(np.float32))


def _actors(agent):
  """Our noiseless actors on a batch: Low (params, obs, goal), Middle TD3 (params, obs)."""
  import jax
  return (jax.jit(jax.vmap(agent.low.td3.act, in_axes=(None, 0, 0))),
          jax.jit(jax.vmap(agent.middle.policy, in_axes=(None, 0))))


def _own_rows(run_dir, method, env_step):
  """{seed: the run's own evaluation at ``env_step``}: S_E, final distance (and the
  re-queried S_E where the run has its column)."""
  from experiments import curves
  found = {}
  for r in curves.load([run_dir]):
    if r["method"] == method and int(r["env_step"]) == env_step and r.get("eval_success"):
      keep = ("eval_success", "eval_distance", "eval_success_requery")
      found[int(r["seed"])] = {k: float(r[k]) for k in keep if r.get(k) not in (None, "")}
  return found


def export(run_dir, method=None, step=None, seeds=None, plan=None) -> dict:
  """Our actors at a checkpoint, for each seed, with probe inputs and our actions on them,
  and the run's own evaluation at that step: arrays for ``np.savez`` (``plan``: the run's,
  when the caller has read it, with ``method``)."""
  import jax
  from nonmono_jax.core import evaluate
  from nonmono_jax.host import programs
  plan, method, step, trainer, states = programs.restored(run_dir, method, step, plan)
  config, agent = plan.configs[method], trainer.agent
  seeds = list(range(plan.spec.seeds)) if seeds is None else list(seeds)
  obs, goal = _probes(agent.env.observation_size)
  low_act, middle_act = _actors(agent)
  out = {"probe_obs": obs, "probe_goal": goal, "low_scale": np.asarray(agent.low.limit),
         "middle_scale": np.asarray(agent.middle.goal_range),
         "middle_context": np.asarray(agent.middle.context)}  # () for the Ant presets
  for k in seeds:
    pick = lambda tree: evaluate.acting_params(jax.tree.map(lambda x: x[k], tree),
                                               config.eval_target_networks)
    low, middle = pick(states.low.params), pick(states.middle.params)
    for name, params in (("low", low), ("middle", middle)):
      for i, w in enumerate(torch_layout(params.actor)):
        out[f"seed{k}/{name}/{i}"] = w
    out[f"seed{k}/probe_low"] = np.asarray(low_act(low, obs, goal))
    out[f"seed{k}/probe_middle"] = np.asarray(middle_act(middle, obs))
  env_step = step * config.num_envs
  meta = {"run": str(pathlib.Path(run_dir).resolve()), "method": method, "step": step,
          "env_step": env_step, "seeds": seeds, "contacts": plan.contacts or "mujoco3",
          "target_networks": config.eval_target_networks,
          "ours": {str(k): v for k, v in _own_rows(run_dir, method, env_step).items()}}
  out["meta"] = np.asarray(json.dumps(meta))
  return out


def our_agent(contacts: str, episode_len: int = 0, optimised: bool = True):
  """The Ant Push agent of the paper preset (ours) on MuJoCo C with ``contacts``, on the
  optimised build our runs train on or (``optimised=False``) HIRO's literal model, the code's:
  (its config, the agent). No state is made."""
  import envs
  from nonmono_jax.core import agent as agent_lib
  from nonmono_jax.host import methods
  config, spec = methods.build_config("paper", "ours", "AntPush")
  env = envs.make("AntPush", episode_length=episode_len or spec.episode_length, physics="c",
                  contacts=contacts, optimised=optimised)
  return config, agent_lib.make_agent(env, config)


def _td3_params(weights):
  from nonmono_jax.core import td3
  actor = flax_layout(weights)
  return td3.TD3Params(actor=actor, critic=None, target_actor=actor, target_critic=None)


def our_policy(data, k, contacts, episode_len=0, optimised=True):
  """(config, agent, Low params, Middle params) of ours holding seed ``k``'s actors from
  ``data``, after the scale and probe checks."""
  config, agent = our_agent(contacts, episode_len, optimised)
  low, middle = (_td3_params([data[f"seed{k}/{n}/{i}"] for i in range(6)])
                 for n in ("low", "middle"))
  check_scales(agent.low.limit, agent.middle.goal_range, data)
  low_act, middle_act = _actors(agent)
  obs, goal = data["probe_obs"], data["probe_goal"]
  _check_gap("our", "low", low_act(low, obs, goal), data[f"seed{k}/probe_low"], agent.low.limit)
  _check_gap("our", "middle", middle_act(middle, obs), data[f"seed{k}/probe_middle"],
             agent.middle.goal_range)
  return config, agent, low, middle


def our_evaluation(data, k, contacts, episodes=50, episode_len=0, draws=1, draw_seed=0,
                   optimised=True):
  """Our evaluation (the Ant preset's kind) of seed ``k``'s actors in ``data`` after the
  checks: [(S_E, final distance of each episode)] per draw."""
  import jax
  from nonmono_jax.core import evaluate
  config, agent, low, middle = our_policy(data, k, contacts, episode_len, optimised)
  goal_act = lambda params, o, key: agent.middle.policy(params, o)
  episode = evaluate.make_episode(agent.env, config.c, agent.low.td3.act, goal_act,
                                  config.eval_goal)
  one = lambda key: evaluate.outcome(episode(low, middle, key)[1], config.eval_goal)
  run = jax.jit(jax.vmap(one))
  out = []
  for d in range(draws):
    o = run(jax.random.split(jax.random.fold_in(jax.random.PRNGKey(draw_seed), d), episodes))
    out.append((float(np.mean(o.success)), [float(x) for x in np.asarray(o.distance)]))
  return out


def is_code_run(run_dir) -> bool:
  """Whether ``run_dir`` is a run folder of the code's (``reference.run``) with weights."""
  return any((pathlib.Path(run_dir) / f).exists() for f in ("final.pt", "checkpoint.pt"))


def code_checkpoint(run_dir) -> pathlib.Path:
  """The code's run's newest weights: ``final.pt``, else ``checkpoint.pt``."""
  run = pathlib.Path(run_dir)
  return run / "final.pt" if (run / "final.pt").exists() else run / "checkpoint.pt"


def code_actors_npz(run_dir, path, venv=None, **draws) -> int:
  """Writes the code's run's target actors (and, with ``draws``' ``draws`` > 0, the code's
  evaluations of them) to ``path`` from the reference venv; its exit code."""
  return _reference_venv(venv, ["--code-checkpoint", str(code_checkpoint(run_dir)),
                                "--weights", str(path)], **{"draws": 0, **draws})


# ----- both venvs: the checks ----------------------------------------------------------------


def check_scales(low_scale, middle_scale, data):
  """Refuses actors whose scales are not the receiving side's."""
  for name, theirs, ours in (("Low's action", data["low_scale"], low_scale),
                             ("Middle's goal", data["middle_scale"], middle_scale)):
    ours = np.broadcast_to(np.asarray(ours, np.float32), theirs.shape)
    if not np.array_equal(ours, theirs):
      raise ValueError(f"the {name} scale is {theirs.tolist()}, here {ours.tolist()}")


def _check_gap(side, name, got, want, scale):
  gap = float(np.max(np.abs(np.asarray(got) - np.asarray(want)) / np.asarray(scale)))
  if gap > TOLERANCE:
    raise ValueError(f"{side} {name} actor with the other side's weights acts otherwise (max "
                     f"gap {gap:.2e} of its scale)")


# ----- the reference venv: the code's actors and evaluation ---------------------------------


def _code_layers(actor):
  import torch
  return [m for m in actor.fc if isinstance(m, torch.nn.Linear)]


def code_actors(hiro, params, data=None, k=0):
  """The code's ActorLow and ActorHigh, holding seed ``k``'s weights from ``data`` if given."""
  import torch
  pp = params.policy_params
  low = hiro.ActorLow(params.state_dim, params.goal_dim, params.action_dim, pp.max_action)
  high = hiro.ActorHigh(params.state_dim, params.goal_dim, pp.max_goal, "cpu")
  for name, actor in (("low", low), ("middle", high)):
    for i, layer in enumerate(_code_layers(actor) if data is not None else ()):
      for j, p in enumerate((layer.weight, layer.bias)):
        w = data[f"seed{k}/{name}/{2 * i + j}"]
        if tuple(w.shape) != tuple(p.shape):
          raise ValueError(f"seed {k} {name} layer {i}: given {w.shape}, the code's "
                           f"{tuple(p.shape)}")
        with torch.no_grad():
          p.copy_(torch.from_numpy(w))
  return low, high


def _code_probes(low, high, obs, goal):
  import torch
  from reference import evaluation
  with torch.no_grad():
    obs, goal = torch.from_numpy(obs), torch.from_numpy(goal)
    return (evaluation.low_actions(low, obs, goal).numpy(),
            evaluation.high_goals(high, obs).numpy())


def _code_evaluation(harness, hiro, params, low, high, target):
  """One evaluation of the code's (batched): (S_E, final distance of each episode)."""
  from reference import evaluation
  recorded = []
  harness.recording = recorded
  try:
    rate = evaluation.batched_evaluate(hiro, harness)(low, high, params, target, "cpu")
  finally:
    harness.recording = None
  t = target.numpy().astype(np.float64)
  return rate, [float(np.linalg.norm(x - t)) for x in recorded]


def _installed(args, physics):
  """(harness, hiro, params, target) of the code imported as the harness runs it."""
  import torch
  from reference.harness import Config, Harness
  out = pathlib.Path(args.weights).parent / "harness"
  harness = Harness(Config(out=str(out), seed=args.draw_seed, threads=args.threads,
                           physics=physics, eval_episodes=args.episodes,
                           episode_len=args.episode_len))
  harness.install()
  params, _ = harness.code_run.load_params(1)
  torch.manual_seed(args.draw_seed)
  return harness, harness.hiro, params, harness.hiro.get_target_position(params.env_name)


def inside(args):
  """Ours -> the code's evaluation: ``--weights`` in, results beside it (``.json``)."""
  data = np.load(args.weights)
  meta = json.loads(str(data["meta"]))
  harness, hiro, params, target = _installed(args, meta["contacts"])
  pp = params.policy_params
  check_scales(pp.max_action, pp.max_goal, data)
  results = []
  for k in meta["seeds"]:
    low, high = code_actors(hiro, params, data, k)
    theirs = _code_probes(low, high, data["probe_obs"], data["probe_goal"])
    for name, got, scale in zip(("low", "middle"), theirs, (pp.max_action, pp.max_goal)):
      _check_gap("the code's", name, got, data[f"seed{k}/probe_{name}"], scale)
    ours = meta["ours"].get(str(k), {})
    for d in range(args.draws):
      rate, dist = _code_evaluation(harness, hiro, params, low, high, target)
      results.append({"seed": k, "draw": d, "code_success": rate,
                      "code_distance": float(np.mean(dist)), "code_distances": dist, **ours})
      print(_line(results[-1]), flush=True)
  pathlib.Path(args.weights).with_suffix(".json").write_text(json.dumps(results))
  return 0


def _code_weights(path):
  """(t, the Low's and the Middle's target actor state dicts) of the code's final.pt or
  checkpoint.pt."""
  import torch
  blob = torch.load(path, weights_only=False)
  if "weights" in blob:  # final.pt
    return blob["t"], blob["weights"]["actor_target_l"], blob["weights"]["actor_target_h"]
  local = blob["locals"]
  return blob["t"], local["actor_target_l"].state_dict(), local["actor_target_h"].state_dict()


def inside_code(args):
  """The code's actors -> arrays (``--weights``) and the code's evaluation of them."""
  config = json.loads((pathlib.Path(args.code_checkpoint).parent / "config.json").read_text())
  harness, hiro, params, target = _installed(args, config["physics"])
  t, low_state, high_state = _code_weights(args.code_checkpoint)
  low, high = code_actors(hiro, params)
  low.load_state_dict(low_state)
  high.load_state_dict(high_state)
  obs, goal = _probes(params.state_dim)
  pp, k = params.policy_params, config["seed"]
  probe_low, probe_middle = _code_probes(low, high, obs, goal)
  out = {"probe_obs": obs, "probe_goal": goal, f"seed{k}/probe_low": probe_low,
         f"seed{k}/probe_middle": probe_middle,
         "low_scale": np.full(params.action_dim, pp.max_action, np.float32),
         "middle_scale": np.asarray(pp.max_goal, np.float32)}
  for name, actor in (("low", low), ("middle", high)):
    for i, layer in enumerate(_code_layers(actor)):
      out[f"seed{k}/{name}/{2 * i}"] = layer.weight.detach().numpy().copy()
      out[f"seed{k}/{name}/{2 * i + 1}"] = layer.bias.detach().numpy().copy()
  results = []
  for d in range(args.draws):
    rate, dist = _code_evaluation(harness, hiro, params, low, high, target)
    results.append({"seed": k, "draw": d, "code_success": rate, "code_distances": dist})
  meta = {"run": str(pathlib.Path(args.code_checkpoint).parent.resolve()),
          "checkpoint": pathlib.Path(args.code_checkpoint).name, "t": t, "seeds": [k],
          "contacts": config["physics"].replace("as-is", "mujoco3"), "results": results}
  np.savez(args.weights, meta=np.asarray(json.dumps(meta)), **out)
  return 0


# ----- the command ---------------------------------------------------------------------------


def _line(r):
  ours = (f"ours S_E {r['eval_success']:.2f} distance {r['eval_distance']:.2f}"
          if "eval_distance" in r else "ours: no row at this step")
  return (f"seed {r['seed']} draw {r['draw']}: the code's evaluation S_E {r['code_success']:.2f} "
          f"distance {r['code_distance']:.2f} (sd {np.std(r['code_distances'], ddof=1):.2f} "
          f"over {len(r['code_distances'])} episodes); {ours}")


def summary(meta, results) -> dict:
  """The code's evaluation of our actors: the rows and the mean over seeds of code - ours in
  final distance, with its 95 % bootstrap percentile interval over seeds (``experiments.stats``;
  every resample up to 8 seeds)."""
  from experiments import stats
  per_seed = {}
  for r in results:
    if "eval_distance" in r:
      per_seed.setdefault(r["seed"], []).append(r["code_distance"] - r["eval_distance"])
  diffs = np.array([np.mean(v) for v in per_seed.values()])
  diff = {"what": "final distance, the code's evaluation - ours, mean over seeds",
          "seeds": len(diffs)}
  if len(diffs):
    reps = "exact" if len(diffs) <= 8 else stats.REPS  # every resample: C(2n - 1, n) of them
    point, lower, upper = stats.interval(stats.mean, diffs[:, None], reps=reps)
    diff.update(mean=float(point), ci95=[float(lower), float(upper)])
  return {**meta, "results": results, "difference": diff}


def mirror_summary(meta, ours) -> dict:
  """Our evaluation of the code's actors beside the code's: per draw both sides' S_E and
  mean final distance, and ours - code in mean final distance over all episodes with its 95 %
  bootstrap percentile interval (the two sides' episodes resampled independently)."""
  from experiments import stats
  rows = [{"draw": r["draw"], "code_success": r["code_success"],
           "code_distance": float(np.mean(r["code_distances"])), "our_success": s,
           "our_distance": float(np.mean(dist)), "our_distances": dist,
           "code_distances": r["code_distances"]}
          for r, (s, dist) in zip(meta["results"], ours)]
  pooled = [np.concatenate([r[f"{side}_distances"] for r in rows])[:, None]
            for side in ("our", "code")]
  point, lower, upper = stats.interval(lambda a, b: stats.mean(a) - stats.mean(b), *pooled)
  diff = {"what": "final distance, our evaluation - the code's, mean over episodes",
          "episodes": [len(p) for p in pooled], "mean": float(point),
          "ci95": [float(lower), float(upper)]}
  return {**{k: v for k, v in meta.items() if k != "results"}, "results": rows,
          "difference": diff}


def _reference_venv(venv, inside_args, draws=1, draw_seed=0, episodes=50, episode_len=0,
                    threads=1) -> int:
  venv = pathlib.Path(venv) if venv else reference.default_venv()
  rest = ["--draws", str(draws), "--draw-seed", str(draw_seed), "--episodes", str(episodes),
          "--episode-len", str(episode_len), "--threads", str(threads)]
  env = dict(os.environ, PYTHONPATH=str(reference.PACKAGE.parent))
  return subprocess.run([str(venv / "bin" / "python"), "-m", "reference.cross_eval",
                         *inside_args, *rest], env=env).returncode


def _draws(args) -> dict:
  return {"draws": args.draws, "draw_seed": args.draw_seed, "episodes": args.episodes,
          "episode_len": args.episode_len, "threads": args.threads}


def of_ours(args, tmp) -> dict | None:
  """The code's evaluation of our actors (RUN is ours)."""
  from nonmono_jax.host import programs
  plan, method, _ = programs.saved_method(args.run, args.method)
  check_config(plan.configs[method])
  weights = os.path.join(tmp, "actors.npz")
  np.savez(weights, **export(args.run, method, args.step, args.seeds, plan))
  if _reference_venv(args.venv, ["--weights", weights], **_draws(args)):
    return None
  results = json.loads(pathlib.Path(weights).with_suffix(".json").read_text())
  return summary(json.loads(str(np.load(weights)["meta"])), results)


def of_the_code(args, tmp) -> dict | None:
  """Our evaluation of the code's actors (RUN is the code's)."""
  weights = os.path.join(tmp, "actors.npz")
  if code_actors_npz(args.run, weights, args.venv, **_draws(args)):
    return None
  data = np.load(weights)
  meta = json.loads(str(data["meta"]))
  ours = our_evaluation(data, meta["seeds"][0], meta["contacts"], args.episodes,
                        args.episode_len, args.draws, args.draw_seed, not args.literal_model)
  out = mirror_summary({**meta, "our_model": "literal" if args.literal_model else "optimised"},
                       ours)
  for r in out["results"]:
    print(f"the code's seed {meta['seeds'][0]} at t={meta['t']} draw {r['draw']}: our "
          f"evaluation S_E {r['our_success']:.2f} distance {r['our_distance']:.2f}; the "
          f"code's S_E {r['code_success']:.2f} distance {r['code_distance']:.2f}", flush=True)
  return out


def main(argv=None):
  argv = sys.argv[1:] if argv is None else argv
  args = parse(argv)
  if args.code_checkpoint:
    return inside_code(args)
  if args.weights:
    return inside(args)
  if not args.run:
    raise SystemExit("cross_eval: give a run folder of ours (with its checkpoints) or of the "
                     "code's (reference.run)")
  from nonmono_jax.host import checkpoints
  checkpoints.quiet_storage_leftovers()
  with tempfile.TemporaryDirectory() as tmp:
    out = (of_the_code if is_code_run(args.run) else of_ours)(args, tmp)
  if out is None:
    return 1
  print(json.dumps(out["difference"]), flush=True)
  if args.json:
    pathlib.Path(args.json).write_text(json.dumps(out, indent=1) + "\n")
  return 0


if __name__ == "__main__":
  sys.exit(main())
