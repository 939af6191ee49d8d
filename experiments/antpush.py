"""`python -m experiments.antpush`: the paper's experiment on AntPush (see `experiments/cli.py`).

    python -m experiments.antpush --method ours hiro ref-uniform ref-ppo --preset quick
    python -m experiments.antpush --help          # every option and config field
"""

import sys

from experiments import cli

if __name__ == "__main__":
  sys.exit(cli.main(cli.task_of_module(__spec__.name)))
