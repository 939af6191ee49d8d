"""`python -m experiments.antmaze`: the paper's experiment on AntMaze (see `experiments/cli.py`).

    python -m experiments.antmaze --method ours hiro ref-uniform ref-ppo --preset quick
    python -m experiments.antmaze --help          # every option and config field
"""

import sys

from experiments import cli

if __name__ == "__main__":
  sys.exit(cli.main(cli.task_of_module(__spec__.name)))
