"""`python -m experiments.pointfall`: the paper's experiment on PointFall (see `experiments/cli.py`).

    python -m experiments.pointfall --method ours hiro ref-uniform ref-ppo --preset quick
    python -m experiments.pointfall --help          # every option and config field
"""

import sys

from experiments import cli

if __name__ == "__main__":
  sys.exit(cli.main(cli.task_of_module(__spec__.name)))
