"""The worlds that exist: name -> `WorldSpec` (example script, profile, host names, factory).

Design: the registry is data, so the UI and the CLI can list worlds, pick the example script and
compile for the right string table without building a world (no pymunk space, no light field).
Each factory imports its world module only when called. A world module added later (the M300
field) registers itself here with one entry.

Options come from users (`--set KEY=VALUE`, already turned into int/float/str), so the factory
checks them against the world class's keyword parameters before building it: an unknown name lists
the names there are; a word where the annotation says number, a fraction where it says int, a
NaN or infinity, or a scalar for a list-valued parameter (obstacles) is refused by name. The world
classes then check ranges (sizes, spacings) themselves.
"""

from __future__ import annotations

import importlib
import inspect
import math
import numbers
from typing import Any

from bbzide.worlds.radio import WorldConfigError
from bbzide.worlds.world import World, WorldSpec

#: Parameter annotations (strings: the world modules use postponed annotations) whose values a
#: `KEY=VALUE` option can give. Anything else (a `Sequence[...]`) cannot come from a command line.
_NUMBER_ANNOTATIONS = {"float", "int", "float | None", "int | None"}


def check_options(world_class: type, options: dict[str, Any]) -> None:
    """Refuse an option `world_class(**options)` cannot take, naming it (WorldConfigError)."""
    parameters = {name: parameter
                  for name, parameter in inspect.signature(world_class).parameters.items()
                  if parameter.kind is inspect.Parameter.KEYWORD_ONLY
                  or parameter.kind is inspect.Parameter.POSITIONAL_OR_KEYWORD}
    for key, value in options.items():
        parameter = parameters.get(key)
        if parameter is None:
            raise WorldConfigError(f"bad option {key!r} for the {world_class.__name__} world; "
                                   f"its options are {', '.join(parameters)}")
        annotation = parameter.annotation
        if not isinstance(annotation, str):  # not written by our world modules: no check
            continue
        shown = f"{key}={value}"
        if isinstance(value, numbers.Real) and not math.isfinite(value):
            raise WorldConfigError(f"world option {shown}: a finite number is needed")
        if annotation in _NUMBER_ANNOTATIONS:
            if value is None and "None" in annotation:
                continue
            if not isinstance(value, numbers.Real) or isinstance(value, bool):
                raise WorldConfigError(f"world option {shown}: a number is needed")
            if annotation.startswith("int") and not isinstance(value, numbers.Integral):
                raise WorldConfigError(f"world option {shown}: a whole number is needed")
        elif ("Sequence" in annotation and "str" not in annotation and "Any" not in annotation
              and isinstance(value, (str, numbers.Real))):
            raise WorldConfigError(f"world option {key} cannot be set as KEY=VALUE "
                                   f"(it is a list; give it from Python)")


def _lazy(module: str, cls: str) -> Any:
    def build(**options: Any) -> World:
        world_class = getattr(importlib.import_module(module), cls)
        check_options(world_class, options)
        try:
            return world_class(**options)
        except TypeError as error:
            raise WorldConfigError(f"bad option for the {cls} world: {error}") from None

    return build


#: The seed of a world when none is given, the same for `bbzide run --world` and the IDE, so a
#: run seen in the IDE repeats on the command line (0: the engine's and the harness's default).
DEFAULT_SEED = 0

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
