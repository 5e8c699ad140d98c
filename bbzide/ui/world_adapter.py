"""The compiler, VM and worlds rooms as the IDE sees them: the one file that imports them.

Everything the UI needs from the lower rooms passes through `WorldsBackend` (which worlds exist,
compile for a world's platform, start a swarm) and `WorldsSimulation` (step, draw, inspect). The
contracts in ARCHITECTURE.md name the calls (`compile_source`, `bittybuzz_string_table`,
`CompiledProgram.to_bbo`, `Simulation(world, program, robots=N, seed=K)`, `Robot.vm`,
`PlatformProfile`) but not every field, so field look-ups go through `_field`, which names the
spellings it accepts; when a room settles a name, this is the only place to change.

Lower rooms are imported lazily, so `bbzide --help` never needs them, and a missing room is a
`UserError` that says which one, never a traceback.
"""

from __future__ import annotations

import importlib
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from bbzide.diagnostics import UserError
from bbzide.ui.heap_decode import HeapGeometry, HeapReader
from bbzide.ui.inspection import RobotInspection
from bbzide.ui.world_backend import SwarmFrame, WorldGeometry

REPO_ROOT = Path(__file__).resolve().parents[2]
#: `bbzide` with no arguments opens this world with this many robots (the issue: "the Kilobot
#: table with ~25 robots").
DEFAULT_WORLD_HINT = "kilobot"
DEFAULT_ROBOTS = 25
#: Objects per table segment when a profile does not say (BittyBuzz's default, notes §E.1).
DEFAULT_ELEMS_PER_SEGMENT = 5
#: Kilobot radius (m), used when a world does not say how big its robots are.
KILOBOT_RADIUS = 0.0165


#: Microcontroller memories the VM profiles do not carry: (RAM bytes, flash bytes). Kilobot:
#: ATmega328P, 2 KB SRAM and 32 KB flash (the firmware and the .bbo share the flash).
PLATFORM_MEMORY = {"kilobot": (2048, 32768)}


class MissingRoomError(UserError):
    """A room the IDE needs (compiler, VM, worlds) is not in this build."""


def _import(module: str) -> ModuleType:
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as missing:
        raise MissingRoomError(
            f"the IDE needs {module}, which is not in this build ({missing.name} is missing)"
        ) from None


def _field(obj: Any, names: Sequence[str], default: Any = None) -> Any:
    """The first of `names` that `obj` has (attribute or mapping key), else `default`."""
    for name in names:
        if isinstance(obj, dict) and name in obj:
            return obj[name]
        if hasattr(obj, name):
            value = getattr(obj, name)
            return value() if callable(value) and name.startswith(("get_", "compute_")) else value
    return default


class WorldsBackend:
    """The real worlds (bbzide.worlds), compiled with the real compiler for each platform."""

    def __init__(self) -> None:
        self._compiler = _import("bbzide.compiler")
        self._engine = _import("bbzide.worlds.engine")
        worlds_package = _import("bbzide.worlds")
        registry = _field(self._engine, ("WORLDS",)) or _field(worlds_package, ("WORLDS",))
        if not registry:
            raise MissingRoomError("bbzide.worlds has no WORLDS registry")
        self._worlds: dict[str, Any] = dict(registry)

    # ---- what exists ---------------------------------------------------------------------------
    def world_names(self) -> list[str]:
        return list(self._worlds)

    def default_world(self) -> str:
        names = self.world_names()
        return next((n for n in names if DEFAULT_WORLD_HINT in n.lower()), names[0])

    def default_robots(self, world: str) -> int:
        return int(_field(self._worlds[world], ("default_robots",), DEFAULT_ROBOTS))

    def example_path(self, world: str) -> Path | None:
        example = _field(self._worlds[world], ("example", "example_path", "default_script"))
        if example is None:
            return None
        path = Path(example)
        return path if path.is_absolute() else REPO_ROOT / path

    def platform(self, world: str) -> Any:
        spec = self._worlds[world]
        profile = _field(spec, ("profile", "platform"))
        if isinstance(profile, str):
            profile = _import("bbzide.vm.profiles").PROFILES[profile]
        return profile

    def flash_budget(self, world: str) -> int | None:
        name = str(_field(self.platform(world), ("name",), ""))
        return PLATFORM_MEMORY.get(name, (None, None))[1]

    def host_names(self, world: str) -> list[str]:
        spec = self._worlds[world]
        names = _field(spec, ("host_names", "host_function_names"))
        if names is None:
            functions = _field(spec, ("host_functions",), {})
            names = list(functions) if isinstance(functions, dict) else []
        return list(names)

    # ---- compile and run -----------------------------------------------------------------------
    def compile(self, text: str, path: Path, world: str) -> tuple[Any, Any]:
        strings = self._compiler.bittybuzz_string_table(self.host_names(world))
        compiled = self._compiler.compile_source(
            text, str(path), include_path=(str(path.parent),), string_table=strings
        )
        return compiled, compiled.to_bbo()

    def create(self, world: str, program: Any, robots: int, seed: int) -> WorldsSimulation:
        simulation = self._engine.Simulation(world, program, robots=robots, seed=seed)
        return WorldsSimulation(simulation, program, self.platform(world))


class WorldsSimulation:
    """A `bbzide.worlds.engine.Simulation` behind the UI's `SimulationHandle` interface."""

    def __init__(self, simulation: Any, program: Any, profile: Any) -> None:
        self.sim = simulation
        self.program = program
        self.profile = profile

    @property
    def step_count(self) -> int:
        return int(_field(self.sim, ("step_count", "steps", "step_index", "time_step"), 0))

    def step(self) -> None:
        self.sim.step()

    def _robot_states(self) -> list[Any]:
        return list(self.sim.robots)

    def robot(self, index: int) -> Any:
        state = self._robot_states()[index]
        return _field(state, ("robot", "firmware"), state)

    def load_program(self, program: Any, keep_state: bool) -> None:
        self.program = program
        self.sim.load_program(program, keep_state=keep_state)

    def frame(self) -> SwarmFrame:
        states = self._robot_states()
        count = len(states)
        positions = np.zeros((count, 2))
        headings = np.zeros(count)
        leds = np.zeros((count, 3))
        failed = np.zeros(count, dtype=bool)
        ids: list[int] = []
        for i, state in enumerate(states):
            pose = _field(state, ("pose", "position"))
            positions[i] = (pose[0], pose[1])
            heading = _field(state, ("heading", "theta", "yaw"))
            headings[i] = heading if heading is not None else (pose[2] if len(pose) > 2 else 0.0)
            led = _field(state, ("led", "led_color", "color"), (0, 0, 0))
            leds[i] = led[:3]
            failed[i] = _field(state, ("failure",)) is not None
            ids.append(int(_field(state, ("robot_id", "id"), i)))
        if leds.max() > 1.0:
            leds = leds / 255.0
        index_of = {robot_id: i for i, robot_id in enumerate(ids)}
        links = [
            (index_of.get(a, a), index_of.get(b, b))
            for a, b in (_field(self.sim, ("links",)) or [])
        ]
        link_array = np.array(links, dtype=np.int32).reshape(-1, 2)
        return SwarmFrame(self.step_count, positions, headings, leds, failed, link_array, ids)

    def geometry(self) -> WorldGeometry:
        world = _field(self.sim, ("world",), self.sim)
        bounds = _field(world, ("bounds",), (-0.5, -0.5, 0.5, 0.5))
        walls = _field(world, ("walls", "overlay_segments"), [])
        segments = np.array(walls, dtype=np.float64).reshape(-1, 2, 2)
        radius = float(_field(world, ("robot_radius",), KILOBOT_RADIUS))
        comm_range = float(_field(world, ("comm_range", "radio_range"), 0.1))
        height = float(_field(world, ("robot_height", "altitude"), 0.0))
        return WorldGeometry(radius, comm_range, tuple(bounds), segments, height)

    # ---- inspector ------------------------------------------------------------------------------
    def inspect(self, index: int) -> RobotInspection:
        robot = self.robot(index)
        vm = robot.vm
        profile = self.profile
        geometry = HeapGeometry(
            size=int(_field(profile, ("heap_size",))),
            object_size=int(_field(profile, ("obj_size", "object_size"))),
            reserved=int(_field(profile, ("rsv_actrec", "reserved_actrecs", "reserved"))),
            elems_per_segment=int(
                _field(profile, ("elems_per_segment", "elems_per_tseg"), DEFAULT_ELEMS_PER_SEGMENT)
            ),
        )
        heap_obj = _field(vm, ("heap",), vm)  # bbzide.vm.heap.Heap: data, rtobj, ltseg
        heap_bytes = bytes(_field(heap_obj, ("data",)))
        rop = int(_field(heap_obj, ("rtobj", "rightmost_object_ptr")))
        lsp = int(_field(heap_obj, ("ltseg", "leftmost_segment_ptr")))
        strings = list(getattr(self.program, "strings", []))
        reader = HeapReader(heap_bytes, geometry, rop, lsp, strings)
        decoded = reader.decode()
        failure = getattr(robot, "failure", None)
        error_text = None
        error_line = None
        if failure is not None:
            where = _field(failure, ("location",))
            error_text = (
                f"{_field(failure, ('reason',), 'error')}: {_field(failure, ('message',), '')}"
            )
            if where is not None:
                error_text += f" at {where}"
                error_line = _source_line(where)
        gsyms = int(_field(vm, ("gsyms",), geometry.reserved + 3))
        globals_ = reader.named_entries(gsyms)
        by_name = dict(globals_)
        table_index = reader.named_refs(gsyms)
        return RobotInspection(
            robot_index=index,
            robot_id=int(_field(robot, ("robot_id", "id"), index)),
            step=self.step_count,
            state=str(_field(vm, ("state",), "?")),
            pc=_field(vm, ("pc",)),
            heap_size=geometry.size,
            rop=rop,
            lsp=lsp,
            reserved_bytes=geometry.reserved * geometry.object_size,
            blocks=decoded.blocks,
            used_bytes=decoded.used_bytes,
            free_bytes=decoded.free_bytes,
            peak_bytes=_field(heap_obj, ("peak_used", "peak_bytes")),
            gc_runs=_field(heap_obj, ("gc_runs",)),
            ram_bytes=_field(profile, ("ram_size", "ram_bytes"))
            or PLATFORM_MEMORY.get(str(_field(profile, ("name",), "")), (None, None))[0],
            objects=decoded.objects,
            frames=[str(f) for f in (_field(vm, ("frames", "call_frames"), []) or [])],
            globals=globals_,
            stigmergy=_table_rows(reader, table_index.get("stigmergy")),
            neighbors=_table_rows(reader, table_index.get("neighbors")),
            swarms=[f"swarm = {by_name['swarm']}"] if "swarm" in by_name else [],
            in_queue=[_message_text(m) for m in (_field(vm, ("in_messages", "inmsgs"), []) or [])],
            out_queue=[
                _message_text(m) for m in (_field(vm, ("out_messages", "outmsgs"), []) or [])
            ],
            last_error=error_text,
            last_error_line=error_line,
            warnings=_runtime_warnings(vm, profile),
        )


#: Wire payload of one message on every BittyBuzz robot (notes §F.4: Kilobot `data[9]`).
DEFAULT_PAYLOAD_BYTES = 9


def _runtime_warnings(vm: Any, profile: Any) -> list[str]:
    """Pitfalls only a running VM can see: int16 wrap-around, messages filling the payload."""
    warnings = []
    overflows = _field(vm, ("int16_overflows", "overflow_count", "int_overflows"))
    if overflows:
        warnings.append(f"int16 overflow seen {overflows} time(s): values wrapped around")
    payload = int(_field(profile, ("message_payload", "payload_bytes"), DEFAULT_PAYLOAD_BYTES))
    for message in _field(vm, ("out_messages", "outmsgs"), []) or []:
        if isinstance(message, bytes | bytearray) and len(message) >= payload - 1:
            warnings.append(f"outgoing message of {len(message)} B is near the {payload} B payload")
            break
    return warnings


def _table_rows(reader: HeapReader, index: int | None) -> list[tuple[str, str]]:
    return [] if index is None else reader.named_entries(index)


def _message_text(message: Any) -> str:
    if isinstance(message, bytes | bytearray):
        return f"{len(message)} B: {bytes(message).hex(' ')}"
    return str(message)


def _source_line(location: Any) -> str | None:
    try:
        lines = Path(location.file).read_text(encoding="utf-8").splitlines()
    except (OSError, AttributeError):
        return None
    return lines[location.line - 1] if 1 <= location.line <= len(lines) else None
