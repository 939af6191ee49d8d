"""The experiment command's flags, built from the config dataclasses, without JAX.

``python -m experiments.<task> --help`` and every bad flag are answered from here before JAX,
MuJoCo or the envs load (``experiments/launch.py``). Each leaf field of ``AgentConfig`` is a flag
``--<dotted.path>`` (``--top.alpha 0 0.4 0.7``, ``--low.batch_size 256``), with

- its type (INT, FLOAT, {true,false}; a tuple's entries as separate values) and allowed values
  (``config.choice``: argparse checks them);
- its help text: the comment its class declares it with (``field_docs``), one place for both;
- its default on this task: ours' under the paper preset, then where another method that reads
  the field (``AgentConfig.reads``) or the quick preset differs.

Errors are one line, exit code 2 (``Parser``); a task name is taken in any case.
"""

from __future__ import annotations

import argparse
import ast
import collections.abc
import dataclasses
import functools
import importlib.util
import inspect
import textwrap
import typing

from nonmono_jax.core import config as config_lib
from nonmono_jax.host import methods

EXIT_FAILED, EXIT_BAD_INPUT, EXIT_TIME_LIMIT = 1, 2, 3


class Parser(argparse.ArgumentParser):
  """argparse with every error on one line (no usage block): ``prog: error: message``."""

  def error(self, message):
    self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {message}\n")


def resolve_task(name: str) -> str:
  """The registry's task (``methods.TASKS``) named ``name`` in any case (``antpush``)."""
  found = [t for t in methods.TASKS if t.lower() == name.lower()]
  if not found:
    raise ValueError(f"unknown task {name}; tasks: {', '.join(methods.TASKS)}")
  return found[0]


# --- the parser ----------------------------------------------------------------------------------

def command(task: str) -> str:
  """The command that runs ``task``: its module, or the registry's generic one."""
  module = f"experiments.{task.lower()}"
  return (f"python -m {module}" if importlib.util.find_spec(module) is not None
          else f"python -m experiments {task}")


def make_parser(task: str) -> argparse.ArgumentParser:
  """Every flag of the command on ``task``: the run's, the processes', each config field's."""
  cmd, sizes = command(task), {p: methods.preset_layers(p, "ours", task)[1]
                               for p in methods.PRESETS}
  paper, quick = sizes["paper"], sizes["quick"]
  p = Parser(prog=cmd, formatter_class=_Formatter, usage=(
      f"{cmd} [--method METHOD ...] [--preset {{paper,quick}}] [--out DIR]\n"
      f"{' ' * (len(cmd) + 8)}[options] [--FIELD VALUE ...]"), description=textwrap.fill(
      f"Train methods of Kim et al. (2023) on {task}: ours (a Top PPO picks the Middle's "
      f"TD3, PPO or RANDOM goals), its ablations and the baselines HIRO, Ref:Uniform and "
      f"Ref:PPO. Seeds, and variants that differ only in traced numbers, are vmapped lanes of "
      f"one jitted program.", width=_Formatter.WIDTH), epilog=(
      f"examples:\n"
      f"  {cmd} --method ours hiro --preset quick --out runs/q   # minutes on a CPU\n"
      f"  {cmd} --method ours hiro --out runs/paper   # the paper's run (a GPU job)\n"
      f"  {cmd} --resume runs/paper                   # continue a stopped run\n"
      f"  {cmd} --top.alpha 0 0.2 0.35 --low.batch_size 256   # any config field\n\n"
      f"exit codes: 0 done; 1 failed, interrupted (Ctrl-C, SIGTERM) or a lost process; 2 bad "
      f"input; 3 stopped by --time-limit. docs/experiments.md has the rest."))

  p.add_argument("--method", nargs="+", default=["ours"], choices=methods.METHODS,
                 metavar="METHOD",
                 help=f"one or more of {', '.join(methods.METHODS)}, into one --out: those that "
                      f"differ only in traced numbers (ours and its ablations) as lanes of one "
                      f"program, the others one after another (default: ours)")
  p.add_argument("--sweep", nargs="+", action="append", default=None,
                 metavar="FIELD=VALUE [VALUE ...]",
                 help="variants of each method, one per value of a dotted config field (a "
                      "tuple's entries joined by commas: --sweep top.alpha=0,0.4,0.7 0,0.2,0.35); "
                      "given twice, the grid of both; named method+field=value")
  p.add_argument("--preset", default="paper", choices=methods.PRESETS,
                 help=f"paper: the paper's numbers (docs/spec.md), {paper.seeds} seeds x "
                      f"{paper.steps:,} steps, a GPU job (days on a CPU for an ant); quick: "
                      f"{quick.seeds} seed{'s' * (quick.seeds > 1)} x {quick.steps:,} steps, "
                      f"the whole pipeline in "
                      f"minutes on a CPU (default: paper)")
  _add_size_flags(p, paper, quick)
  p.add_argument("--envs-per-seed", type=int, default=None, metavar="E",
                 help="E envs per seed with the preset's schedule and gradient samples per env "
                      "step (methods.widen_layer; --steps etc. then count vector steps of E envs; "
                      "default: 1)")
  p.add_argument("--grad-steps", type=int, default=None, metavar="U",
                 help="with --envs-per-seed: TD3 updates per vector step, each of batch x E/U "
                      "(default: E, the paper's updates exactly)")
  p.add_argument("--seed", type=int, default=0, metavar="N",
                 help="PRNG seed of the run (default: 0)")
  p.add_argument("--out", default=None, metavar="DIR",
                 help=f"a new or empty output folder (default: runs/{task}-<date>-<time>)")
  _add_run_flags(p, task)
  _add_process_flags(p)
  add_field_flags(p, task)
  return p


def _add_size_flags(p: argparse.ArgumentParser, paper, quick) -> None:
  """The run's size, each flag's default the preset's (``methods.RunSpec``)."""
  def size(name):
    a, b = getattr(paper, name), getattr(quick, name)
    return f"default: {a}" + ("" if a == b else f"; --preset quick: {b}")

  p.add_argument("--seeds", type=int, default=None, metavar="N",
                 help=f"seeds, vmapped ({size('seeds')})")
  p.add_argument("--steps", type=int, default=None, metavar="N",
                 help=f"vector env steps per seed ({size('steps')})")
  p.add_argument("--chunk", type=int, default=None, metavar="N",
                 help=f"steps per jitted call and metrics row ({size('chunk')})")
  p.add_argument("--checkpoint-every", type=int, default=None, metavar="N",
                 help=f"steps between checkpoints, a multiple of --chunk "
                      f"({size('checkpoint_every')})")
  p.add_argument("--episode-length", type=int, default=None, metavar="N",
                 help=f"env steps per episode ({size('episode_length')})")


class _Formatter(argparse.RawDescriptionHelpFormatter):
  """The epilog's examples as written; flags and their help in two columns."""

  WIDTH = 100

  def __init__(self, prog):
    super().__init__(prog, max_help_position=34, width=self.WIDTH)


def _add_run_flags(p: argparse.ArgumentParser, task: str) -> None:
  """How this process runs: resume, time limit, devices, physics, outputs."""
  p.add_argument("--resume", default=None, metavar="DIR",
                 help="continue the run in DIR with its saved configuration (config.json)")
  p.add_argument("--time-limit", type=float, default=None, metavar="SECONDS",
                 help="stop, checkpointed, before a chunk that would end past this many seconds "
                      f"of wall time; exit code {EXIT_TIME_LIMIT}, continue with --resume")
  p.add_argument("--cpu-devices", type=int, default=None, metavar="N",
                 help="on the CPU, split the lanes over N devices, e.g. one per core (about "
                      "1.6-2.5x faster at 16 seeds on 2 cores; --seeds a multiple of N; not "
                      "bit-identical to 1 device); --resume uses the run's count (default: 1)")
  if methods.TASKS[task].robot == "ant":
    from envs import contacts as contacts_lib  # MuJoCo and numpy only
    from envs.physics import PHYSICS
    p.add_argument("--physics", default="auto", choices=PHYSICS,
                   help="the ant's physics: c, MuJoCo's C engine called from inside the jitted "
                        "step (10-25x MJX on a CPU); mjx, the MJX pipeline (for accelerators); "
                        "auto: c on a CPU, mjx on an accelerator; --resume keeps the run's "
                        "(default: auto)")
    p.add_argument("--contacts", default=None, choices=contacts_lib.CONTACTS,
                   help="the ant's engine settings: mujoco200, those that make MuJoCo 3 move "
                        "the ant and blocks as MuJoCo 2.x with MuJoCo 2.0's capsule inertia, "
                        "what the paper's code ran; mujoco2, without the inertia (checked "
                        "against MuJoCo 2.3.7); mujoco3, MuJoCo 3's own (docs/environments.md); "
                        f"--resume keeps the run's (default: {contacts_lib.RUN_DEFAULT})")
  p.add_argument("--no-progress", action="store_true",
                 help="a line per chunk instead of the progress bar")
  p.add_argument("--tensorboard", action="store_true",
                 help="also write TensorBoard event files to OUT/tensorboard/<method> (needs "
                      "tensorboardX: pip install 'nonmono-jax[tensorboard]')")
  p.add_argument("--wandb", default=None, metavar="PROJECT", nargs="?", const="nonmono-jax",
                 help="also log to Weights & Biases, project PROJECT (default: nonmono-jax), one "
                      "W&B run per method; WANDB_MODE=offline keeps it on disk (needs wandb: "
                      "pip install 'nonmono-jax[wandb]')")


def _add_process_flags(p: argparse.ArgumentParser) -> None:
  """--distributed and the three flags that say where the processes are."""
  p.add_argument("--distributed", action="store_true",
                 help="one run over several processes (JAX's multi-process runtime): the "
                      "lanes are split over every process's devices, process 0 writes the run "
                      "folder (which all must see); on SLURM or Open MPI the processes find "
                      "each other, elsewhere give the three flags below (docs/cluster.md)")
  p.add_argument("--coordinator", default=None, metavar="HOST:PORT",
                 help="with --distributed: process 0's address and a free port")
  p.add_argument("--num-processes", type=int, default=None, metavar="N",
                 help="with --distributed: the run's process count")
  p.add_argument("--process-id", type=int, default=None, metavar="I",
                 help="with --distributed: this process's index, 0 to N - 1")


# --- the config's fields: types, help texts, defaults ------------------------------------------

def fields(cls, prefix: str = ""):
  """(dotted name, type, dataclasses.Field, owner class) of every leaf field, recursively."""
  hints = typing.get_type_hints(cls)
  for f in dataclasses.fields(cls):
    t = hints[f.name]
    if dataclasses.is_dataclass(t):
      yield from fields(t, prefix + f.name + ".")
    else:
      yield prefix + f.name, t, f, cls


@functools.lru_cache(maxsize=None)
def field_docs(cls) -> dict[str, str]:
  """Each field's comment in ``cls``'s source: the comment lines just above its declaration
  and the one after it on its line, joined (what a reader of the class sees)."""
  lines, _ = inspect.getsourcelines(cls)
  tree = ast.parse("".join(lines))
  docs = {}
  for node in tree.body[0].body:
    if not (isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name)):
      continue
    i, above = node.lineno - 1, []
    while i > 0 and lines[i - 1].strip().startswith("#"):
      above.insert(0, lines[i - 1].strip().lstrip("#").strip())
      i -= 1
    own = _trailing_comment(lines[node.end_lineno - 1])
    docs[node.target.id] = " ".join(above + ([own] if own else []))
  return docs


def _trailing_comment(line: str) -> str:
  """The comment at the end of a source line (a ``#`` outside quotes), without ``noqa``."""
  quote = None
  for i, ch in enumerate(line):
    if quote:
      quote = None if ch == quote else quote
    elif ch in "\"'":
      quote = ch
    elif ch == "#":
      return line[i + 1:].strip()
  return ""


def _text(value) -> str:
  """A value as it is written on the command line."""
  if isinstance(value, bool):
    return "true" if value else "false"
  if isinstance(value, tuple):
    return " ".join(_text(v) for v in value) if value else "(none)"
  return str(value)


def _defaults(task: str) -> dict:
  """{dotted field: {(preset, method): value}} on ``task``, for the methods that read it."""
  out = collections.defaultdict(dict)
  for preset in methods.PRESETS:
    for method in methods.METHODS:
      config, _ = methods.build_config(preset, method, task)
      for name, *_ in fields(config_lib.AgentConfig):
        if config.reads(name):
          out[name][preset, method] = config_lib.get(config, name)
  return out


def default_text(values: dict, section_readers=None) -> str:
  """``values`` ({(preset, method): value}) as one help clause: ours' paper value, then the
  methods and the quick preset where they differ, and which methods read the field if not
  those of its section (``section_readers``; all methods by default)."""
  readers = [m for m in methods.METHODS if ("paper", m) in values]

  def clause(preset):
    first = _text(values[preset, readers[0]])
    groups = collections.defaultdict(list)
    for m in readers:
      groups[_text(values[preset, m])].append(m)
    return "; ".join([first] + [f"{t} for {', '.join(ms)}" for t, ms in groups.items()
                                if t != first])

  paper, quick = clause("paper"), clause("quick")
  text = f"default: {paper}" + ("" if quick == paper else f"; --preset quick: {quick}")
  if readers != list(section_readers or methods.METHODS):
    text += f"; only for {', '.join(readers)}"
  return text


def _readers(values: dict) -> list[str]:
  return [m for m in methods.METHODS if ("paper", m) in values]


def _flag_kwargs(t, f) -> dict | None:
  """argparse's type, nargs, metavar and choices of a field of type ``t``; None: no flag."""
  allowed = f.metadata.get(config_lib.CHOICES)
  origin = typing.get_origin(t)
  if t is bool:
    return dict(type=_bool, metavar="{true,false}")
  if origin in (tuple, list, collections.abc.Sequence):
    args = typing.get_args(t)
    elem = args[0]
    fixed = origin is tuple and Ellipsis not in args
    nargs = len(args) if fixed else ("*" if allowed else "+")
    meta = "{" + ",".join(allowed) + "}" if allowed else elem.__name__.upper()
    return dict(type=elem, nargs=nargs, metavar=meta, choices=allowed)
  if t in (int, float, str):
    return dict(type=t, metavar=None if allowed else t.__name__.upper(), choices=allowed)
  return None


def add_field_flags(parser: argparse.ArgumentParser, task: str) -> None:
  """A flag per config field, grouped by the dataclass that holds it."""
  defaults, groups = _defaults(task), {}
  readers = collections.defaultdict(set)  # section -> the methods that read any of its fields
  for name, values in defaults.items():
    readers[name.rpartition(".")[0]].update(_readers(values))
  for name, t, f, owner in fields(config_lib.AgentConfig):
    kwargs = _flag_kwargs(t, f)
    if kwargs is None:
      continue
    section = name.rpartition(".")[0]
    ordered = [m for m in methods.METHODS if m in readers[section]]
    if section not in groups:
      groups[section] = parser.add_argument_group(_section_title(section, ordered))
    help_text = field_docs(owner).get(f.name, "")
    groups[section].add_argument(
        f"--{name}", dest="field:" + name, default=argparse.SUPPRESS,
        help=f"{help_text} ({default_text(defaults[name], ordered)})".replace("%", "%%"),
        **kwargs)


def _section_title(section: str, readers) -> str:
  """A group's title: the dotted section, its field's comment in the class above it, and the
  methods that read it if not all."""
  only = "" if list(readers) == list(methods.METHODS) else f" (read by {', '.join(readers)})"
  if not section:
    return f"agent config: --FIELD VALUE, a tuple's entries as separate values{only}"
  parent, _, name = section.rpartition(".")
  cls = config_lib.AgentConfig
  for part in parent.split(".") if parent else []:
    cls = typing.get_type_hints(cls)[part]
  return f"{section}.*: {field_docs(cls).get(name, '')}{only}"


# --- values as the flags parse them --------------------------------------------------------------

def _bool(text: str) -> bool:
  if text.lower() in ("1", "true", "yes", "on"):
    return True
  if text.lower() in ("0", "false", "no", "off"):
    return False
  raise argparse.ArgumentTypeError(f"expected true or false, got {text!r}")


def typed(t, text: str):
  """A field's value from text by its type: a sequence's entries joined by commas."""
  if typing.get_origin(t) in (tuple, list, collections.abc.Sequence):
    elem = typing.get_args(t)[0]
    return tuple(elem(x) for x in text.split(","))
  return _bool(text) if t is bool else t(text)


def parse_sweep(given) -> dict:
  """``[["top.alpha=0,0.4,0.7", "0,0.2,0.35"], ...]`` -> {"top.alpha": [(0, 0.4, 0.7), ...]};
  each value parsed by its field's type, as the field's own flag parses it."""
  types = {name: t for name, t, *_ in fields(config_lib.AgentConfig)}
  sweep = {}
  for tokens in given or []:
    path, sep, first = tokens[0].partition("=")
    if not sep or not path:
      raise ValueError(f"--sweep takes FIELD=VALUE [VALUE ...], got {' '.join(tokens)}")
    if path not in types:
      raise ValueError(f"--sweep {path}: not a config field with a value (see --help)")
    if path in sweep:
      raise ValueError(f"--sweep {path} is given twice")
    try:
      sweep[path] = [typed(types[path], text) for text in [first] + tokens[1:]]
    except (ValueError, argparse.ArgumentTypeError) as e:
      raise ValueError(f"--sweep {path}: {e}") from None
  return sweep
