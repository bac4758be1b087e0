"""The global `--log-level` option: this project's loggers follow it, others stay at WARNING."""
from __future__ import annotations

import logging

from typer.testing import CliRunner

from nicer_stream.cli.main import app

runner = CliRunner()


def test_log_level_sets_the_project_loggers_only(replica_dir):
    res = runner.invoke(app, ["--log-level", "debug", "inspect", f"replica:{replica_dir}"])
    assert res.exit_code == 0, res.output
    assert logging.getLogger("nicer_stream").level == logging.DEBUG
    assert logging.getLogger("sources").level == logging.DEBUG
    assert logging.getLogger().level >= logging.WARNING
    res = runner.invoke(app, ["--log-level", "info", "inspect", f"replica:{replica_dir}"])
    assert logging.getLogger("sinks").level == logging.INFO


def test_an_unknown_log_level_is_a_one_line_usage_error(replica_dir):
    res = runner.invoke(app, ["--log-level", "loud", "inspect", f"replica:{replica_dir}"])
    assert res.exit_code == 2
    assert res.stderr == "error: --log-level 'loud' is not one of debug, info, warning, error\n"
