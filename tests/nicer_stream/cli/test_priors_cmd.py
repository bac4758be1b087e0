"""`nicer-stream priors` end to end on real Replica frames."""
from __future__ import annotations

import json

import numpy as np
from typer.testing import CliRunner

from nicer_stream.cli.main import app
from nicer_stream.priors import make_depth_normal_provider, make_flow_provider
from nicer_stream.priors.oracle import OracleDepthNormal
from sources import open_source
from sources.base import SourceOptions

runner = CliRunner()


def test_priors_writes_a_cache_that_reads_back(tmp_path, replica_dir):
    out = tmp_path / "cache"
    uri = f"replica:{replica_dir}"
    res = runner.invoke(
        app,
        ["priors", "--source", uri, "--provider", "oracle", "--max-frames", "3", "--max-side", "160",
         "--flow-gap", "2", "--out", str(out)],
    )
    assert res.exit_code == 0, res.output
    assert f"read it with --priors cache:{out} --flow cache:{out}" in res.output  # run's and map's flags
    assert sum(line.startswith("frame ") for line in res.output.splitlines()) == 3  # one progress line per frame
    meta = json.loads((out / "meta.json").read_text())
    assert (meta["depth_normal_provider"], meta["flow_provider"]) == ("oracle", "dis")
    assert (meta["width"], meta["height"]) == (160, 91)
    assert sorted(p.name for p in (out / "depth_normal").iterdir()) == [f"frame_00000{i}.npz" for i in range(3)]
    pairs = sorted(p.name for p in (out / "flow").iterdir())
    assert pairs == sorted(f"flow_00000{s}_00000{d}.npz" for s in range(3) for d in range(3) if s != d)

    frames = list(open_source(uri, SourceOptions(max_frames=3, max_side=160)))
    dn = make_depth_normal_provider(f"cache:{out}").predict(frames[2])
    ref = OracleDepthNormal().predict(frames[2])
    assert np.array_equal(dn.depth, ref.depth) and np.array_equal(dn.normal, ref.normal)
    fl = make_flow_provider(f"cache:{out}").flow(frames[2], frames[0])
    assert fl.flow.shape == (91, 160, 2) and fl.valid.any()


def test_unknown_provider_is_a_one_line_error(tmp_path, replica_dir):
    res = runner.invoke(
        app, ["priors", "--source", f"replica:{replica_dir}", "--provider", "midas", "--out", str(tmp_path / "c")]
    )
    assert res.exit_code == 2
    lines = [l for l in res.output.splitlines() if l.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: unknown depth/normal prior provider 'midas'")
    assert not (tmp_path / "c").exists()


def test_oracle_on_a_source_without_gt_depth_is_a_one_line_error(tmp_path, tum_dir):
    res = runner.invoke(
        app, ["priors", "--source", f"tum:{tum_dir}", "--provider", "oracle", "--max-frames", "1",
              "--max-side", "64", "--out", str(tmp_path / "c")]
    )
    lines = [l for l in res.output.splitlines() if l.strip()]
    assert res.exit_code == 2 and len(lines) == 1 and "oracle" in lines[0], res.output
    assert not (tmp_path / "c").exists()
