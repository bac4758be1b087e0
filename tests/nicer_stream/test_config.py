"""Configuration presets, paper values, overrides, files and field docstrings."""
import ast
import dataclasses
import json
from pathlib import Path

import pytest

from nicer_stream import config as C
from nicer_stream.errors import UserError


def test_presets_exist():
    assert set(C.PRESETS) >= {"paper", "fast"}
    assert C.preset("paper").preset == "paper"
    assert C.preset("fast").preset == "fast"
    with pytest.raises(UserError, match="nope"):
        C.preset("nope")


def test_paper_values():
    p = C.paper()
    r, m, t, mo = p.render, p.mapping, p.tracking, p.model
    assert (r.beta_c0, r.beta_c1, r.beta_c2) == (1.208e-2, 6.26471e-6, 2.3e-3)
    assert r.beta_voxels == 64 and r.beta_mode == "adaptive"
    assert m.rays == 8096 and t.rays == 1024
    assert m.iters == 100 and t.iters == 100
    assert (m.window_random, m.window_recent, m.recent_pool) == (5, 10, 20)  # + current = 16
    assert m.keyframe_every == 10 and m.every == 5 and m.final_iters is None
    assert (m.fine_start, m.ba_start) == (0.25, 0.75)
    assert (mo.coarse_res, mo.coarse_dim, mo.coarse_hidden, mo.pe_levels) == (32, 32, 64, 6)
    assert (mo.fine_levels, mo.fine_res_min, mo.fine_res_max, mo.fine_dim) == (8, 32, 128, 4)
    assert (mo.fine_hidden, mo.fine_layers, mo.geo_feature_dim) == (64, 3, 32)
    assert (mo.color_levels, mo.color_res_min, mo.color_res_max, mo.color_dim) == (16, 16, 2048, 2)
    assert (mo.color_hidden, mo.color_layers, mo.view_pe_levels) == (64, 2, 4)
    assert p.mesh.resolution == 512
    w = p.loss.weights
    assert (w.rgb, w.warp, w.flow, w.depth, w.eikonal) == (1.0, 0.5, 0.001, 0.1, 0.1)
    assert w.normal_l1 == w.normal_angular == 0.05


def test_override_nested_and_unknown_keys():
    cfg = C.paper()
    new = C.override(cfg, {"mapping": {"iters": 7}, "bound": {"centre": [1, 2, 3]}, "seed": 3,
                           "loss": {"weights": {"rgb": 2.0}}})
    assert new.mapping.iters == 7 and new.mapping.rays == cfg.mapping.rays
    assert new.bound.centre == (1, 2, 3) and new.seed == 3
    assert new.loss.weights.rgb == 2.0 and new.loss.weights.warp == 0.5
    assert cfg.mapping.iters == 100  # the original is unchanged (frozen)
    with pytest.raises(UserError, match=r"config\.mapping\.iterz") as e:
        C.override(cfg, {"mapping": {"iterz": 7}})
    assert "\n" not in str(e.value)
    with pytest.raises(UserError, match="bogus"):
        C.override(cfg, {"bogus": 1})
    with pytest.raises(UserError, match="render"):
        C.override(cfg, {"render": 5})


def test_load_toml_and_json(tmp_path: Path):
    toml = tmp_path / "c.toml"
    toml.write_text('seed = 4\n[render]\nn_probe = 33\nbeta_mode = "fixed"\n[model]\nfine_levels = 3\n')
    cfg = C.load("fast", toml)
    assert cfg.preset == "fast" and cfg.seed == 4
    assert cfg.render.n_probe == 33 and cfg.render.beta_mode == "fixed"
    assert cfg.model.fine_levels == 3
    assert cfg.mapping.rays == C.fast().mapping.rays
    js = tmp_path / "c.json"
    js.write_text(json.dumps({"tracking": {"lr": 0.1}, "max_side": 200}))
    cfg = C.load("paper", js)
    assert cfg.tracking.lr == 0.1 and cfg.max_side == 200 and cfg.preset == "paper"
    assert C.load("paper") == C.paper()
    with pytest.raises(UserError, match="does not exist"):
        C.load("paper", tmp_path / "missing.toml")
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"render": {"n_probes": 3}}))
    with pytest.raises(UserError, match="n_probes"):
        C.load("paper", bad)


@pytest.mark.parametrize("name,text", [("x.json", "{mapping: 3"), ("x.toml", "[mapping\niters = 3"),
                                       ("x.json", "[1, 2]")])
def test_load_malformed_file_is_one_line_user_error(tmp_path: Path, name: str, text: str):
    p = tmp_path / name
    p.write_text(text)
    with pytest.raises(UserError, match="x\\.(json|toml)") as e:
        C.load("paper", p)
    assert "\n" not in str(e.value)


def test_to_dict_round_trips_through_override():
    cfg = C.fast()
    assert C.override(C.paper(), dataclasses.asdict(cfg)) == cfg


def config_sources() -> list[Path]:
    """The files of the config package."""
    return sorted(Path(C.__file__).parent.glob("*.py"))


def test_every_config_file_is_short():
    long = {p.name: n for p in config_sources() if (n := len(p.read_text().splitlines())) > 350}
    assert not long, f"config files over 350 lines: {long}"


def test_every_field_has_a_docstring():
    nodes = [node for p in config_sources() for node in ast.parse(p.read_text()).body]
    checked = 0
    for node in nodes:
        if not isinstance(node, ast.ClassDef):
            continue
        cls = getattr(C, node.name)
        if not dataclasses.is_dataclass(cls):
            continue
        body = node.body
        names = {f.name for f in dataclasses.fields(cls)}
        for i, stmt in enumerate(body):
            if isinstance(stmt, ast.AnnAssign) and isinstance(stmt.target, ast.Name) and stmt.target.id in names:
                nxt = body[i + 1] if i + 1 < len(body) else None
                ok = isinstance(nxt, ast.Expr) and isinstance(nxt.value, ast.Constant) and isinstance(nxt.value.value, str)
                assert ok, f"{node.name}.{stmt.target.id} has no docstring"
                names.discard(stmt.target.id)
                checked += 1
        assert not names, f"{node.name}: fields not found in source {names}"
    assert checked > 50


@pytest.mark.parametrize("text, message", [
    ('seed = "zero"', "config file {path}: seed must be an integer, got 'zero'"),
    ("[tracking]\niters = -5", "config file {path}: tracking.iters must be an integer >= 0, got -5"),
    ('[tracking]\noptimizer = "newton"', "config file {path}: tracking.optimizer must be one of 'adam', 'gauss_newton', got 'newton'"),
    ("[mapping]\nba_start = 1.5", "config file {path}: mapping.ba_start must be a number in [0, 1], got 1.5"),
    ("[mapping]\nbatched_terms = 1", "config file {path}: mapping.batched_terms must be true or false, got 1"),
    ("[loss.weights]\ndepth = -1.0", "config file {path}: loss.weights.depth must be a number >= 0, got -1.0"),
    ("[bound]\ncentre = [1, 2]", "config file {path}: bound.centre must be 3 numbers, got (1, 2)"),
    ("max_side = 0", "config file {path}: max_side must be an integer > 0, got 0"),
])
def test_a_wrong_value_in_a_file_is_one_line_naming_its_key(tmp_path: Path, text: str, message: str):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(UserError) as e:
        C.load("fast", path)
    assert str(e.value) == message.format(path=path)


def test_sections_check_their_modes_and_ranges_when_built():
    with pytest.raises(UserError, match="model.sphere_centre must be one of 'bound', 'camera', 'auto'"):
        C.ModelConfig(sphere_centre="centre")
    with pytest.raises(UserError, match=r"tracking.lr must be a number > 0"):
        dataclasses.replace(C.fast().tracking, lr=0.0)
    assert dataclasses.replace(C.fast().tracking, lr=1).lr == 1  # an integer where a number is asked for is a number
    assert C.load("fast") == C.fast()  # both presets pass their own checks
    assert C.load("paper") == C.paper()
