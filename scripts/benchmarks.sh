#!/usr/bin/env bash
# The measurements named in the issues (long: run one at a time on a 2-core CPU).
# Usage: scripts/benchmarks.sh [map|map-none|map-paper|map-synth|run|run-seeds|seeds|run-none|run-synth|run10|run10-paper|flow|ab|speedup|iters|frontend|street|kitti|jump|async|memory|batch] [OUTROOT]
# speedup: the Replica `run` of commit BASE (default c64946b; a git worktree in OUTROOT/base_worktree)
#   and of this tree (uncommitted edits included) back to back, then scripts/speedup_table.py
#   (~15 min). EXTRA="..." appends arguments to both runs (e.g. EXTRA="--max-frames 3"), NEW_EXTRA="..."
#   to this tree's alone (e.g. NEW_EXTRA="--config candidate.toml": settings the baseline does not know).
#   SOURCE=URI runs another log instead of the Replica clip (e.g. SOURCE=mcap:LOG.mcap EXTRA="--max-frames
#   300": a real 30 Hz log), PRIORS=NAME the same priors in both runs (default: the oracle's near-GT priors).
# Tables: .venv/bin/python scripts/eval_table.py OUT... [--reference OUTROOT/map_oracle]
# run10-paper needs hours here: Ctrl-C writes what was computed (trajectory so far, mesh, eval).
set -euo pipefail
cd "$(dirname "$0")/.."
NS=.venv/bin/nicer-stream
REPLICA=replica:../shared/data/replica_room0_20f
OUT=${2:-runs/bench}
t() { /usr/bin/time -f "wall %e s, peak RSS %M KB" "$@"; }
# Compiled kernels: one cache per tree. Torch rebuilds an extension whose source path changed, and
# commits before 8d72127 use one cache name for every checkout, so alternating trees on one cache
# would time a build.
kernel_cache() { export TORCH_EXTENSIONS_DIR="$PWD/runs/torch_ext/$(echo "$1" | md5sum | cut -c1-8)"; }
# speedup_run TREE OUTDIR PRIORS: `nicer-stream run` of the code in TREE (not the editable install),
# timed into OUTDIR/time.txt (read by speedup_table.py).
speedup_run() {
  local tree=$1 dir=$2 root=$PWD py=$PWD/.venv/bin/python
  # The tree's packages must win over the editable install's (its finder comes after PYTHONPATH).
  (cd "$tree" && PYTHONPATH="$tree" $py -c 'import os, sys, nicer_stream, sources, sinks
tree = os.path.realpath(sys.argv[1]) + os.sep
bad = [m.__file__ for m in (nicer_stream, sources, sinks) if not os.path.realpath(m.__file__).startswith(tree)]
sys.exit(f"imported from outside {sys.argv[1]}: {bad}" if bad else 0)' "$tree")
  rm -rf "$dir" && mkdir -p "$dir"
  echo "== $(git -C "$tree" rev-parse --short HEAD) ($tree) -> $dir"
  kernel_cache "$tree"  # built here, before the clock starts
  for m in model/grid_kernel model/softplus model/positional denormals; do
    if [ -f "$tree/nicer_stream/$m.py" ]; then (cd "$tree" && PYTHONPATH="$tree" $py -m "nicer_stream.${m//\//.}" >/dev/null); fi
  done
  # shellcheck disable=SC2086  # EXTRA is split into arguments on purpose
  (cd "$tree" && PYTHONPATH="$tree" /usr/bin/time -f "%e %M" -o "$dir/time.txt" $py -m nicer_stream.cli.main run \
     --source "${SOURCE:-replica:$root/../shared/data/replica_room0_20f}" --priors "${PRIORS:-$3}" --preset fast --out "$dir" ${EXTRA:-} ${4:-})
  echo "wall $(cut -d' ' -f1 "$dir/time.txt") s, peak RSS $(cut -d' ' -f2 "$dir/time.txt") KB"
}
# seed_runs NAME SOURCE PRIORS [CONFIG [ARGS...]]: `nicer-stream run` (`fast`) on seeds 0 1 2 into
# OUT/NAME_seedN, each with CONFIG's overrides (a TOML file without a `seed` key) when given, and ARGS.
seed_runs() {
  mkdir -p $OUT
  for s in 0 1 2; do
    local cfg=$OUT/$1_seed$s.toml
    echo "seed = $s" > $cfg
    if [ -n "${4:-}" ]; then grep -v '^seed' "$4" >> $cfg || true; fi
    t $NS run --source "$2" --priors "$3" --preset fast --config $cfg --out $OUT/$1_seed$s "${@:5}"
  done
}
case "${1:-all}" in
  map)       t $NS map --source $REPLICA --poses gt --priors oracle --preset fast --out $OUT/map_oracle ;;
  map-none)  t $NS map --source $REPLICA --poses gt --priors none --preset fast --out $OUT/map_none ;;
  map-paper) t $NS map --source $REPLICA --poses gt --priors oracle --preset paper --minutes 15 --max-side 320 --render-every 20 --out $OUT/map_paper320 ;;
  flow)      .venv/bin/python scripts/flow_benchmark.py ;;
  map-synth) t $NS map --source "synthetic:room?frames=60" --poses gt --priors oracle --preset fast --out $OUT/map_synth ;;
  run)       t $NS run --source $REPLICA --priors oracle --preset fast --out $OUT/run_oracle ;;
  run-seeds) # the Replica run for seeds 0 1 2 (results vary run to run: judge a change by the spread)
             seed_runs run $REPLICA oracle
             ref=(); [ -f $OUT/map_oracle/eval.json ] && ref=(--reference $OUT/map_oracle)
             .venv/bin/python scripts/eval_table.py $OUT/run_seed0 $OUT/run_seed1 $OUT/run_seed2 "${ref[@]}" ;;
  seeds)     # a config on three seeds and its table with means (docs/performance.md, stop 39: one seed
             # decides nothing). CONFIG=overrides.toml (optional, no `seed` key), SOURCE= (default the
             # Replica clip), PRIORS= (default oracle:clean).
             name=$(basename "${CONFIG:-fast}" .toml)
             seed_runs "$name" "${SOURCE:-$REPLICA}" "${PRIORS:-oracle:clean}" "${CONFIG:-}"
             .venv/bin/python scripts/eval_table.py $OUT/${name}_seed0 $OUT/${name}_seed1 $OUT/${name}_seed2 ;;
  run-none)  t $NS run --source $REPLICA --priors none --preset fast --out $OUT/run_none ;;
  run10)     t $NS run --source $REPLICA --priors oracle --preset fast --max-frames 10 --out $OUT/run10_fast ;;
  run10-paper) t $NS run --source $REPLICA --priors oracle --preset paper --max-frames 10 --max-side 320 --render-every 100 --out $OUT/run10_paper ;;
  frontend)  # issue 17: the Replica run with the classical frontend (seed 0), and the frontend alone
             mkdir -p $OUT
             printf '[tracking]\nfrontend = "classical"\n' > $OUT/frontend.toml
             printf '[tracking]\nfrontend = "classical"\niters = 0\n' > $OUT/frontend_only.toml
             t $NS run --source $REPLICA --priors oracle --preset fast --config $OUT/frontend.toml --out $OUT/run_frontend
             t $NS run --source $REPLICA --priors oracle --preset fast --config $OUT/frontend_only.toml --out $OUT/run_frontend_only ;;
  street)    # issue 17: the synthetic street, 100 frames, without priors, frontend on (PRIORS= to change)
             mkdir -p $OUT && printf '[tracking]\nfrontend = "classical"\n' > $OUT/frontend.toml
             t $NS run --source "synthetic:street?frames=100" --priors ${PRIORS:-none} --preset fast --config $OUT/frontend.toml --out $OUT/run_street_${PRIORS:-none} ;;
  kitti)     # the real KITTI drive (51 grey frames, 51.8 m) with the default priors (stereo here), the
             # map at `fast`'s 320 px and the frontend on the 1241 px image, seeds 0 1 2 (CONFIG= a toml
             # to add; SIDE=640 for a 640 px map; docs/priors.md, stops 42-43)
             seed_runs kitti_${SIDE:-320} "tum:../shared/data/kitti_gray_seq2_51f" auto "${CONFIG:-}" --max-side ${SIDE:-320} ;;
  jump)      # issue 17: 5 frames removed from the middle of the Replica clip (CONFIG= a toml to add;
             # SOURCE=synthetic:room?frames=40 DROP=18:23 for the demo room)
             t $NS run --source "${SOURCE:-$REPLICA}" --priors oracle --preset fast --drop "${DROP:-8:13}" ${CONFIG:+--config $CONFIG} --out $OUT/run_jump ;;
  run-synth) t $NS run --source "synthetic:room?frames=100" --priors oracle --preset fast --out $OUT/run_synth ;;
  async)     # issue 15: the Replica run with --sync, then with mapping on its worker thread (PRIORS=, default oracle:clean)
             mkdir -p $OUT
             t $NS run --source $REPLICA --priors ${PRIORS:-oracle:clean} --preset fast --sync --out $OUT/runtime_sync
             t $NS run --source $REPLICA --priors ${PRIORS:-oracle:clean} --preset fast --mapping-worker on --out $OUT/runtime_async
             .venv/bin/python scripts/runtime_table.py $OUT/runtime_sync $OUT/runtime_async ;;
  batch)     # issue 18: three synthetic logs (a cheap config) sequentially in-process (--local), then on a local
             # Ray instance (one CPU per run: two at a time on 2 cores)
             mkdir -p $OUT
             printf 'max_side = 160\n[mapping]\niters = 20\nfirst_iters = 60\nfinal_iters = 20\n[tracking]\niters = 10\n' > $OUT/batch_cheap.toml
             srcs=("synthetic:room?frames=15" "synthetic:tabletop?frames=15" "synthetic:room?frames=15&seed=1")
             t $NS batch "${srcs[@]}" --out $OUT/batch_local --local --force --config $OUT/batch_cheap.toml --priors oracle:clean
             t $NS batch "${srcs[@]}" --out $OUT/batch_ray --force --config $OUT/batch_cheap.toml --priors oracle:clean ;;
  memory)    # issue 15: RSS at frames 250 / 500 / 1000 of a cheap 1,000-frame run, with the keyframe cap and without
             .venv/bin/python scripts/memory_bench.py --out $OUT/mem_capped
             .venv/bin/python scripts/memory_bench.py --out $OUT/mem_uncapped --mapping-extra 'full_res_keyframes = 0' ;;
  iters)     # per-iteration costs (mapping, tracking) with FLOPs, sgemm and each kind of op against the CPU's limits: BASE's code at fast sizes
             # (needs the worktree of `speedup`), then this tree at fast and paper sizes
             wt=$(realpath "$OUT")/base_worktree
             [ -e "$wt/.git" ] && PYTHONPATH=$wt .venv/bin/python scripts/iter_bench.py --presets fast --iters 10 --floor
             .venv/bin/python scripts/iter_bench.py --presets fast,paper --iters 10 --profile --floor ;;
  ab)        # BASE's code (default HEAD~1, a worktree in OUTROOT/ab_worktree) and this tree alternated ROUNDS (2) times:
             # per-iteration costs at fast sizes, then one render and the mesh of RUN (a finished run's OUT)
             base=$(git rev-parse --verify "${BASE:-HEAD~1}^{commit}") && mkdir -p "$OUT" && wt=$(realpath "$OUT")/ab_worktree root=$PWD
             [ -e "$wt/.git" ] || git worktree add -q --detach "$wt" "$base"
             git -C "$wt" checkout -q --detach "$base"
             ln -sfn "$(realpath ../shared)" "$(dirname "$wt")/shared"  # the scripts' ../shared/data from the worktree
             for round in $(seq "${ROUNDS:-2}"); do
               for tree in "$wt" "$PWD"; do
                 echo "== round $round: $(git -C "$tree" rev-parse --short HEAD)$([ "$tree" = "$PWD" ] && [ -n "$(git status --porcelain)" ] && echo +edits)"
                 kernel_cache "$tree"
                 (cd "$tree" && PYTHONPATH="$tree" "$root/.venv/bin/python" scripts/iter_bench.py --presets fast --iters 10 | tail -1)
                 if [ -n "${RUN:-}" ]; then
                   (cd "$tree" && PYTHONPATH="$tree" "$root/.venv/bin/python" "$root/scripts/output_bench.py" "$root/$RUN")
                 fi
               done
             done ;;
  speedup)   BASE=${BASE:-c64946b}
             base=$(git rev-parse --verify "$BASE^{commit}")
             mkdir -p "$OUT" && out=$(realpath "$OUT") && wt=$out/base_worktree
             if [ -e "$wt/.git" ]; then
               [ "$(git -C "$wt" rev-parse HEAD)" = "$base" ] || git -C "$wt" checkout -q --detach "$base"
             else
               git worktree add -q --detach "$wt" "$base"
             fi
             # The baseline's `oracle` is what this tree calls `oracle:clean` (near-GT priors, GT flow).
             speedup_run "$wt" "$out/speedup_base" oracle
             new=$(git rev-parse --short HEAD)$([ -z "$(git status --porcelain)" ] || echo +edits)
             speedup_run "$PWD" "$out/speedup_new" oracle:clean "${NEW_EXTRA:-}"
             .venv/bin/python scripts/speedup_table.py "$out/speedup_base" "$out/speedup_new" \
               --labels "$(git rev-parse --short "$base")" "$new" ;;
  *) echo "usage: [BASE=commit] [EXTRA=args] $0 map|map-none|map-paper|map-synth|run|run-seeds|seeds|run-none|run10|run10-paper|run-synth|flow|speedup|iters|memory [OUTROOT]"; exit 2 ;;
esac
