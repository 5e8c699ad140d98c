"""bbzide: a browser IDE and simulator for Buzz swarm programs on a BittyBuzz VM model.

Rooms, lowest first (a room never imports a higher one):
compiler (Buzz -> .basm -> .bo -> .bbo), vm (the BittyBuzz VM model), worlds (engine, radio,
physics), ui (viser IDE, recording and replay). See ARCHITECTURE.md.
"""

__version__ = "0.1.0"
