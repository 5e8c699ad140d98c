"""The Buzz reference tables: every built-in is a BittyBuzz name, every world's host functions
are documented exactly, and docs/buzz-reference.md is the page the tables make."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from bbzide.compiler.reference import BUILTINS
from bbzide.compiler.string_table import BITTYBUZZ_BASE_STRINGS
from bbzide.worlds.engine import Simulation
from bbzide.worlds.reference import (
    HOST_FUNCTIONS,
    completion_items,
    entries_for,
    reference_markdown,
)
from bbzide.worlds.registry import WORLDS

REPO = Path(__file__).resolve().parents[2]
PAGE = REPO / "docs" / "buzz-reference.md"

#: Built-in global functions BittyBuzz registers under strings of its own (not the base 46).
GLOBAL_FUNCTIONS = {"foreach", "filter", "map", "reduce", "size"}


def test_every_builtin_is_a_bittybuzz_name():
    for entry in BUILTINS:
        assert entry.completion in BITTYBUZZ_BASE_STRINGS or entry.completion in \
            GLOBAL_FUNCTIONS, entry.name
        assert entry.doc.strip() and entry.group


@pytest.mark.parametrize("world", sorted(WORLDS))
def test_every_host_function_of_a_world_is_documented_and_nothing_else(world):
    sim = Simulation(world, None, robots=1, seed=0)
    offered = set(sim.world.host_functions(sim, 0))
    documented = [entry.name for entry in HOST_FUNCTIONS[world]]
    assert len(documented) == len(set(documented))
    assert set(documented) == offered
    assert set(documented) <= set(WORLDS[world].host_names)   # compiled into the string table
    assert {e.name for e in entries_for(world)} >= offered | {"neighbors.broadcast", "id"}


def test_the_reference_page_is_up_to_date():
    assert PAGE.read_text(encoding="utf-8") == reference_markdown(), \
        "docs/buzz-reference.md is out of date: run scripts/buzz_reference.py"
    for entry in (*BUILTINS, *HOST_FUNCTIONS["crazyflie"]):
        assert (entry.signature or entry.name) in PAGE.read_text(encoding="utf-8")


def test_the_generator_script_checks_the_page():
    done = subprocess.run([sys.executable, str(REPO / "scripts" / "buzz_reference.py"),
                           "--check"], capture_output=True, text=True, cwd=REPO)
    assert done.returncode == 0, done.stderr


def test_completion_items_offer_the_worlds_own_host_functions_as_json():
    import json

    kilobot = {item["label"]: item for item in json.loads(json.dumps(completion_items("kilobot")))}
    assert kilobot["set_motor"]["signature"] == "set_motor(left, right)"
    assert kilobot["broadcast"]["name"] == "neighbors.broadcast" and kilobot["broadcast"]["memory"]
    assert "takeoff" not in kilobot                                  # another world's
    assert "takeoff" in {item["label"] for item in completion_items("crazyflie")}
    assert {item["label"] for item in completion_items(None)} == {e.completion for e in BUILTINS}
