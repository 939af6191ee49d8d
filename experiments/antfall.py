"""`python -m experiments.antfall`: the paper's experiment on AntFall (see `experiments/cli.py`).

    python -m experiments.antfall --method ours hiro ref-uniform ref-ppo --preset quick
    python -m experiments.antfall --help          # every option and config field
"""

import sys

from experiments import cli

if __name__ == "__main__":
  sys.exit(cli.main(cli.task_of_module(__spec__.name)))
