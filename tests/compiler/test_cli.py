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


def test_run_searches_buzz_include_path_too(tmp_path, monkeypatch, capsys):
    """`run` (one robot, and a swarm in a world) finds includes where `compile` does."""
    library = tmp_path / "lib"
    library.mkdir()
    (library / "helpers.bzz").write_text("function twice(x) { return 2 * x }\n")
    script = tmp_path / "main.bzz"
    script.write_text('include "helpers.bzz"\nfunction init() {\n  log(twice(21))\n}\n'
                      "function step() {}\n")
    monkeypatch.chdir(tmp_path)
    one_robot = ["run", str(script), "--steps", "1"]
    in_a_world = ["run", str(script), "--world", "kilobot", "--robots", "1", "--steps", "1"]
    for command in (one_robot, in_a_world):
        monkeypatch.setenv("BUZZ_INCLUDE_PATH", "")
        assert main(command) == 1
        assert "Can't read 'helpers.bzz'" in capsys.readouterr().err
        monkeypatch.setenv("BUZZ_INCLUDE_PATH", str(library))
        assert main(command) == 0, capsys.readouterr().err
    capsys.readouterr()
    assert main(one_robot) == 0
    assert capsys.readouterr().out.splitlines()[0] == "42"


def test_bst_with_host_or_a_non_bittybuzz_bst_with_platform_is_refused(tmp_path, capsys):
    script = _copy("arith16", BBZ_DIR, tmp_path)
    bst = str(tmp_path / "arith16.bst")
    assert main(["compile", str(script), "--bst", bst, "--host", "led"]) == 1
    err = capsys.readouterr().err
    assert "--bst gives the whole string table, host names included: --host" in err
    plain = tmp_path / "plain.bst"
    plain.write_text("log\ninit\n")
    assert main(["compile", str(script), "--bst", str(plain), "--platform", "kilobot"]) == 1
    err = capsys.readouterr().err
    assert f"--bst {plain} with --platform kilobot: it is not BittyBuzz's string table" in err
    assert "Traceback" not in err
    assert main(["compile", str(script), "--bst", str(plain), "-o", str(tmp_path / "p.bo")]) == 0


def _compile_error(tmp_path: Path, source: bytes, capsys) -> str:
    script = tmp_path / "bad.bzz"
    script.write_bytes(source)
    assert main(["compile", str(script)]) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err and ".bo" not in err  # about the script, not a file we made
    return err


def test_a_string_the_bytecode_cannot_store_is_an_error_at_the_string(tmp_path, capsys):
    for source in (b'var s = "a\\nb"\nlog(s)\n', b'var s = "a\nb"\nlog(s)\n'):
        err = _compile_error(tmp_path, source, capsys)
        assert "bad.bzz:1:8: error: Syntax error: a string cannot hold a line break" in err
    err = _compile_error(tmp_path, b'var s = "a\0b"\nlog(s)\n', capsys)
    assert "bad.bzz:1:8: error: Syntax error: a string cannot hold a NUL byte" in err
    assert "\0" not in err  # the line with the raw NUL is not echoed to the terminal
    # the same script as `run` compiles it
    script = tmp_path / "bad.bzz"
    script.write_bytes(b'var s = "a\\nb"\nlog(s)\n')
    assert main(["run", str(script)]) == 1
    assert "bad.bzz:1:8: error: Syntax error: a string cannot hold a line break" in (
        capsys.readouterr().err)


def test_a_binary_file_is_named_as_one_and_its_bytes_are_not_printed(tmp_path, capsys):
    binary = bytes(range(256)) * 4  # control bytes, NUL and bytes that are not UTF-8
    for data in (binary, b"\x9f\xff" + binary):
        err = _compile_error(tmp_path, data, capsys)
        assert "unknown character" in err and "the file is not text: is it a Buzz script?" in err
        assert len(err.splitlines()) == 1
        assert all(ch.isprintable() for ch in err.rstrip("\n"))
