"""`nicer-stream run`'s own option checks: one-line errors before anything is read or written."""
from __future__ import annotations

import pytest
from typer.testing import CliRunner

from nicer_stream.cli.main import app

runner = CliRunner()


@pytest.mark.parametrize("flags", [["--max-renders", "-1"], ["--render-every", "0"]])
def test_bad_render_options_are_one_line_errors_and_write_nothing(replica_dir, tmp_path, flags):
    out = tmp_path / "out"
    res = runner.invoke(app, ["run", "--source", f"replica:{replica_dir}", "--out", str(out), *flags])
    assert res.exit_code == 2
    assert res.stderr.startswith("error: --render-every must be at least 1 and --max-renders at least 0")
    assert res.stderr.count("\n") == 1
    assert not out.exists()
