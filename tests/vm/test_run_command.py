"""``bbzide run X.bzz|X.bbo`` (one robot, headless): the log, ``--dump`` equal to the
reference for a corpus command compiled from source, VM errors at source positions."""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))

from corpus import BBZ_DIR  # noqa: E402
from test_conformance import _bbzconf, _compare  # noqa: E402

from bbzide.cli import main  # noqa: E402


def test_run_prints_what_the_script_logs(tmp_path: Path, capsys) -> None:  # noqa: ANN001
    script = tmp_path / "count.bzz"
    script.write_text("n = 0\nfunction step() {\n  n = n + 2\n  log(\"n\", n)\n}\n")
    assert main(["run", str(script), "--platform", "kilobot", "--steps", "3"]) == 0
    assert capsys.readouterr().out.splitlines() == ['"n" 2', '"n" 4', '"n" 6']


def test_run_dump_of_a_compiled_corpus_script_equals_the_reference(
        tmp_path: Path, monkeypatch, capsys) -> None:  # noqa: ANN001
    """gradient.bzz compiled from source with the harness's --reg names (the corpus .bst)."""
    for name in ("gradient.bzz", "gradient.inj"):
        shutil.copy(Path(BBZ_DIR) / name, tmp_path / name)
    monkeypatch.chdir(tmp_path)
    status = main(["run", "gradient.bzz", "--platform", "kilobot", "--robot", "3",
                   "--steps", "30", "--reg", "log=print", "--reg", "led=ret0/1",
                   "--reg", "math.min=min", "--inject", "gradient.inj", "--dump"])
    assert status == 0
    mine = tmp_path / "mine.dump"
    mine.write_text(capsys.readouterr().out)
    differences, report = _compare(_bbzconf(), Path(BBZ_DIR) / "gradient.r3.avr.dump", mine,
                                   semantic=False)
    assert differences == 0, report


def test_run_error_names_the_source_position(tmp_path: Path, capsys) -> None:  # noqa: ANN001
    script = tmp_path / "bad.bzz"
    script.write_text("function step() {\n  s = swarm.create(9) x = 1\n}\n")
    assert main(["run", str(script), "--platform", "pc", "--steps", "2"]) == 1
    err = capsys.readouterr().err
    assert "bad.bzz:2:" in err and "SWARM" in err


def test_calling_an_unregistered_host_function_gets_a_hint(tmp_path: Path, capsys) -> None:  # noqa: ANN001
    """A world's host function (led) is nil in a one-robot run that does not register it: the
    error is at the call itself (not at the next token, where bzzparse's debug info puts it),
    says so in plain words and names what to do."""
    script = tmp_path / "blink.bzz"
    script.write_text("function step() {\n  log(1)\n    led(3)\n}\n")
    assert main(["run", str(script), "--platform", "pc", "--steps", "1"]) == 1
    err = capsys.readouterr().err.splitlines()
    assert err[0].startswith(f"{script}:3:4: warning: `led` is never defined")  # the lint
    assert err[1].startswith("robot 0: 1 step(s) on the pc profile; heap peak ")
    err = err[2:]
    assert err[0].startswith(f"{script}:3:4: error: robot 0 stopped: TYPE")
    assert "`led` is nil here: it is not defined, and no host function of this run " \
           "(--reg log) has that name" in err[0]
    assert err[1:3] == ["      led(3)", "      ^"]
    assert err[-1].startswith("  hint: a host function such as led() exists only where it is "
                              "registered") and "--world" in err[-1]


def test_an_undefined_function_is_named_at_its_call(tmp_path: Path, capsys) -> None:  # noqa: ANN001
    """The student's mistake: `nosuchfunction(x)` on line 3 is reported on line 3, column 2,
    by name, with the closest known name when there is one."""
    script = tmp_path / "typo.bzz"
    script.write_text("function step() {\n  var x = 1\n  lgo(x)\n}\n")
    assert main(["run", str(script), "--platform", "pc", "--steps", "1"]) == 1
    first = capsys.readouterr().err.splitlines()[2]
    assert first.startswith(f"{script}:3:2: error:")
    assert first.endswith("`lgo` is nil here: it is not defined, and no host function of this "
                          "run (--reg log) has that name; did you mean `log`?")


def test_a_global_defined_as_a_number_is_not_called_nil(tmp_path: Path, capsys) -> None:  # noqa: ANN001
    script = tmp_path / "number.bzz"
    script.write_text("speed = 3\nfunction step() {\n  t = {}\n  speed(t.x)\n}\n")
    assert main(["run", str(script), "--platform", "pc", "--steps", "1"]) == 1
    first = capsys.readouterr().err.splitlines()[1]
    assert first.startswith(f"{script}:4:2: error:")
    assert "`speed` is not a function when this call runs" in first


def test_a_type_error_that_is_not_a_call_has_no_call_hint(tmp_path: Path, capsys) -> None:  # noqa: ANN001
    script = tmp_path / "add.bzz"
    script.write_text("function step() {\n  x = 1\n  x.y = 2\n}\n")
    assert main(["run", str(script), "--platform", "kilobot", "--steps", "1"]) == 1
    err = capsys.readouterr().err
    assert "TYPE" in err and "hint" not in err


def test_run_missing_file_is_a_user_error(tmp_path: Path, capsys) -> None:  # noqa: ANN001
    assert main(["run", str(tmp_path / "nope.bzz")]) == 1
    assert "no such file" in capsys.readouterr().err


def test_run_stops_an_infinite_loop(tmp_path: Path, capsys) -> None:  # noqa: ANN001
    script = tmp_path / "spin.bzz"
    script.write_text("function step() {\n  while(1) { x = 1 }\n}\n")
    assert main(["run", str(script), "--steps", "1", "--budget", "3000"]) == 1
    assert "BUDGET" in capsys.readouterr().err


def test_run_refuses_bad_numbers_and_a_missing_injection_file(tmp_path: Path, capsys) -> None:  # noqa: ANN001
    script = tmp_path / "ok.bzz"
    script.write_text("function step() {\n  x = 1\n}\n")
    for extra, expected in ((["--budget", "-1"], "--budget must be"),
                            (["--robot", "70000"], "--robot must be a robot id in 0..65535"),
                            (["--robot", "-1"], "--robot must be"),
                            (["--inject", str(tmp_path / "missing.txt")], "no such file"),
                            (["--inject", str(tmp_path)], "is a folder")):
        assert main(["run", str(script), "--steps", "1", *extra]) == 1, extra
        err = capsys.readouterr().err
        assert expected in err and "Traceback" not in err and "internal error" not in err


def test_run_refuses_a_bbo_compiled_without_the_bittybuzz_strings(tmp_path: Path, capsys) -> None:  # noqa: ANN001
    """Its swarm calls would go nowhere (built-ins use the base strings' fixed ids)."""
    script = tmp_path / "g.bzz"
    script.write_text("function step() {\n  neighbors.broadcast(\"g\", 1)\n}\n")
    assert main(["compile", str(script), "--bbo", str(tmp_path / "g.bbo")]) == 0
    assert main(["run", str(tmp_path / "g.bbo"), "--steps", "1"]) == 1
    assert "compiled without BittyBuzz's string table" in capsys.readouterr().err
    assert main(["compile", str(script), "--bbo", str(tmp_path / "k.bbo"), "--platform",
                 "kilobot", "-o", str(tmp_path / "k.bo")]) == 0
    assert main(["run", str(tmp_path / "k.bbo"), "--steps", "1"]) == 0


def test_a_kilobot_example_runs_alone_with_the_firmware_functions(capsys) -> None:  # noqa: ANN001
    """`bbzide run examples/kilobot/gradient.bzz --platform kilobot` (the README's command):
    the firmware's `led` is registered and traced, the heap peak is reported."""
    example = Path(__file__).parents[2] / "examples" / "kilobot" / "gradient.bzz"
    assert main(["run", str(example), "--platform", "kilobot", "--steps", "5"]) == 0
    captured = capsys.readouterr()
    assert captured.out.splitlines() == ["led(1)"] * 5        # robot 0 is the seed: gradient 0
    assert "warning" not in captured.err
    assert captured.err.startswith("robot 0: 5 step(s) on the kilobot profile; heap peak ")
    assert " of 1088 B (" in captured.err


def test_a_heap_near_its_limit_is_warned(tmp_path: Path, capsys) -> None:  # noqa: ANN001
    script = tmp_path / "big.bzz"
    script.write_text("t = {}\nfunction step() {\n  t[size(t)] = size(t)\n}\n")
    main(["run", str(script), "--platform", "kilobot", "--steps", "60"])
    err = capsys.readouterr().err
    assert "warning: the heap peaked at" in err and "of the kilobot heap" in err
