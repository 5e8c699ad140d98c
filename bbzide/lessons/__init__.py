"""The teaching track: lessons a class follows from a blinking LED to swarm behaviours.

Design: a lesson is a data folder here (`NN-slug/`: `lesson.md`, `scenario.toml`,
`starter.bzz`, `solution.bzz`) plus an automatic check in `checks.py`, found by its slug. The
room sits above the worlds (a check builds and steps a `Simulation` from the lesson's scenario)
and below the UI (which opens a lesson in the IDE); `catalog.py` lists the lessons and keeps
each student's work, `checks.py` runs a check headless and says what passed or what to look at.
"""
