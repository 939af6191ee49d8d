"""`python -m experiments TASK [flags]`: any task of the registry (``methods.TASKS``), the same
command as ``python -m experiments.<task>``; a task added to the registry runs here with no
module of its own.

    python -m experiments PointMaze --method ours hiro --preset quick
    python -m experiments antpush --help          # a task's name in any case
"""

if __name__ == "__main__":
  from nonmono_jax.host import interrupts
  interrupts.install()  # first: a Ctrl-C at any moment of start-up is one line
  from experiments import launch
  launch.main_any_task()
