"""End-to-end `run` on the synthetic scene with a tiny config: the output contract."""
import json

import numpy as np
import pytest

from nicer_stream.io import output_dir as od
from nicer_stream.io.trajectory import read_tum
from nicer_stream.runtime.slam_run import RunRequest, run_slam
from nicer_stream.slam.system import SlamSystem
from nicer_stream.config import load
from sources.base import SourceOptions


def test_run_writes_the_output_contract(tmp_path, tiny_config, capsys):
    cfg = tiny_config
    out = run_slam(RunRequest(source="synthetic:room?frames=6", out_dir=tmp_path / "out", priors="oracle",
                              preset="fast", config_file=str(cfg), sinks=(f"rerun:{tmp_path / 'rec.rrd'}",))).out_dir
    t, poses = read_tum(out / od.TRAJECTORY_FILE)
    assert len(t) == 6 and np.all(np.diff(t) > 0)  # input order, though the two-view start holds frames
    assert np.allclose(poses[0], np.eye(4), atol=1e-6)  # the first pose is the identity
    assert np.isfinite(poses).all()
    summary = json.loads((out / od.SUMMARY_FILE).read_text())
    for key in ("frames", "preset", "device", "priors", "wall_s", "stages_s", "seconds_per_frame", "peak_rss_mb",
                "versions", "interrupted"):
        assert key in summary
    assert summary["frames"] == 6 and summary["interrupted"] is False
    assert "oracle" in summary["priors"]
    assert set(summary["stages_s"]) == {"tracking", "frontend", "mapping", "priors", "sinks"}
    # All 6 frames were handled by finish() (the two-view start never got its 10th frame):
    # its time is still split into tracking and mapping.
    assert summary["stats"]["tracking_s_per_frame"] > 0 and summary["stats"]["mapping_s_per_frame"] > 0
    assert summary["bound"]["source"] == "depth_prior"
    assert any("two-view" in n for n in summary["notes"])
    # `fast` fits the monocular prior to the keyframes' stereo, and says so.
    note = next(n for n in summary["notes"] if n.startswith("priors: oracle"))
    assert "stereo.mono_fusion" in note and " keyframes" in note, note
    assert (tmp_path / "rec.rrd").stat().st_size > 0
    assert any((out / od.RENDERS_DIR).glob("*.npz"))
    # One progress line per frame; replayed held frames show their own tracking time.
    lines = [ln for ln in capsys.readouterr().out.splitlines() if "track loss" in ln]
    assert [int(ln.split()[1]) for ln in lines] == list(range(6))
    assert all("s tracking" in ln for ln in lines)
    assert "[6/6, " in lines[-1] and "eta 0 s, map v" in lines[-1] and "sink calls]" in lines[-1]


@pytest.mark.parametrize("priors", ["none", "oracle"])  # oracle: the NaN frame is among those held
def test_nan_frame_does_not_reach_outputs(tmp_path, monkeypatch, tiny_config, priors):
    import sources.synthetic as synth

    real_open = synth.open

    def open_with_nan(path, query, opts):
        src = real_open(path, query, opts)
        frames_fn = src._frames

        def frames():
            for f in frames_fn():
                if f.index == 3:
                    f.rgb = f.rgb.copy()
                    f.rgb[5:9, 5:9] = np.nan
                yield f

        src._frames = frames
        return src

    monkeypatch.setattr(synth, "open", open_with_nan)
    cfg = tiny_config
    out = run_slam(RunRequest(source="synthetic:room?frames=5", out_dir=tmp_path / "out", priors=priors,
                              flow="none" if priors == "none" else "oracle", config_file=str(cfg))).out_dir
    t, poses = read_tum(out / od.TRAJECTORY_FILE)
    assert len(t) == 5 and np.isfinite(poses).all() and np.all(np.diff(t) > 0)
    summary = json.loads((out / od.SUMMARY_FILE).read_text())
    assert 3 in summary["stats"]["lost_frames"]
    for f in (out / od.RENDERS_DIR).glob("*.npz"):
        with np.load(f) as z:
            assert all(np.isfinite(z[k]).all() for k in ("rgb", "depth", "normal"))


def test_slam_step_refuses_ground_truth():
    from sources import open_source
    from nicer_stream.errors import UserError

    frame = next(iter(open_source("synthetic:room?frames=2", SourceOptions(max_side=32))))
    with pytest.raises(UserError, match="ground truth"):
        SlamSystem(load("fast")).step(frame)


def test_run_with_prior_cache_equals_run_with_its_provider(tmp_path, tiny_config):
    from typer.testing import CliRunner

    from nicer_stream.cli.main import app

    cache = tmp_path / "cache"
    res = CliRunner().invoke(app, ["priors", "--source", "synthetic:room?frames=5", "--provider", "oracle",
                                   "--flow", "oracle", "--flow-gap", "4", "--max-side", "48", "--out", str(cache)])
    assert res.exit_code == 0, res.output
    runs = {}
    for name, pri, flow in (("direct", "oracle", "oracle"), ("cached", f"cache:{cache}", f"cache:{cache}")):
        out = run_slam(RunRequest(source="synthetic:room?frames=5", out_dir=tmp_path / name, priors=pri, flow=flow,
                                  config_file=str(tiny_config), sync=True)).out_dir
        runs[name] = read_tum(out / od.TRAJECTORY_FILE)[1]
    assert np.array_equal(runs["direct"], runs["cached"])  # --sync is deterministic
    summary = json.loads((tmp_path / "cached" / od.SUMMARY_FILE).read_text())
    assert any("oracle" in p for p in summary["priors"])  # a cache of oracle priors stays labelled oracle
