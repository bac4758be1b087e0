"""The options `run`, `map` and `batch` share: checked before anything is read or written (one line
naming the flag and its range, exit 2), each with help text, and the same set on each command."""
from __future__ import annotations

from pathlib import Path

import pytest
import typer
from typer.testing import CliRunner

from nicer_stream.cli.main import app

runner = CliRunner()
SRC = "synthetic:room?frames=2"


def _args(command: str, out: Path) -> list[str]:
    if command == "batch":
        return ["batch", SRC, "--out", str(out), "--local"]
    extra = ["--poses", "gt"] if command == "map" else []
    return [command, "--source", SRC, "--out", str(out), *extra]


@pytest.mark.parametrize("command", ["run", "map", "batch"])
@pytest.mark.parametrize("flag, value, says", [
    ("--intrinsics", "0,0,0,0", "error: --intrinsics must be fx,fy,cx,cy with fx, fy > 0"),
    ("--max-side", "0", "error: --max-side must be an integer >= 32 (pixels), got 0"),
    ("--render-every", "0", "error: --render-every must be"),
    ("--device", "gpu0", "error: --device must be a torch device"),
])
def test_a_bad_value_is_one_line_naming_its_flag_and_nothing_is_written(tmp_path, command, flag, value, says):
    if command == "batch" and flag == "--device":
        pytest.skip("batch takes its device from --gpus-per-run")
    out = tmp_path / "out"
    res = runner.invoke(app, [*_args(command, out), flag, value])
    assert res.exit_code == 2, res.output
    assert res.stderr.startswith(says) and res.stderr.count("\n") == 1, res.stderr
    assert not out.exists()


@pytest.mark.parametrize("command", ["run", "map", "batch"])
def test_every_option_has_help_text(command):
    cmd = typer.main.get_command(app).commands[command]
    missing = [p.name for p in cmd.params if not getattr(p, "help", None)]
    assert not missing, f"{command}: options without help: {missing}"


def test_batch_has_the_run_options_it_shares():
    cli = typer.main.get_command(app)
    opts = {c: {o for p in cli.commands[c].params for o in p.opts} for c in ("run", "batch")}
    shared = {"--start", "--stride", "--drop", "--max-frames", "--max-side", "--intrinsics", "--sink", "--render-every",
              "--preset", "--config", "--priors", "--flow"}
    assert shared <= opts["run"] and shared <= opts["batch"], shared - opts["batch"]


def test_run_needs_a_source(tmp_path):
    res = runner.invoke(app, ["run", "--out", str(tmp_path / "out")])
    assert res.exit_code == 2 and "--source" in res.output
    assert not (tmp_path / "out").exists()


def test_map_needs_poses_given_by_name(tmp_path):
    res = runner.invoke(app, ["map", "--source", SRC, "--out", str(tmp_path / "out")])
    assert res.exit_code == 2 and "--poses" in res.output
    assert not (tmp_path / "out").exists()


def test_maps_auto_priors_never_resolve_to_stereo(monkeypatch):
    from nicer_stream.priors import auto
    from nicer_stream.runtime.frame_priors import make_engine

    monkeypatch.setattr(auto, "learned_weights", lambda: (None, "no learned weights here"))
    assert make_engine("auto", None, "cpu", auto_fallback="none").depth_normal.name == "none"
    assert make_engine("auto", None, "cpu").depth_normal.name == "stereo"  # run's auto


def test_batch_sinks_write_into_each_sources_directory(tmp_path):
    from nicer_stream.runtime.batch_plan import per_source_sinks

    out = tmp_path / "root" / "room"
    specs = per_source_sinks(("mcap:rec.mcap?images_every=5,rerun:/x/r.rrd", "rerun+grpc://host:9876/proxy"), out)
    assert specs == (f"mcap:{out / 'rec.mcap'}?images_every=5,rerun:{out / 'r.rrd'}", "rerun+grpc://host:9876/proxy")
