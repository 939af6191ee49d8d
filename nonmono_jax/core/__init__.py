"""The jitted core: pure functions over flax.struct state, what runs inside ``jax.jit``.

    config, lanes          the configuration; which of its fields are a lane's traced numbers
    agent                  one env step of the whole agent (the paper's Algorithm 1, in phases)
    modes, top, switch,    how g_expl_mode is chosen: HIRO's fixed TD3, the Top PPO (ours),
      homeostasis            Pislar et al.'s informed trigger (Ref:*)
    low, middle            the Low and Middle levels; hierarchy: the formulas that tie them
    td3, ppo, learning     the learners and their gradient step
    buffers, relabel,      replay buffers, HIRO's goal relabelling, MLPs,
      networks, gates        branches that cost nothing when skipped
    evaluate, metrics      S_E episodes; per-step metrics and their chunk reductions
    train                  the trainer: lax.scan over steps, vmap over lanes, shard_map over devices

Nothing here touches files, clocks or processes: that is ``nonmono_jax.host``.
"""
