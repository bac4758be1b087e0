"""Per-iteration cost of mapping and tracking at `fast` and `paper` sizes (Replica clip,
oracle priors, GT poses: a benchmark of compute, not of accuracy), the FLOPs each iteration
needs (counted from the layer shapes) and this CPU's sgemm rate, measured in the same run.

`--trained N` first fits the map for N more iterations at `fast`'s mapping sizes (1024 rays,
32 + 12 + 4 samples; the preset's own model and schedule) before anything is timed: the map a
run's tracking meets has surfaces, where the probes' early stop and the tracker's transmittance
cut take effect, unlike the one-iteration map of the default (`paper`).

`--floor` splits a `fast` mapping iteration by kind of op (torch.profiler, self CPU time) and puts
each kind against this CPU's limits measured in the same run: the products' FLOPs (from their
shapes) at the sgemm rate, Adam and the gradient zeroing's bytes at the copy bandwidth.

Usage: .venv/bin/python scripts/iter_bench.py [--presets fast,paper] [--iters N] [--profile] [--trained N] [--floor]
"""
from __future__ import annotations

import argparse
import collections
import importlib.util
import math
import time
from dataclasses import replace

import numpy as np
import torch

from nicer_stream import config as config_mod
from nicer_stream.mapping.mapper import Mapper
from nicer_stream.model.bound import bound_from_points
from nicer_stream.model.scene import SceneModel
from nicer_stream.render.beta import BetaField
from nicer_stream.runtime.frame_priors import make_engine, map_frame
from nicer_stream.tracking.tracker import Tracker
from sources import open_source
from sources.base import SourceOptions

REPLICA = "replica:../shared/data/replica_room0_20f"


def sgemm_gflops(n: int = 2048, reps: int = 5) -> float:
    a, b = torch.randn(n, n), torch.randn(n, n)
    a @ b
    t = time.perf_counter()
    for _ in range(reps):
        a @ b
    return 2 * n**3 * reps / (time.perf_counter() - t) / 1e9


def copy_gbs(mb: int = 128, reps: int = 10) -> float:
    """Copy bandwidth (bytes read + written per second, GB/s) of a large tensor."""
    x = torch.empty(mb * 2**18)
    y = torch.empty_like(x)
    y.copy_(x)
    t = time.perf_counter()
    for _ in range(reps):
        y.copy_(x)
    return reps * 2 * x.numel() * 4 / (time.perf_counter() - t) / 1e9


PRODUCTS = {"mkldnn::_linear_pointwise", "aten::addmm_", "aten::addmm", "aten::mm", "aten::bmm"}  # leaf ops only
BULK = {"aten::_fused_adam_", "aten::fill_", "aten::zero_", "aten::cat", "aten::copy_"}
GRIDS = {"GridInterp", "GridInterpBackward"}


def product_flops(key: str, shapes: list) -> float:
    """FLOPs of one product op from its recorded input shapes."""
    if key == "mkldnn::_linear_pointwise":
        return 2 * math.prod(shapes[0][:-1]) * shapes[0][-1] * shapes[1][0]
    if key == "aten::mm":
        return 2 * shapes[0][0] * shapes[0][1] * shapes[1][1]
    if key == "aten::bmm":
        return 2 * math.prod(shapes[0]) * shapes[1][-1]
    return 2 * shapes[1][0] * shapes[1][1] * shapes[2][1]  # addmm(_): (bias, m x k, k x n)


def floor_table(mapper: Mapper, mfs, poses, iters: int) -> None:
    """A `fast` mapping iteration by kind of op against this CPU's limits (see the module doc)."""
    from torch.profiler import ProfilerActivity, profile as prof
    ba = {mfs[-1].index}
    mapper.optimise(mfs, poses, 2, ba_indices=ba)
    t = time.perf_counter()
    mapper.optimise(mfs, poses, iters, ba_indices=ba)
    wall = (time.perf_counter() - t) / iters * 1e3
    stepped, step = [], mapper.opt.step

    def counted_step(*args, **kwargs):  # the parameters Adam updates (frozen groups have no gradient)
        stepped.append(sum(q.numel() for g in mapper.opt.param_groups for q in g["params"] if q.grad is not None))
        return step(*args, **kwargs)

    mapper.opt.step = counted_step
    with prof(activities=[ProfilerActivity.CPU], record_shapes=True) as p:
        mapper.optimise(mfs, poses, iters, ba_indices=ba)
    mapper.opt.step = step
    ms, flops, other = collections.Counter(), 0.0, collections.Counter()
    for e in p.key_averages(group_by_input_shape=True):
        kind = ("products" if e.key in PRODUCTS else "bulk" if e.key in BULK
                else "grids" if e.key in GRIDS else "other")
        ms[kind] += e.self_cpu_time_total / iters / 1e3
        if kind == "other":
            other[e.key] += e.self_cpu_time_total / iters / 1e3
        if kind == "products":
            flops += product_flops(e.key, e.input_shapes) * e.count / iters
    peak, bw = sgemm_gflops(), copy_gbs()
    n_params = sum(q.numel() for q in mapper.model.parameters())
    # Adam reads p, g, m, v and writes p, m, v of what it updates; zeroing writes every gradient.
    adam_mb = (7 * sum(stepped) / len(stepped) + n_params) * 4 / 1e6
    print(f"\n--- fast mapping iteration against this CPU's limits: {wall:.1f} ms unprofiled, "
          f"{sum(ms.values()):.1f} ms of ops under the profiler; sgemm {peak:.0f} GFLOP/s, copy {bw:.0f} GB/s, "
          f"{n_params / 1e6:.1f}M parameters")
    print("| ops | ms per iteration | work | ms at the limit |")
    print("|---|---|---|---|")
    print(f"| products (oneDNN linear, addmm_, mm) | {ms['products']:.1f} | {flops / 1e9:.2f} GFLOP, "
          f"{flops / 1e6 / max(ms['products'], 1e-9):.0f} GFLOP/s | {flops / 1e6 / peak:.1f} |")
    print(f"| Adam, zeroing, cat, copy | {ms['bulk']:.1f} | Adam and zeroing {adam_mb:.0f} MB | {adam_mb / bw:.1f} (Adam and zeroing) |")
    print(f"| grid kernels (gathers, scatters) | {ms['grids']:.1f} | | |")
    top = ", ".join(f"{k} {v:.1f}" for k, v in other.most_common(6))
    print(f"| other ops | {ms['other']:.1f} | {len(other)} kinds; the largest (ms): {top} | |")


def mlp_macs(dims: list[int]) -> int:
    return sum(a * b for a, b in zip(dims[:-1], dims[1:]))


def flops_per_iteration(cfg, rays: int, n_probe: int, n_grad: int, eikonal: int, tracking: bool,
                        tangents: bool = False) -> float:
    """Matmul FLOPs of one iteration (the MLPs dominate; grids and compositing are memory-bound).
    Probe: forward of coarse + fine geometry. Samples with gradient: geometry value plus the
    reverse sweep for its gradient (2x), colour forward; a backward of ~2x that forward when
    the weights get gradients (mapping), ~1x when they are frozen (tracking). `tangents=True`
    counts the forward-mode geometry of the code before `sdf_grad_mlp.py` (4 rows)."""
    m = cfg.model
    pe = 3 + 6 * m.pe_levels
    coarse = mlp_macs([pe + m.coarse_dim, m.coarse_hidden, 1 + m.geo_feature_dim])
    fine = mlp_macs([pe + m.fine_levels * m.fine_dim] + [m.fine_hidden] * m.fine_layers + [1 + m.geo_feature_dim])
    color_in = 6 + 3 + 6 * m.view_pe_levels + 2 * m.geo_feature_dim + m.color_levels * m.color_dim
    color = mlp_macs([color_in] + [m.color_hidden] * m.color_layers + [3])
    geo = coarse + fine
    probe = rays * n_probe * geo
    rows = 4 if tangents else 2
    fwd = rays * n_grad * (rows * geo + color) + eikonal * rows * geo
    return 2 * (probe + (2 if tracking and not tangents else 3) * fwd)


def load(n_frames: int, max_side: int):
    src = open_source(REPLICA, SourceOptions(max_side=max_side, max_frames=n_frames))
    frames = list(src)
    try:
        engine = make_engine("oracle:clean", None, "cpu")
    except Exception:  # a baseline commit from before `oracle:clean` (its `oracle` is the same)
        engine = make_engine("oracle", None, "cpu")
    mfs = [map_frame(f, engine, [frames[j] for j in (i - 2, i + 2) if 0 <= j < len(frames)], "cpu")
           for i, f in enumerate(frames)]
    poses = {f.index: torch.tensor(f.gt_pose, dtype=torch.float32) for f in frames}
    pts = np.stack([f.gt_pose[:3, 3] for f in frames])
    bound = bound_from_points(np.concatenate([pts - 2.5, pts + 2.5]), 1.0, "config")
    return mfs, poses, bound


def warmed_up(cfg, mfs, poses, bound, warmup_iters: int, trained: int = 0) -> tuple[Mapper, Tracker]:
    """A mapper and a tracker over a map after `warmup_iters` mapping iterations (a warm-up, and
    a map that is not the initial sphere), preceded by `trained` at `fast`'s mapping sizes; later
    calls time iterations in the last stage."""
    torch.manual_seed(0)
    model = SceneModel(cfg.model, bound)
    beta = BetaField(cfg.render)
    if trained:
        small = replace(cfg, render=replace(cfg.render, n_probe=32, n_importance=12, n_uniform=4),
                        mapping=replace(cfg.mapping, rays=1024, eikonal_points=256))
        Mapper(model, beta, small, 0).optimise(mfs, poses, trained)
    mapper = Mapper(model, beta, cfg, 0)
    mapper.optimise(mfs, poses, warmup_iters, ba_indices={mfs[-1].index})
    return mapper, Tracker(model, beta, cfg.tracking, cfg.render, 0)


def bench(name: str, iters: int, profile: bool, trained: int = 0, floor: bool = False) -> dict:
    cfg = config_mod.preset(name)
    side = cfg.max_side or 1200
    mfs, poses, bound = load(5, side if name == "fast" else 320)
    mapper, tracker = warmed_up(cfg, mfs, poses, bound, 3 if name == "fast" else 1, trained)
    t = time.perf_counter()
    mapper.optimise(mfs, poses, iters, ba_indices={mfs[-1].index})
    map_s = (time.perf_counter() - t) / iters
    tr_cfg = tracker.cfg
    tracker.cfg = type(tr_cfg)(**{**tr_cfg.__dict__, "iters": iters})
    tracker.track(mfs[-1], poses[mfs[-1].index])
    t = time.perf_counter()
    tracker.track(mfs[-1], poses[mfs[-1].index])
    track_s = (time.perf_counter() - t) / (iters + 1)
    if floor and name == "fast":
        floor_table(mapper, mfs, poses, iters)
    if profile and name == "fast":
        from torch.profiler import ProfilerActivity, profile as prof
        with prof(activities=[ProfilerActivity.CPU]) as p:
            mapper.optimise(mfs, poses, 3, ba_indices={mfs[-1].index})
        print(f"--- {name}: mapping profile (3 iterations)")
        print(p.key_averages().table(sort_by="self_cpu_time_total", row_limit=12))
        with prof(activities=[ProfilerActivity.CPU]) as p:
            tracker.cfg = type(tr_cfg)(**{**tr_cfg.__dict__, "iters": 5})
            tracker.track(mfs[-1], poses[mfs[-1].index])
        print(f"--- {name}: tracking profile (6 iterations)")
        print(p.key_averages().table(sort_by="self_cpu_time_total", row_limit=12))
    r = cfg.render
    # The code before `sdf_grad_mlp.py` pushed three tangent rows through the geometry MLPs.
    tangents = importlib.util.find_spec("nicer_stream.model.sdf_grad_mlp") is None
    tr = tracker.render
    m_flop = flops_per_iteration(cfg, cfg.mapping.rays, r.n_probe, r.n_importance + r.n_uniform, cfg.mapping.eikonal_points, False, tangents)
    t_flop = flops_per_iteration(cfg, cfg.tracking.rays, tr.n_probe, tr.n_importance + tr.n_uniform, 0, True, tangents)
    return {"preset": name, "map_s": map_s, "track_s": track_s, "map_gflop": m_flop / 1e9, "track_gflop": t_flop / 1e9}


def run_conditions() -> list[str]:
    """The process settings a SLAM run makes (where this tree has them)."""
    done = []
    try:
        from nicer_stream.runtime.allocator import retain_freed_memory
        if retain_freed_memory():
            done.append("freed memory retained")
    except ImportError:
        pass
    try:
        from nicer_stream.runtime.matmul_backend import enable_onednn_matmul
        if enable_onednn_matmul():
            done.append("oneDNN matmuls")
    except ImportError:
        pass
    return done


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--presets", default="fast,paper")
    ap.add_argument("--iters", type=int, default=5)
    ap.add_argument("--profile", action="store_true")
    ap.add_argument("--trained", type=int, default=0, help="mapping iterations at fast's sizes before timing")
    ap.add_argument("--floor", action="store_true", help="a fast mapping iteration by kind of op against the CPU's limits")
    a = ap.parse_args()
    print(f"torch {torch.__version__}, threads {torch.get_num_threads()}; {', '.join(run_conditions()) or 'default settings'}", flush=True)
    rows = [bench(p, a.iters if p == "fast" else max(1, a.iters // 5), a.profile, a.trained, a.floor) for p in a.presets.split(",")]
    peak = sgemm_gflops()
    print(f"\nsgemm 2048^3: {peak:.1f} GFLOP/s; map fitted for {a.trained} iterations at fast's sizes first")
    print("| preset | mapping s/iter | GFLOP | GFLOP/s | x sgemm | tracking s/iter | GFLOP | GFLOP/s | x sgemm |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        mg, tg = r["map_gflop"] / r["map_s"], r["track_gflop"] / r["track_s"]
        print(f"| {r['preset']} | {r['map_s']:.3f} | {r['map_gflop']:.1f} | {mg:.1f} | {peak / mg:.1f} "
              f"| {r['track_s']:.3f} | {r['track_gflop']:.2f} | {tg:.1f} | {peak / tg:.1f} |")


if __name__ == "__main__":
    main()
