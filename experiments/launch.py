"""How every experiment command starts: answer ``--help`` and bad flags before JAX loads, then
run ``experiments.cli``.

    python -m experiments.antpush --help        # experiments/antpush.py -> launch.main
    python -m experiments antpush --preset quick

The entry modules install the Ctrl-C handler first (``nonmono_jax.host.interrupts``), then call
``main``, which imports only the flags (``experiments.flags``: the config dataclasses and the
presets, no JAX, no MuJoCo for a point task) until the flags parse; a Ctrl-C during the heavy
imports that follow is one line too.
"""

from __future__ import annotations

import sys

from experiments import flags


def main(task_name: str, argv=None) -> None:
  """Run the command on ``task_name`` (a task of the registry in any case, or a module name
  ``experiments.antpush``) with ``argv``; exits with the command's code."""
  argv = sys.argv[1:] if argv is None else list(argv)
  try:
    task = flags.resolve_task(task_name.rpartition(".")[2])
  except ValueError as e:
    sys.exit(_usage(str(e)))
  flags.make_parser(task).parse_args(argv)  # --help, or exit 2 on a bad flag, without JAX
  from experiments import cli  # JAX, MuJoCo, the envs: seconds
  sys.exit(cli.main(task, argv))


def main_any_task(argv=None) -> None:
  """``python -m experiments TASK [flags]``: the task is the first argument."""
  argv = sys.argv[1:] if argv is None else list(argv)
  if not argv or argv[0].startswith("-"):
    help_asked = bool(argv) and argv[0] in ("-h", "--help")
    sys.exit(_usage(None if help_asked else "a task is needed", code=0 if help_asked else 2))
  main(argv[0], argv[1:])


def _usage(error: str | None, code: int = flags.EXIT_BAD_INPUT) -> int:
  """The generic command's usage (and an error) on one line each; the exit code."""
  from nonmono_jax.host import methods
  usage = (f"usage: python -m experiments TASK [flags]; TASK one of "
           f"{', '.join(methods.TASKS)} (any case); python -m experiments TASK --help lists "
           f"the flags")
  if error is None:
    print(usage)
    return code
  print(f"python -m experiments: error: {error}", file=sys.stderr)
  return code
