"""Compile-time benchmark: the largest corpus script and a generated 5,000-line script.

Prints front end (bzzparse equivalent), back end (assembler + bo2bbo) and total times, best of
5 runs. Target: well under 1 s for the 5,000-line script.

    PYTHONPATH=. python benchmarks/compile_bench.py
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

from corpus import BBZ_DIR, COMPILER_DIR  # noqa: E402

from bbzide.compiler import _program_from_basm  # noqa: E402
from bbzide.compiler.frontend import compile_to_basm  # noqa: E402

RUNS = 5


def generated_script(lines: int) -> str:
    """Functions, loops, tables and arithmetic, about `lines` lines."""
    out = ["var total = 0", "var t = {}"]
    index = 0
    while len(out) < lines:
        out += [
            f"function f{index}(a, b) {{",
            f"  var x = a * {index} + b / 2.5",
            "  if (x > 10) { x = x - 1 } else { x = x + 1 }",
            f"  t.k{index % 50} = x",
            "  return x",
            "}",
            f"var i{index} = 0",
            f"while (i{index} < 3) {{ total = total + f{index}(i{index}, 1.5)  "
            f"i{index} = i{index} + 1 }}",
        ]
        index += 1
    return "\n".join(out) + "\n"


def measure(path: Path) -> tuple[float, float, int, int]:
    best_front = best_back = float("inf")
    basm_lines = bbo_size = 0
    for _ in range(RUNS):
        start = time.perf_counter()
        result = compile_to_basm(path)
        middle = time.perf_counter()
        program = _program_from_basm(result.basm, path.stem + ".bo", [], os.path.realpath(path))
        bbo = program.to_bbo()
        end = time.perf_counter()
        best_front, best_back = min(best_front, middle - start), min(best_back, end - middle)
        basm_lines, bbo_size = result.basm.count("\n"), len(bbo.bbo)
    return best_front, best_back, basm_lines, bbo_size


def report(name: str, path: Path) -> None:
    front, back, basm_lines, bbo_size = measure(path)
    source_lines = path.read_text().count("\n")
    print(
        f"{name:28s} {source_lines:6d} src lines {basm_lines:7d} basm lines  "
        f"front {front * 1000:7.1f} ms"
        f"  back {back * 1000:7.1f} ms  total {(front + back) * 1000:7.1f} ms  .bbo {bbo_size} B"
    )


def main() -> None:
    scripts = sorted(
        [*COMPILER_DIR.glob("*.bzz"), *BBZ_DIR.glob("*.bzz")], key=lambda p: p.stat().st_size
    )
    largest = scripts[-1]
    os.chdir(largest.parent)
    report(f"largest corpus ({largest.name})", largest)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "generated.bzz"
        path.write_text(generated_script(5000))
        report("generated 5,000 lines", path)


if __name__ == "__main__":
    main()
