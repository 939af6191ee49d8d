"""`python -m experiments TASK [flags]`: any task of the registry (``methods.TASKS``), the same
command as ``python -m experiments.<task>``; a task added to the registry runs here with no
module of its own.

    python -m experiments PointMaze --method ours hiro --preset quick
    python -m experiments AntPush --help
"""

import sys

from experiments import cli
from nonmono_jax.host import methods

if __name__ == "__main__":
  if len(sys.argv) < 2 or sys.argv[1] not in methods.TASKS:
    print(f"usage: python -m experiments TASK [flags]; TASK one of {', '.join(methods.TASKS)}",
          file=sys.stderr)
    sys.exit(2)
  sys.exit(cli.main(sys.argv[1], sys.argv[2:]))
