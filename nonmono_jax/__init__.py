"""nonmono-jax: the learners, the three-level agent and the vmapped trainer.

The environments live in the top-level ``envs`` package; this package holds the learning side
(Kim et al. 2023, Algorithm 1), built in the trainer issue.
"""

__version__ = "0.1.0"
