"""Each world's host functions as data (signature, doc, memory cost), and the Buzz reference
page made from them and the language's built-ins (bbzide/compiler/reference.py).

Design: `HOST_FUNCTIONS[world]` documents every host function that world's robots get (a test
builds each world and compares the names with `World.host_functions`, so a function added to a
world without a line here fails). `reference_markdown()` renders docs/buzz-reference.md;
scripts/buzz_reference.py writes it and a test checks the file is up to date. The editor's
completion and hover read the same tables.
"""

from __future__ import annotations

from bbzide.compiler.reference import BUILTINS, LANGUAGE_SECTIONS, ReferenceEntry
from bbzide.worlds.registry import WORLDS

_RETURNS_INT = "one whole number"
_RETURNS_TABLE = "a new table (one object, one segment, an object per entry)"


def _host(name: str, signature: str, doc: str, memory: str = "") -> ReferenceEntry:
    return ReferenceEntry(name, signature, doc, memory, group="Host functions")


HOST_FUNCTIONS: dict[str, tuple[ReferenceEntry, ...]] = {
    "kilobot": (
        _host("led", "led(colour)", "Light the RGB LED: bit 1 red, bit 2 green, bit 4 blue "
              "(`led(0)` off, `led(7)` white)."),
        _host("set_motor", "set_motor(left, right)", "Vibration motor duties, 0..255 each: "
              "both on walks forward, one on turns about the other leg."),
        _host("motion", "motion(kind)", "Walk: 0 stop, 1 forward, 2 turn left, 3 turn right "
              "(about 1 cm/s and 45 degrees/s). Another kind stops the robot (OUTOFRANGE)."),
        _host("delay", "delay(ms)", "Block the robot for `ms` milliseconds: it skips its "
              "control steps meanwhile (a whole step is 100 ms)."),
        _host("abs", "abs(x)", "The absolute value of a whole number (`abs(-32768)` wraps to "
              "-32768).", _RETURNS_INT),
        _host("rand", "rand()", "A random whole number 0..255 (each robot its own stream).",
              _RETURNS_INT),
        _host("light", "light()", "The ambient light under the robot, 0..1023 (10-bit "
              "sensor).", _RETURNS_INT),
    ),
    "crazyflie": (
        _host("led", "led(colour)", "Light the LED: bit 1 red, bit 2 green, bit 4 blue."),
        _host("delay", "delay(ms)", "Does nothing (the BittyBuzz Crazyflie firmware's)."),
        _host("takeoff", "takeoff(height)", "Climb to `height` metres (at least 0.1 m, below "
              "the ceiling) and start flying."),
        _host("land", "land()", "Descend to the floor and stop the motors."),
        _host("hover", "hover()", "Stay where the drone is now."),
        _host("goTo", "goTo(x, y, z)", "Fly to the room point (x, y, z) in metres (the room's "
              "centre is 0, 0; the floor is z = 0). Ignored while on the floor."),
        _host("ranges", "ranges()", "The multi-ranger's distances in metres, a table {front, "
              "back, left, right, up} (floats, up to 4 m), in the drone's frame.",
              _RETURNS_TABLE),
        _host("position", "position()", "Where the drone is: {x, y, z} in metres (floats, 1 cm "
              "noise).", _RETURNS_TABLE),
        _host("flying", "flying()", "1 while flying (after takeoff, until land), else 0.",
              _RETURNS_INT),
        _host("rand", "rand()", "A random whole number 0..255.", _RETURNS_INT),
    ),
    "m300": (
        _host("takeoff", "takeoff()", "Climb to the mission altitude."),
        _host("land", "land()", "Descend and stop the motors."),
        _host("goto", "goto(x, y)", "Fly to (x, y) decimetres at the mission altitude "
              "(clipped to the field)."),
        _host("position", "position()", "{x, y, z, cell}: where the drone is (decimetres) and "
              "the index of the belief cell under it.", _RETURNS_TABLE),
        _host("arrived", "arrived()", "1 when flying within 0.3 m of the last goto point.",
              _RETURNS_INT),
        _host("flying", "flying()", "1 when airborne and not landing.", _RETURNS_INT),
        _host("camera", "camera()", "nil, or {x, y}: the ground position (dm) of the nearest "
              "target in the camera's footprint.", _RETURNS_TABLE),
        _host("random_goal", "random_goal()", "{x, y, cell}: a uniform random point of the "
              "field.", _RETURNS_TABLE),
        _host("prior", "prior(cell)", "The prior belief of a cell, 0..100 (percent).",
              _RETURNS_INT),
        _host("distance", "distance(x1, y1, x2, y2)", "Euclidean distance in decimetres "
              "(rounded).", _RETURNS_INT),
        _host("mission", "mission()", "{search, steps, size, rx, ry, range, cells, threshold}: "
              "the mission's settings (search 1 = belief map, 0 = random walk).",
              _RETURNS_TABLE),
        _host("set_role", "set_role(code)", "Show the drone's role in the IDE (and its LED "
              "colour): 0 searcher, 1 root candidate, 2 root, 3 auctioneer, ..."),
        _host("know_target", "know_target(x, y)", "The drone knows a target at (x, y) dm "
              "(drawn by the IDE)."),
        _host("relay_link", "relay_link(parent)", "The drone relays for robot `parent` (-1: "
              "none); drawn as the relay tree."),
        _host("missed", "missed(dm)", "Percent (0..100) of a belief cell's value left after "
              "the camera swept `dm` decimetres over it without a sighting.", _RETURNS_INT),
        _host("rand", "rand()", "A random whole number 0..255.", _RETURNS_INT),
        _host("clock", "clock()", "The world's control step number.", _RETURNS_INT),
        _host("doze", "doze(n)", "Skip up to `n` control steps while the flight controller "
              "flies on; woken early on arrival, a new cell or a sighting."),
    ),
}


def entries_for(world: str | None) -> tuple[ReferenceEntry, ...]:
    """What a script in `world` can call: the built-ins, then the world's host functions."""
    return BUILTINS + (HOST_FUNCTIONS.get(world, ()) if world else ())


def completion_items(world: str | None) -> list[dict[str, str]]:
    """`entries_for(world)` as plain data (JSON-ready), for an editor's completion and hover:
    label (what is typed after a dot), name, signature, doc, memory, group."""
    return [{"label": e.completion, "name": e.name, "signature": e.signature or e.name,
             "doc": e.doc, "memory": e.memory, "group": e.group}
            for e in entries_for(world)]


def _entry_markdown(entry: ReferenceEntry) -> list[str]:
    call = entry.signature or entry.name
    lines = [f"- `{call}`: {entry.doc}"]
    if entry.memory:
        lines.append(f"  *Memory:* {entry.memory}.")
    return lines


def reference_markdown() -> str:
    """The whole reference page (docs/buzz-reference.md)."""
    out = ["# Buzz on BittyBuzz: language reference", "",
           "<!-- Generated by scripts/buzz_reference.py from bbzide/compiler/reference.py and "
           "bbzide/worlds/reference.py: edit those, then run the script. -->", "",
           "Buzz as the robots in bbzide run it: the BittyBuzz virtual machine, with its "
           "16-bit numbers, its small heap and its differences from desktop Buzz.", ""]
    for title, body in LANGUAGE_SECTIONS:
        out += [f"## {title}", "", body, ""]
    out += ["## Built-ins", "", "Every robot has these, whatever the world. `vs` stands for "
            "a table made by `stigmergy.create`, `s` for one made by `swarm.create`.", ""]
    groups: dict[str, list[ReferenceEntry]] = {}
    for entry in BUILTINS:
        groups.setdefault(entry.group, []).append(entry)
    for group, entries in groups.items():
        out += [f"### {group}", ""]
        for entry in entries:
            out += _entry_markdown(entry)
        out.append("")
    out += ["## Host functions of each world", "", "A host function is C code of the robot's "
            "firmware, called like a Buzz function. A call to a function of another world "
            "stops the robot with a TYPE error (the name is nil there).", ""]
    for world, entries in HOST_FUNCTIONS.items():
        spec = WORLDS[world]
        out += [f"### {spec.title} (`{world}`, {spec.profile} profile)", ""]
        for entry in entries:
            out += _entry_markdown(entry)
        out.append("")
    return "\n".join(out).rstrip() + "\n"
