"""UserError rendering: file:line:col, the source line and a caret under the column."""

from pathlib import Path

from bbzide.cli import main
from bbzide.diagnostics import CompileError, SourceLocation, UserError


def test_render_shows_location_source_line_and_caret(tmp_path: Path) -> None:
    script = tmp_path / "s.bzz"
    script.write_text("x = 1\nif x > 0 {\n", encoding="utf-8")
    error = CompileError("expected (, found identifier", SourceLocation(str(script), 2, 3))
    lines = error.render().splitlines()
    assert lines[0] == f"{script}:2:3: error: expected (, found identifier"
    assert lines[1] == "  if x > 0 {"
    assert lines[2] == "     ^"


def test_render_without_location_is_one_line() -> None:
    assert UserError("no such world 'moon'").render() == "error: no such world 'moon'"


def test_render_uses_given_source_line_over_the_file() -> None:
    error = CompileError("bad", SourceLocation("/nonexistent.bzz", 1, 2), source_line="ab\tc")
    assert error.render().splitlines()[1:] == ["  ab c", "    ^"]


def test_cli_turns_user_errors_into_exit_1_without_traceback(capsys, monkeypatch) -> None:
    import bbzide.cli as cli

    def failing(_args: object) -> int:
        raise UserError("something the user did")

    original = cli.build_parser

    def parser_with_failing_command():  # noqa: ANN202
        parser = original()
        for action in parser._subparsers._group_actions:  # noqa: SLF001
            action.add_parser("fail-for-test").set_defaults(handler=failing)
        return parser

    monkeypatch.setattr(cli, "build_parser", parser_with_failing_command)
    assert main(["fail-for-test"]) == 1
    captured = capsys.readouterr()
    assert captured.err.strip() == "error: something the user did"
    assert "Traceback" not in captured.err
