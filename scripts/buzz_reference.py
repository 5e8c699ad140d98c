"""Write docs/buzz-reference.md from the reference tables (bbzide/compiler/reference.py, the
language and its built-ins; bbzide/worlds/reference.py, each world's host functions).

    .venv/bin/python scripts/buzz_reference.py           write the page
    .venv/bin/python scripts/buzz_reference.py --check   exit 1 if the page is out of date

The page is generated so that it never disagrees with the editor's completion and hover, which
read the same tables; tests/worlds/test_reference.py fails while the page is out of date.
"""

from __future__ import annotations

import sys
from pathlib import Path

from bbzide.worlds.reference import reference_markdown

PAGE = Path(__file__).resolve().parents[1] / "docs" / "buzz-reference.md"


def main(argv: list[str]) -> int:
    text = reference_markdown()
    if "--check" in argv:
        current = PAGE.read_text(encoding="utf-8") if PAGE.exists() else ""
        if current != text:
            print(f"{PAGE} is out of date: run scripts/buzz_reference.py", file=sys.stderr)
            return 1
        return 0
    PAGE.write_text(text, encoding="utf-8")
    print(f"wrote {PAGE} ({len(text.splitlines())} lines)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
