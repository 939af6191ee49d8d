"""nonmono-jax: the learners, the three-level agent and the vmapped trainer.

Two halves (ARCHITECTURE.md): ``nonmono_jax.core``, the jitted program (the agent of Kim et
al. 2023, Algorithm 1, its learners and the trainer), and ``nonmono_jax.host``, the Python
side that plans a run and keeps its folder. The environments are the top-level ``envs``
package; the commands are ``experiments``.
"""

__version__ = "0.1.0"
