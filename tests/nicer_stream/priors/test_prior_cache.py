"""The on-disk prior cache: exact round trips and one-line errors."""
from __future__ import annotations

import json

import numpy as np
import pytest

from nicer_stream.errors import UserError
from nicer_stream.priors import make_depth_normal_provider, make_flow_provider
from nicer_stream.priors.base import DepthNormal
from nicer_stream.priors.cache import FORMAT_VERSION, CacheMeta, CacheWriter, depth_normal_path, flow_path
from nicer_stream.priors.oracle import OracleDepthNormal, OracleFlow
from nicer_stream.types import FlowPrior


def _meta(frame, dn="oracle", flow="oracle") -> CacheMeta:
    return CacheMeta(FORMAT_VERSION, dn, flow, frame.width, frame.height, "test")


def test_cache_providers_return_exactly_what_was_written(tmp_path, replica_small):
    dn_p, flow_p = OracleDepthNormal(seed=1), OracleFlow()
    writer = CacheWriter(tmp_path, _meta(replica_small[0]))
    written = {}
    for f in replica_small:
        written[f.index] = dn_p.predict(f)
        writer.write_depth_normal(f.index, written[f.index])
    fw, bw = flow_p.flow_both(replica_small[0], replica_small[1])
    writer.write_flow(fw)
    writer.write_flow(bw)

    cached_dn = make_depth_normal_provider(f"cache:{tmp_path}")
    cached_flow = make_flow_provider(f"cache:{tmp_path}")
    assert cached_dn.name == "cache(oracle)" and cached_flow.name == "cache(oracle)"
    for f in replica_small:
        got = cached_dn.predict(f)
        assert np.array_equal(got.depth, written[f.index].depth) and got.depth.dtype == np.float32
        assert np.array_equal(got.normal, written[f.index].normal) and got.normal.dtype == np.float32
    for ref, (s, d) in ((fw, (0, 1)), (bw, (1, 0))):
        got = cached_flow.flow(replica_small[s], replica_small[d])
        assert (got.src_index, got.dst_index) == (s, d)
        assert np.array_equal(got.flow, ref.flow) and np.array_equal(got.valid, ref.valid)
        assert got.valid.dtype == bool


def test_round_trip_of_arbitrary_arrays_and_none(tmp_path, replica_small):
    f = replica_small[0]
    rng = np.random.default_rng(0)
    writer = CacheWriter(tmp_path, _meta(f, dn="none"))
    depth = rng.normal(size=(f.height, f.width)).astype(np.float32)
    writer.write_depth_normal(0, DepthNormal(depth=depth, normal=None))
    flow = FlowPrior(0, 2, rng.normal(size=(f.height, f.width, 2)).astype(np.float32), rng.random((f.height, f.width)) > 0.5)
    writer.write_flow(flow)
    assert depth_normal_path(tmp_path, 0).is_file() and flow_path(tmp_path, 0, 2).name == "flow_000000_000002.npz"
    got = make_depth_normal_provider(f"cache:{tmp_path}").predict(f)
    assert np.array_equal(got.depth, depth) and got.normal is None
    meta = json.loads((tmp_path / "meta.json").read_text())
    assert meta["format_version"] == FORMAT_VERSION and (meta["width"], meta["height"]) == (f.width, f.height)


def _one_line_error(fn) -> str:
    with pytest.raises(UserError) as e:
        fn()
    msg = str(e.value)
    assert "\n" not in msg
    return msg


def test_missing_files_name_the_file_and_the_command(tmp_path, replica_small):
    f0, f1 = replica_small[:2]
    msg = _one_line_error(lambda: make_depth_normal_provider(f"cache:{tmp_path / 'nope'}"))
    assert "meta.json" in msg and "nicer-stream priors" in msg
    CacheWriter(tmp_path, _meta(f0))
    msg = _one_line_error(lambda: make_depth_normal_provider(f"cache:{tmp_path}").predict(f0))
    assert "frame_000000.npz" in msg and "nicer-stream priors" in msg
    msg = _one_line_error(lambda: make_flow_provider(f"cache:{tmp_path}").flow(f0, f1))
    assert "flow_000000_000001.npz" in msg and "nicer-stream priors" in msg


def test_wrong_size_and_wrong_version_are_user_errors(tmp_path, replica_small):
    f = replica_small[0]
    CacheWriter(tmp_path, CacheMeta(FORMAT_VERSION, "oracle", "dis", f.width + 1, f.height, ""))
    msg = _one_line_error(lambda: make_depth_normal_provider(f"cache:{tmp_path}").predict(f))
    assert "--max-side" in msg
    meta = json.loads((tmp_path / "meta.json").read_text())
    meta["format_version"] = 99
    (tmp_path / "meta.json").write_text(json.dumps(meta))
    assert "format_version" in _one_line_error(lambda: make_flow_provider(f"cache:{tmp_path}"))
