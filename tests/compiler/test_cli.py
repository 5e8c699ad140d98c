"""The compile / disasm / bo2bbo subcommands, in process and as `python -m bbzide`."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

from corpus import BBZ_DIR, COMPILER_DIR

from bbzide.cli import main

REPO = Path(__file__).resolve().parents[2]


def _copy(name: str, source_dir: Path, tmp_path: Path) -> Path:
    for path in source_dir.glob(name + ".*"):
        shutil.copy(path, tmp_path / path.name)
    return tmp_path / f"{name}.bzz"


def test_compile_for_kilobot_writes_reference_identical_files(
    tmp_path, monkeypatch, capsys
) -> None:
    script = _copy("arith16", BBZ_DIR, tmp_path)
    monkeypatch.chdir(tmp_path)
    status = main(
        [
            "compile",
            script.name,
            "--bst",
            "arith16.bst",
            "-o",
            "out.bo",
            "--bbo",
            "out.bbo",
            "--basm",
            "out.basm",
            "--platform",
            "kilobot",
        ]
    )
    assert status == 0
    assert (tmp_path / "out.bo").read_bytes() == (BBZ_DIR / "arith16.bo").read_bytes()
    assert (tmp_path / "out.bbo").read_bytes() == (BBZ_DIR / "arith16.bbo").read_bytes()
    assert (tmp_path / "out.bdb").exists() and (tmp_path / "out.basm").exists()
    out, err = capsys.readouterr()
    assert ".bbo size          501 bytes" in out and "kilobot" in out
    assert "out of 16 bit integer range" in err


def test_platform_without_bst_uses_base_strings_and_hosts(tmp_path, monkeypatch) -> None:
    script = _copy("arith16", BBZ_DIR, tmp_path)
    monkeypatch.chdir(tmp_path)
    # arith16.bst = the 46 base strings + "log" (README §1): --host log reproduces it.
    assert (
        main(["compile", script.name, "--platform", "pc", "--host", "log", "--bbo", "x.bbo"]) == 0
    )
    assert (tmp_path / "x.bbo").read_bytes() == (BBZ_DIR / "arith16.bbo").read_bytes()


def test_disasm_and_bo2bbo(tmp_path, capsys) -> None:
    _copy("arith16", BBZ_DIR, tmp_path)
    assert main(["bo2bbo", str(tmp_path / "arith16.bo"), "-o", str(tmp_path / "y.bbo")]) == 0
    assert (tmp_path / "y.bbo").read_bytes() == (BBZ_DIR / "arith16.bbo").read_bytes()
    capsys.readouterr()
    assert main(["disasm", str(tmp_path / "arith16.bbo")]) == 0
    out = capsys.readouterr().out
    assert "     2: pushs    4  ; 'init'" in out
    assert main(["disasm", str(COMPILER_DIR / "algorithms.bo")]) == 0
    assert "pushs" in capsys.readouterr().out


def test_errors_exit_1_with_one_message(tmp_path, capsys) -> None:
    bad = tmp_path / "bad.bo"
    bad.write_bytes(b"\x05\x00ab")
    assert main(["disasm", str(bad)]) == 1
    assert main(["bo2bbo", str(bad)]) == 1
    assert main(["compile", str(tmp_path / "missing.bzz")]) == 1
    syntax = tmp_path / "s.bzz"
    syntax.write_text("x = (1 +\n")
    assert main(["compile", str(syntax)]) == 1
    err = capsys.readouterr().err
    assert "bad.bo: offset 2" in err and "Traceback" not in err


def test_subprocess_exit_codes_and_no_traceback(tmp_path) -> None:
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    bad = tmp_path / "bad.bbo"
    bad.write_bytes(b"\x00\x00" + bytes([44, 0x40, 0]))
    failed = subprocess.run(
        [sys.executable, "-m", "bbzide", "disasm", str(bad)],
        capture_output=True,
        text=True,
        env=env,
        cwd=tmp_path,
    )
    assert failed.returncode == 1 and "Traceback" not in failed.stderr
    assert "bad.bbo: offset 2" in failed.stderr
    script = _copy("arith16", BBZ_DIR, tmp_path)
    ok = subprocess.run(
        [sys.executable, "-m", "bbzide", "compile", script.name, "--platform", "kilobot"],
        capture_output=True,
        text=True,
        env=env,
        cwd=tmp_path,
    )
    assert ok.returncode == 0, ok.stderr
    assert "instructions" in ok.stdout and "Traceback" not in ok.stderr


def test_disasm_of_a_lone_bbo_names_the_base_strings(tmp_path, capsys) -> None:
    lone = tmp_path / "lone.bbo"
    lone.write_bytes((BBZ_DIR / "arith16.bbo").read_bytes())
    assert main(["disasm", str(lone)]) == 0
    out = capsys.readouterr().out
    assert "pushs    4  ; 'init'" in out and "pushs    47\n" in out


def test_compile_searches_buzz_include_path(tmp_path, monkeypatch):
    library = tmp_path / "lib"
    library.mkdir()
    (library / "helpers.bzz").write_text("function twice(x) { return 2 * x }\n")
    script = tmp_path / "main.bzz"
    script.write_text('include "helpers.bzz"\ny = twice(4)\n')
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("BUZZ_INCLUDE_PATH", str(library))
    assert main(["compile", str(script), "--platform", "pc"]) == 0
    assert b"twice" in (tmp_path / "main.bo").read_bytes()
    monkeypatch.setenv("BUZZ_INCLUDE_PATH", "")
    assert main(["compile", str(script), "--platform", "pc"]) == 1


SCRIPT = "function init() {\n  x = 1\n}\n"


def _script(tmp_path: Path, name: str = "mine.bzz") -> Path:
    script = tmp_path / name
    script.write_text(SCRIPT)
    return script


def test_an_output_onto_the_script_itself_is_refused_and_the_script_kept(tmp_path, capsys):
    script = _script(tmp_path)
    for option in ("-o", "--bbo", "--basm", "--bdb"):
        for force in ([], ["--force"]):
            assert main(["compile", str(script), option, str(script), *force]) == 1
            err = capsys.readouterr().err
            assert "is the input" in err and "Traceback" not in err
            assert script.read_text() == SCRIPT


def test_an_output_onto_another_buzz_source_needs_force(tmp_path, capsys):
    script = _script(tmp_path)
    other = _script(tmp_path, "other.bzz")
    assert main(["compile", str(script), "--basm", str(other)]) == 1
    assert "--force" in capsys.readouterr().err
    assert other.read_text() == SCRIPT
    assert main(["compile", str(script), "--basm", str(other), "--force"]) == 0
    assert other.read_text().startswith("!")     # the .basm's string section


def test_two_outputs_on_one_path_are_refused(tmp_path, capsys):
    script = _script(tmp_path)
    assert main(["compile", str(script), "-o", str(tmp_path / "x.bin"),
                 "--bbo", str(tmp_path / "x.bin")]) == 1
    assert "both name" in capsys.readouterr().err
    assert not (tmp_path / "x.bin").exists()


def test_bo2bbo_onto_its_own_bo_is_refused(tmp_path, capsys):
    script = _script(tmp_path)
    assert main(["compile", str(script)]) == 0
    bo = script.with_suffix(".bo")
    before = bo.read_bytes()
    assert main(["bo2bbo", str(bo), "-o", str(bo)]) == 1
    assert "is the input" in capsys.readouterr().err
    assert bo.read_bytes() == before


def test_compiling_a_folder_says_it_is_a_folder(tmp_path, capsys):
    folder = tmp_path / "lesson.bzz"
    folder.mkdir()
    assert main(["compile", str(folder)]) == 1
    assert "is a folder" in capsys.readouterr().err
