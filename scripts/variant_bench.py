"""Per-iteration cost of `fast` and config variants of it, alternated in one process (this
machine's speed drifts between runs: compare ratios measured side by side), and where a
mapping iteration's time goes by phase.

Each variant is a TOML file of overrides, as `nicer-stream run --config` takes (model sizes,
render samples, ...). Replica clip, `oracle:clean` priors, GT poses, 5 frames: a benchmark of
compute, not of accuracy (`scripts/iter_bench.py` has the FLOP counts).

Usage: .venv/bin/python scripts/variant_bench.py [VARIANT.toml ...] [--rounds 3] [--iters 10] [--warmup 3] [--phases]
"""
from __future__ import annotations

import argparse
import collections
import statistics
import time
from contextlib import contextmanager
from pathlib import Path

import torch

from iter_bench import load, warmed_up
from nicer_stream import config as config_mod
from nicer_stream.mapping import mapper as mapper_mod
from nicer_stream.mapping.mapper import Mapper
from nicer_stream.render import renderer as renderer_mod


@contextmanager
def phase_timers(mapper: Mapper, acc: dict[str, float]):
    """Wall time per phase of `mapper.optimise` into `acc` (seconds), by wrapping its calls."""
    saved = []

    def wrap(owner, name, label):
        f = getattr(owner, name)
        saved.append((owner, name, f, name in vars(owner)))  # own attribute, or found on a class

        def timed(*a, **k):
            t = time.perf_counter()
            r = f(*a, **k)
            acc[label] += time.perf_counter() - t
            return r
        setattr(owner, name, timed)

    wrap(renderer_mod, "probe_pass", "probe pass (no grad)")
    wrap(mapper_mod, "batch_rays", "ray sampling")
    wrap(mapper_mod, "mapping_terms_batched", "loss terms")
    wrap(mapper.model.geometry, "forward", "geometry forward (samples + Eikonal points)")
    wrap(mapper.model.color, "forward", "colour forward")
    wrap(mapper, "_step", "Adam step")
    wrap(mapper.opt, "zero_grad", "zeroing gradients")
    wrap(mapper.beta, "count", "beta counter")
    wrap(torch.Tensor, "backward", "backward")
    try:
        yield
    finally:
        for owner, name, f, own in reversed(saved):
            if own:
                setattr(owner, name, f)
            else:
                delattr(owner, name)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("variants", nargs="*", help="TOML override files (the first row is always plain `fast`)")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--iters", type=int, default=10, help="mapping iterations per round (tracking: the preset's)")
    ap.add_argument("--phases", action="store_true", help="also split plain `fast`'s mapping iterations by phase")
    ap.add_argument("--warmup", type=int, default=3,
                    help="mapping iterations before the clock (a map trained longer has more of its samples behind surfaces)")
    a = ap.parse_args()
    mfs, poses, bound = load(5, 320)
    cfgs = {"fast": config_mod.preset("fast")}
    cfgs.update({Path(v).stem: config_mod.load("fast", v) for v in a.variants})
    setups = {name: warmed_up(cfg, mfs, poses, bound, a.warmup) for name, cfg in cfgs.items()}
    times = {name: ([], []) for name in setups}
    for _ in range(a.rounds):
        for name, (mapper, tracker) in setups.items():
            t = time.perf_counter()
            mapper.optimise(mfs, poses, a.iters, ba_indices={mfs[-1].index})
            times[name][0].append((time.perf_counter() - t) / a.iters)
            t = time.perf_counter()
            tracker.track(mfs[-1], poses[mfs[-1].index])
            times[name][1].append((time.perf_counter() - t) / (tracker.cfg.iters + 1))
    base_m, base_t = (statistics.median(x) for x in times["fast"])
    print(f"torch {torch.__version__}, threads {torch.get_num_threads()}; medians of {a.rounds} alternated rounds")
    print("| variant | mapping s/iter | x fast | tracking s/iter | x fast |\n|---|---|---|---|---|")
    for name, (m, t) in times.items():
        mm, tt = statistics.median(m), statistics.median(t)
        print(f"| {name} | {mm:.4f} | {mm / base_m:.2f} | {tt:.4f} | {tt / base_t:.2f} |")
    if a.phases:
        mapper = setups["fast"][0]
        acc: dict[str, float] = collections.defaultdict(float)
        t = time.perf_counter()
        with phase_timers(mapper, acc):
            mapper.optimise(mfs, poses, 3 * a.iters, ba_indices={mfs[-1].index})
        total = (time.perf_counter() - t) / (3 * a.iters)
        print(f"\n`fast` mapping iteration by phase ({3 * a.iters} iterations, the last quarter with BA poses): "
              f"{total * 1000:.1f} ms\n| phase | ms | share |\n|---|---|---|")
        for label, s in sorted(acc.items(), key=lambda kv: -kv[1]):
            print(f"| {label} | {s / (3 * a.iters) * 1000:.1f} | {s / (3 * a.iters) / total:.1%} |")


if __name__ == "__main__":
    main()
