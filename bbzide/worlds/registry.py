"""The worlds that exist: name -> `WorldSpec` (example script, profile, host names, factory).

Design: the registry is data, so the UI and the CLI can list worlds, pick the example script and
compile for the right string table without building a world (no pymunk space, no light field).
Each factory imports its world module only when called. A world module added later (the M300
field) registers itself here with one entry.
"""

from __future__ import annotations

import importlib
from typing import Any

from bbzide.worlds.radio import WorldConfigError
from bbzide.worlds.world import World, WorldSpec


def _lazy(module: str, cls: str) -> Any:
    def build(**options: Any) -> World:
        world_class = getattr(importlib.import_module(module), cls)
        try:
            return world_class(**options)
        except TypeError as error:
            raise WorldConfigError(f"bad option for the {cls} world: {error}") from None

    return build


#: Host names of the Kilobot world, in string-table order. The first four are the BittyBuzz
#: Kilobot firmware's (`KILOBOT_HOST_NAMES`, compiler string table); the rest are ours.
KILOBOT_HOST_NAMES = ("led", "set_motor", "delay", "abs", "rand", "light", "motion")

#: Host names of the Crazyflie world. The direction and coordinate names are host strings so
#: that `ranges()` and `position()` can return tables keyed by them.
CRAZYFLIE_HOST_NAMES = (
    "led", "delay", "rand", "takeoff", "land", "hover", "goTo", "ranges", "position",
    "flying", "front", "back", "left", "right", "up", "x", "y", "z",
)

#: Host names of the M300 field: its host functions, then the keys of the tables they return.
M300_HOST_NAMES = (
    "takeoff", "land", "goto", "position", "arrived", "flying", "camera", "random_goal",
    "prior", "distance", "mission", "set_role", "know_target", "relay_link", "rand", "clock",
    "doze", "missed",
    "x", "y", "z", "cell", "search", "steps", "size", "rx", "ry", "range", "cells", "threshold",
)

WORLDS: dict[str, WorldSpec] = {
    "kilobot": WorldSpec(
        name="kilobot",
        title="Kilobot table",
        example="examples/kilobot/gradient.bzz",
        profile="kilobot",
        host_names=KILOBOT_HOST_NAMES,
        default_robots=25,
        factory=_lazy("bbzide.worlds.kilobot", "KilobotTable"),
        options={"width": 1.0, "height": 1.0, "light": "gradient"},
    ),
    "crazyflie": WorldSpec(
        name="crazyflie",
        title="Crazyflie lab",
        example="examples/crazyflie/consensus.bzz",
        profile="crazyflie",
        host_names=CRAZYFLIE_HOST_NAMES,
        default_robots=10,
        factory=_lazy("bbzide.worlds.crazyflie", "CrazyflieLab"),
        options={"width": 6.0, "depth": 6.0, "height": 3.0},
    ),
    "m300": WorldSpec(
        name="m300",
        title="M300 field",
        example="examples/m300/flocking.bzz",
        profile="m300",
        host_names=M300_HOST_NAMES,
        default_robots=6,
        factory=_lazy("bbzide.worlds.m300", "M300Field"),
        options={"size": 36.0, "comm_range": 10.0, "speed": 2.0, "altitude": 5.0,
                 "targets": 3, "cells": 10, "search": "belief"},
    ),
}


def world_spec(name: str) -> WorldSpec:
    """The spec called `name`, or a user error naming the worlds that exist."""
    try:
        return WORLDS[name]
    except KeyError:
        raise WorldConfigError(
            f"unknown world {name!r}; choose one of {', '.join(sorted(WORLDS))}") from None


def create_world(name: str, **options: Any) -> World:
    return world_spec(name).create(**options)
