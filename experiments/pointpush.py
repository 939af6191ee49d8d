"""`python -m experiments.pointpush`: the paper's experiment on PointPush
(see `experiments/cli.py`).

    python -m experiments.pointpush --method ours hiro ref-uniform ref-ppo --preset quick
    python -m experiments.pointpush --help          # every option and config field
"""

if __name__ == "__main__":
  from nonmono_jax.host import interrupts
  interrupts.install()  # first: a Ctrl-C at any moment of start-up is one line
  from experiments import launch
  launch.main(__spec__.name)
