"""The recording room: missions written to Rerun `.rrd` files and read back for replay.

Above the worlds room (it observes a `bbzide.worlds.engine.Simulation`; the engine never imports
it). `recorder.py` writes, `reader.py` reads, `rebuild.py` rebuilds a robot's exact VM at any
recorded step, `layout.py` names the entity paths, `blueprint.py` is the Rerun viewer layout,
`commands.py` adds `--record` to `bbzide run`.
"""
