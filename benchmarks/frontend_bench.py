"""Front-end speed: a ~5,000-line script through `compile_to_basm` (budget: 0.3 s of the 1 s
compile budget). Built by repeating the corpus scripts' bodies inside functions, so every
construct is represented. Run: PYTHONPATH=. /work/venv/bin/python benchmarks/frontend_bench.py
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from corpus import BBZ_DIR  # noqa: E402

from bbzide.compiler.frontend import compile_to_basm  # noqa: E402

BUDGET_SECONDS = 0.3


def big_script(min_lines: int = 5000) -> str:
    bodies = [p.read_text() for p in sorted(BBZ_DIR.glob("*.bzz"))]
    parts: list[str] = []
    lines = 0
    copy = 0
    while lines < min_lines:
        for body in bodies:
            # rename functions so each copy defines new ones (still valid Buzz)
            text = body.replace("function init", f"function init{copy}")
            text = text.replace("function step", f"function step{copy}")
            parts.append(text)
            lines += text.count("\n")
            copy += 1
    return "\n".join(parts)


def main() -> None:
    source = big_script()
    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, "big.bzz")
        Path(path).write_text(source)
        compile_to_basm(path)  # warm-up
        runs = []
        for _ in range(5):
            start = time.perf_counter()
            result = compile_to_basm(path)
            runs.append(time.perf_counter() - start)
    best = min(runs)
    print(f"front end: {source.count(chr(10))} lines, {len(result.basm.splitlines())} .basm lines, "
          f"best {best * 1000:.1f} ms, median {sorted(runs)[2] * 1000:.1f} ms "
          f"(budget {BUDGET_SECONDS * 1000:.0f} ms, ratio {best / BUDGET_SECONDS:.2f})")


if __name__ == "__main__":
    main()
