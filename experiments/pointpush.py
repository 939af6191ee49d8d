"""`python -m experiments.pointpush`: the paper's experiment on PointPush (see `experiments/cli.py`).

    python -m experiments.pointpush --method ours hiro ref-uniform ref-ppo --preset quick
    python -m experiments.pointpush --help          # every option and config field
"""

import sys

from experiments import cli

if __name__ == "__main__":
  sys.exit(cli.main(cli.task_of_module(__spec__.name)))
