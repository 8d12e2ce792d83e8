#!/usr/bin/env bash
# Measured cost of each shard of a plan (docs/scaling.md): plans EXPERIMENT into OUT with
# `simulate plan --shards N`, runs every array task of OUT/job.sh one after the other on this
# machine (no Slurm needed: SLURM_ARRAY_TASK_ID and SLURM_CPUS_PER_TASK are set by hand) under
# /usr/bin/time -v, then `simulate merge OUT`; prints one line per shard and one for the merge:
# wall time, CPU time (user + system) and peak resident memory.
#
#   scripts/shard_costs.sh EXPERIMENT N OUT [CPUS] [extra `simulate plan` options, e.g. --spp 32]
set -euo pipefail
exp="$1" n="$2" out="$3" cpus="${4:-2}"
shift 3
[ $# -gt 0 ] && shift
sim="$(cd "$(dirname "$0")/.." && pwd)/target/release/simulate"
[ -x "$sim" ] || { echo "build first: cargo build --release --bins" >&2; exit 1; }
[ -x /usr/bin/time ] || { echo "/usr/bin/time not found (Debian package: time)" >&2; exit 1; }
"$sim" -q plan "$exp" --shards "$n" -o "$out" --cpus-per-task "$cpus" "$@"
measure() { # label, log, command...
    local label="$1" log="$2"
    shift 2
    /usr/bin/time -v "$@" >"$log" 2>&1 || { tail -n 30 "$log" >&2; echo "$label failed" >&2; exit 1; }
    awk -v l="$label" -F': ' '/Elapsed \(wall clock\)/ { w = $2 } /Maximum resident/ { r = $2 }
        /User time/ { u = $2 } /System time/ { y = $2 }
        END { printf "%-10s wall %s, CPU %.1f s, peak RSS %.0f MiB\n", l, w, u + y, r / 1024 }' "$log"
}
for k in $(seq 0 $((n - 1))); do
    SLURM_ARRAY_TASK_ID=$k SLURM_CPUS_PER_TASK=$cpus measure "shard $k" "$out/logs/shard_$k.log" bash "$out/job.sh"
done
measure "merge" "$out/logs/merge.log" "$sim" merge "$out"
