"""`nicer-stream convert` and `nicer-stream inspect` through the CLI (typer's CliRunner)."""
from __future__ import annotations

import importlib.util
import json
from collections import defaultdict

import numpy as np
import pytest
import torch
import trimesh
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory
from typer.testing import CliRunner

from nicer_stream.cli.main import app
from nicer_stream.geometry.se3 import quat_to_matrix, se3_exp
from nicer_stream.io.trajectory import write_tum
from nicer_stream.types import Intrinsics

runner = CliRunner()
TIMES = np.array([10.0, 10.5, 11.25])


def _poses() -> np.ndarray:
    g = torch.Generator().manual_seed(7)
    return se3_exp(torch.randn(3, 6, generator=g, dtype=torch.float64)).numpy()


@pytest.fixture
def outdir(tmp_path):
    """A hand-made output directory: 3-pose trajectory.tum and a box mesh.ply."""
    d = tmp_path / "out"
    d.mkdir()
    write_tum(d / "trajectory.tum", TIMES, _poses())
    trimesh.creation.box(extents=(1.0, 2.0, 3.0)).export(d / "mesh.ply")
    return d


def _read(path) -> dict[str, list]:
    out = defaultdict(list)
    with open(path, "rb") as f:
        for _, ch, msg, dec in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages():
            out[ch.topic].append((msg.log_time, dec))
    return out


def _pose(p) -> np.ndarray:
    T = np.eye(4)
    q = torch.tensor([p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w], dtype=torch.float64)
    T[:3, :3] = quat_to_matrix(q).numpy()
    T[:3, 3] = [p.position.x, p.position.y, p.position.z]
    return T


def test_convert_to_mcap(outdir):
    res = runner.invoke(app, ["convert", str(outdir), "--to", "mcap", "--out", str(outdir / "x.mcap")])
    assert res.exit_code == 0, res.output
    msgs = _read(outdir / "x.mcap")
    assert [t for t, _ in msgs["/camera/pose"]] == [int(t * 1e9) for t in TIMES]
    for (_, m), T in zip(msgs["/camera/pose"], _poses()):
        np.testing.assert_allclose(_pose(m.pose), T, atol=1e-7)  # TUM file keeps 9 decimals
    assert len(msgs["/trajectory"]) == 1 and len(msgs["/trajectory"][0][1].poses) == 3
    tri = msgs["/mesh"][0][1].entities[0].triangles[0]
    assert (len(tri.points), len(tri.indices)) == (8, 36)
    extent = np.ptp([[p.x, p.y, p.z] for p in tri.points], axis=0)
    np.testing.assert_allclose(extent, [1.0, 2.0, 3.0])
    assert "/camera/image" not in msgs  # no renders: poses only


def test_convert_with_render_and_intrinsics(outdir):
    intr = Intrinsics(30.0, 31.0, 15.5, 11.5, 32, 24)
    (outdir / "summary.json").write_text(json.dumps({"intrinsics": {
        "fx": intr.fx, "fy": intr.fy, "cx": intr.cx, "cy": intr.cy, "width": intr.width, "height": intr.height}}))
    (outdir / "renders").mkdir()
    rgb = np.full((12, 16, 3), 0.5, np.float32)  # rendered at half resolution
    np.savez(outdir / "renders" / "frame_000001.npz", rgb=rgb, depth=np.full((12, 16), 2.0, np.float32))
    res = runner.invoke(app, ["convert", str(outdir)])
    assert res.exit_code == 0, res.output
    msgs = _read(outdir / "recording.mcap")
    assert [t for t, _ in msgs["/camera/image"]] == [int(TIMES[1] * 1e9)]
    cal = msgs["/camera/calibration"][0][1]
    assert (cal.width, cal.height) == (16, 12)
    np.testing.assert_allclose(np.reshape(cal.K, (3, 3)), intr.resized(16, 12).matrix())
    assert len(msgs["/camera/pose"]) == 3
    # A second convert refuses to overwrite without --force.
    again = runner.invoke(app, ["convert", str(outdir)])
    assert again.exit_code == 2 and "--force" in again.stderr and again.stderr.count("\n") == 1


def test_convert_matches_renders_to_poses_by_timestamp(outdir):
    """After `--stride 2` frame 4 is trajectory line 2: its render goes with TIMES[2], not line 4."""
    intr = Intrinsics(30.0, 31.0, 15.5, 11.5, 32, 24)
    (outdir / "summary.json").write_text(json.dumps({"intrinsics": {
        "fx": intr.fx, "fy": intr.fy, "cx": intr.cx, "cy": intr.cy, "width": intr.width, "height": intr.height}}))
    (outdir / "renders").mkdir()
    rgb = np.full((24, 32, 3), 0.5, np.float32)
    for index, t in ((2, TIMES[1]), (4, TIMES[2])):
        np.savez(outdir / "renders" / f"frame_{index:06d}.npz", rgb=rgb, frame_index=np.int64(index),
                 timestamp=np.float64(t))
    res = runner.invoke(app, ["convert", str(outdir)])
    assert res.exit_code == 0, res.output
    msgs = _read(outdir / "recording.mcap")
    assert [t for t, _ in msgs["/camera/image"]] == [int(TIMES[1] * 1e9), int(TIMES[2] * 1e9)]


def test_convert_to_rrd_then_inspect(outdir):
    rrd = outdir / "x.rrd"
    assert runner.invoke(app, ["convert", str(outdir), "--to", "rrd", "--out", str(rrd)]).exit_code == 0
    res = runner.invoke(app, ["inspect", str(rrd)])
    assert res.exit_code == 0, res.output
    lines = {ln.split()[0]: ln for ln in res.stdout.splitlines() if ln.startswith("  /")}
    assert "rows=3" in lines["/world/camera"] and "Transform3D" in lines["/world/camera"]
    assert "Mesh3D" in lines["/world/mesh"] and "/world/trajectory/estimate" in lines


def test_inspect_mcap(outdir):
    runner.invoke(app, ["convert", str(outdir)])
    res = runner.invoke(app, ["inspect", str(outdir / "recording.mcap")])
    assert res.exit_code == 0, res.output
    rows = {ln.split()[0]: ln.split() for ln in res.stdout.splitlines() if ln.startswith("  /")}
    assert rows["/camera/pose"][1] == "3" and rows["/camera/pose"][3] == "foxglove.PoseInFrame"
    assert rows["/mesh"][1] == "1" and rows["/tf"][1] == "3"
    assert "time range: 10.000000000 .. 11.250000000 s" in res.stdout


def test_inspect_errors_are_one_line(tmp_path, outdir):
    bad = tmp_path / "garbage.rrd"
    bad.write_bytes(b"not a recording")
    notmcap = tmp_path / "x.mcap"
    notmcap.write_text("hello")
    for target in [str(tmp_path / "missing.mcap"), str(tmp_path / "missing.rrd"), str(bad), str(notmcap),
                   "nosuchscheme:abc", str(outdir / "trajectory.tum")]:
        res = runner.invoke(app, ["inspect", target])
        assert res.exit_code == 2, (target, res.output)
        assert res.stderr.startswith("error: ") and res.stderr.count("\n") == 1, res.stderr


def test_convert_errors_are_one_line(tmp_path, outdir):
    for args in [["convert", str(tmp_path / "nowhere")], ["convert", str(tmp_path)],
                 ["convert", str(outdir), "--to", "ply"], ["convert", str(outdir), "--out", str(tmp_path / "a.rrd")]]:
        res = runner.invoke(app, args)
        assert res.exit_code == 2, (args, res.output)
        assert res.stderr.startswith("error: ") and res.stderr.count("\n") == 1, res.stderr


def test_inspect_source_uri(replica_dir):
    if importlib.util.find_spec("sources.replica") is None:
        pytest.skip("replica source not built yet")
    res = runner.invoke(app, ["inspect", f"replica:{replica_dir}"])
    assert res.exit_code == 0, res.output
    assert "frames: 20" in res.stdout and "1200 x 680" in res.stdout
    assert "fx=600.000" in res.stdout and "pose yes, depth yes" in res.stdout


def test_inspect_unfinalised_mcap(tmp_path):
    """A run that crashed leaves an MCAP without footer: inspect still counts what is there."""
    from sinks.mcap_sink import McapSink

    sink = McapSink(tmp_path / "cut.mcap")
    for i in range(2):
        sink.log_pose(i, 1.0 + i, np.eye(4))
        sink.log_frame(i, 1.0 + i, np.zeros((4, 4, 3), np.float32), Intrinsics(4, 4, 1.5, 1.5, 4, 4), np.eye(4))
    res = runner.invoke(app, ["inspect", str(tmp_path / "cut.mcap")])
    sink.close()
    assert res.exit_code == 0, res.output
    assert "ends early" in res.stdout
    rows = {ln.split()[0]: ln.split() for ln in res.stdout.splitlines() if ln.startswith("  /")}
    assert rows["/tf"][1] == "4" and rows["/camera/image"][1] == "2"


def test_inspect_output_directory_text_and_json(outdir):
    from nicer_stream.io import output_dir as od

    od.write_summary(outdir, od.Summary(
        frames=3, preset="fast", device="cpu", priors=["stereo"], wall_s=12.0, stages_s=od.StageSeconds(mapping=9.0),
        seconds_per_frame=4.0, peak_rss_mb=100.0, versions={}, interrupted=True, error="RuntimeError: boom",
        source="synthetic:room", notes=["scene bound from depth"]))
    od.write_eval(outdir, od.EvalReport(ate_rmse_m=0.0123, psnr_db=27.5))
    res = runner.invoke(app, ["inspect", str(outdir)])
    assert res.exit_code == 0, res.output
    assert "ended early: RuntimeError: boom" in res.stdout and "3 frames in 12 s" in res.stdout
    assert "27.5" in res.stdout and "note: scene bound from depth" in res.stdout
    res = runner.invoke(app, ["inspect", str(outdir), "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    assert data["kind"] == "outputs" and data["summary"]["frames"] == 3
    assert data["eval"]["ate_rmse_m"] == pytest.approx(0.0123) and "trajectory.tum" in data["files"]


def test_inspect_json_of_a_recording(outdir):
    runner.invoke(app, ["convert", str(outdir), "--to", "mcap", "--out", str(outdir / "x.mcap")])
    data = json.loads(runner.invoke(app, ["inspect", str(outdir / "x.mcap"), "--json"]).stdout)
    assert data["kind"] == "mcap" and any("/camera/pose" in line for line in data["lines"])
