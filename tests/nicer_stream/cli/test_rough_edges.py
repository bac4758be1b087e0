"""Errors a new user meets: one line and exit code 2, naming flags that exist."""
from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest
import typer
from typer.testing import CliRunner

from nicer_stream.cli.common import user_errors
from nicer_stream.cli.main import app

runner = CliRunner()
PKG = Path(__file__).resolve().parents[3] / "nicer_stream"


def test_out_pointing_at_a_file_is_one_line(tmp_path):
    out = tmp_path / "taken"
    out.write_text("not a folder")
    res = runner.invoke(app, ["run", "--source", "synthetic:room?frames=2", "--out", str(out), "--sync"])
    assert res.exit_code == 2, res.output
    assert res.stderr == f"error: File exists: {out}\n"


@pytest.mark.parametrize("err", [PermissionError(13, "Permission denied", "/runs/x"),
                                 OSError(28, "No space left on device", "/runs/x/mesh.ply"),
                                 NotADirectoryError(20, "Not a directory", "/runs/file/x")])
def test_any_os_error_a_user_causes_is_one_line(err, capsys):
    def fails():
        raise err

    with pytest.raises(typer.Exit) as e:
        user_errors(fails)()
    assert e.value.exit_code == 2
    assert capsys.readouterr().err == f"error: {err.strerror}: {err.filename}\n"


def _messages(path: Path) -> list[str]:
    """The string literals (f-string parts included) of a module, docstrings left out."""
    tree = ast.parse(path.read_text())
    docs = {id(n.value) for n in ast.walk(tree) if isinstance(n, ast.Expr)}
    return [n.value for n in ast.walk(tree) if isinstance(n, ast.Constant) and isinstance(n.value, str) and id(n) not in docs]


def test_messages_name_only_flags_the_command_line_has():
    cli = typer.main.get_command(app)
    flags = {o for cmd in cli.commands.values() for p in cmd.params for o in p.opts}
    flags |= {o for p in cli.params for o in p.opts}
    files = [*PKG.joinpath("priors").glob("*.py"), *PKG.joinpath("cli").glob("*.py"), *PKG.joinpath("runtime").glob("*.py")]
    named = {(f.name, flag) for f in files for m in _messages(f) for flag in re.findall(r"(?<![\w-])--[a-z][a-z-]*", m)}
    assert named, "no flag found in any message: the check reads nothing"
    unknown = sorted((f, flag) for f, flag in named if flag not in flags)
    assert not unknown, f"messages name flags that do not exist: {unknown}"


def test_prior_hints_name_no_flag_of_another_command():
    from nicer_stream.priors import cache, oracle

    assert "--provider" not in oracle._NEEDS_GT  # run and map take --priors; the hint names no flag
    assert "--scale" not in Path(cache.__file__).read_text()  # no command that reads a cache has --scale
