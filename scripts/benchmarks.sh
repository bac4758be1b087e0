#!/usr/bin/env bash
# The measurements named in the issues (long: run one at a time on a 2-core CPU).
# Usage: scripts/benchmarks.sh [map|map-none|map-paper|map-synth|run|run-seeds|run-none|run-synth|run10|run10-paper|flow] [OUTROOT]
# Tables: .venv/bin/python scripts/eval_table.py OUT... [--reference OUTROOT/map_oracle]
# run10-paper needs hours here: Ctrl-C writes what was computed (trajectory so far, mesh, eval).
set -euo pipefail
cd "$(dirname "$0")/.."
NS=.venv/bin/nicer-stream
REPLICA=replica:../shared/data/replica_room0_20f
OUT=${2:-runs/bench}
t() { /usr/bin/time -f "wall %e s, peak RSS %M KB" "$@"; }
case "${1:-all}" in
  map)       t $NS map --source $REPLICA --poses gt --priors oracle --preset fast --out $OUT/map_oracle ;;
  map-none)  t $NS map --source $REPLICA --poses gt --priors none --preset fast --out $OUT/map_none ;;
  map-paper) t $NS map --source $REPLICA --poses gt --priors oracle --preset paper --minutes 15 --max-side 320 --render-every 20 --out $OUT/map_paper320 ;;
  flow)      .venv/bin/python scripts/flow_benchmark.py ;;
  map-synth) t $NS map --source "synthetic:room?frames=60" --poses gt --priors oracle --preset fast --out $OUT/map_synth ;;
  run)       t $NS run --source $REPLICA --priors oracle --preset fast --out $OUT/run_oracle ;;
  run-seeds) # the Replica run for seeds 0 1 2 (results vary run to run: judge a change by the spread)
             mkdir -p $OUT
             for s in 0 1 2; do
               echo "seed = $s" > $OUT/seed$s.toml
               t $NS run --source $REPLICA --priors oracle --preset fast --config $OUT/seed$s.toml --out $OUT/run_seed$s
             done
             ref=(); [ -f $OUT/map_oracle/eval.json ] && ref=(--reference $OUT/map_oracle)
             .venv/bin/python scripts/eval_table.py $OUT/run_seed0 $OUT/run_seed1 $OUT/run_seed2 "${ref[@]}" ;;
  run-none)  t $NS run --source $REPLICA --priors none --preset fast --out $OUT/run_none ;;
  run10)     t $NS run --source $REPLICA --priors oracle --preset fast --max-frames 10 --out $OUT/run10_fast ;;
  run10-paper) t $NS run --source $REPLICA --priors oracle --preset paper --max-frames 10 --max-side 320 --render-every 100 --out $OUT/run10_paper ;;
  run-synth) t $NS run --source "synthetic:room?frames=100" --priors oracle --preset fast --out $OUT/run_synth ;;
  *) echo "usage: $0 map|map-none|map-paper|map-synth|run|run-seeds|run-none|run10|run10-paper|run-synth|flow [OUTROOT]"; exit 2 ;;
esac
