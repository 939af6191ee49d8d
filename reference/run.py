"""Run the paper's code (its training loop on AntPush) seeded, resumable and logged.

    python -m reference.run --seed 0 --steps 1100000 --out runs/ref_seed0

Runs in the reference venv made by ``python -m reference.setup`` (``--venv``, or
``$REFERENCE_VENV``, or the default). The folder ``--out`` holds config.json,
provenance.json, evaluations.csv, windows.csv, wandb.jsonl, checkpoint.pt (every 10K env
steps) and at the end final.pt and done.json. Run again with the same arguments, the run
resumes from its checkpoint; a finished run is left alone. Exit codes: 0 finished, 2 bad
arguments, 3 stopped at ``--stop-at``.
"""

import argparse
import dataclasses
import json
import os
import pathlib
import shlex
import sys

import reference
from reference.harness import Config


def parse(argv=None):
  p = argparse.ArgumentParser(prog="python -m reference.run", description=__doc__,
                              formatter_class=argparse.RawDescriptionHelpFormatter)
  p.add_argument("--out", required=True, help="the run folder")
  p.add_argument("--seed", type=int, default=0)
  p.add_argument("--steps", type=int, default=1_100_000,
                 help="env steps (the code's max_timestep; the Low buffer is sized for it)")
  p.add_argument("--threads", type=int, default=1, help="torch.set_num_threads")
  p.add_argument("--eval", choices=("code", "batched", "batched-td3"), default="code",
                 help="the code's evaluations; 'batched': the TD3 one ('success rate', the "
                      "one the Top reads) batched over its 50 episodes, the same judgements "
                      "bit for bit; 'batched-td3': that, and the Middle PPO's ('higher "
                      "success rate', read by nothing) left out")
  p.add_argument("--unseeded", action="store_true",
                 help="keep the code's seeding: the envs' generators from the OS")
  p.add_argument("--physics", default="as-is",
                 help="engine settings (reference.physics): as-is (MuJoCo 3's, = mujoco3), "
                      "mujoco2, mujoco200 (envs/contacts.py, as our runs take them)")
  p.add_argument("--mujoco-warnings", choices=("raise", "count"), default="raise",
                 help="'raise': a MuJoCo warning ends the run, as with mujoco_py")
  p.add_argument("--code-output", default="", help="a file for the code's own prints "
                 "(default: discarded)")
  p.add_argument("--venv", default=os.environ.get("REFERENCE_VENV"),
                 help="the reference venv (default: $REFERENCE_VENV or reference/.code/venv)")
  p.add_argument("--code", default="", help="the code folder (default: the fetched one)")
  t = p.add_argument_group("for tests")
  t.add_argument("--start-timestep", type=int, default=100_000)
  t.add_argument("--evaluation-interval", type=int, default=10_000)
  t.add_argument("--episode-len", type=int, default=0, help="0: the CSV's 1000")
  t.add_argument("--eval-episodes", type=int, default=50,
                 help="evaluate only the first N of the 50 episodes (N <= 5 or a multiple "
                 "of 5; the code still divides by 50)")
  t.add_argument("--checkpoint-every", type=int, default=10_000)
  t.add_argument("--window", type=int, default=5_000, help="env steps per windows.csv row")
  t.add_argument("--stop-at", type=int, default=0, help="stop at this env step")
  return p.parse_args(argv)


def config_from(args, command):
  """The run's Config from the parsed arguments."""
  if args.eval_episodes not in (1, 2, 3, 4, 5) and args.eval_episodes % 5:
    raise SystemExit("--eval-episodes must be at most 5 or a multiple of 5")
  return Config(
      out=str(pathlib.Path(args.out).resolve()), seed=args.seed, steps=args.steps,
      start_timestep=args.start_timestep, evaluation_interval=args.evaluation_interval,
      episode_len=args.episode_len, threads=args.threads, seeded=not args.unseeded,
      physics=args.physics, eval=args.eval, eval_episodes=args.eval_episodes,
      checkpoint_every=args.checkpoint_every, window=args.window, stop_at=args.stop_at,
      warnings=args.mujoco_warnings, code_output=args.code_output,
      code=str(pathlib.Path(args.code).resolve()) if args.code else "", command=command)


def check_folder(config):
  """Write config.json, or check that a resumed run asks for the same settings."""
  out = pathlib.Path(config.out)
  out.mkdir(parents=True, exist_ok=True)
  path = out / "config.json"
  mine = dataclasses.asdict(config)
  if path.exists():
    saved = json.loads(path.read_text())
    diff = [k for k in mine if k not in Config.FREE and saved.get(k) != mine[k]]
    if diff:
      raise SystemExit(f"{out} holds a run with other settings: "
                       + ", ".join(f"{k}={saved.get(k)!r} (asked {mine[k]!r})" for k in diff))
  path.write_text(json.dumps(mine, indent=1) + "\n")
  return path


def main(argv=None):
  args = parse(argv)
  command = "python -m reference.run " + shlex.join(sys.argv[1:] if argv is None else argv)
  config = config_from(args, command)
  path = check_folder(config)
  venv = pathlib.Path(args.venv) if args.venv else reference.default_venv()
  python = venv / "bin" / "python"
  if not python.exists():
    raise SystemExit(f"no reference venv at {venv}: run python -m reference.setup first")
  if not (pathlib.Path(config.code or reference.code_dir()) / "hiro.py").exists():
    raise SystemExit("the paper's code is not fetched: run python -m reference.setup first")
  env = dict(os.environ, PYTHONPATH=str(reference.PACKAGE.parent))
  os.execve(str(python), [str(python), "-m", "reference.harness", str(path)], env)


if __name__ == "__main__":
  sys.exit(main())
