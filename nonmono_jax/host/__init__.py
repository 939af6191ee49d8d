"""The host side: what plans a run, feeds the jitted core chunk by chunk and keeps what comes out.

    methods                the presets: tasks (the registry), methods, per-task numbers
    plan                   a run as data (Plan): configs from presets and dotted overrides;
                           config.json to and from it
    programs               a trainer per group of variants, built once; the memory check
    run                    the run folder: open, lock (runlock), resume, the chunk loop
    sinks, io              metrics.csv / JSONL / TensorBoard / progress; files and checkpoints
    processes              one run over several processes (JAX's multi-process runtime)
"""
