#!/usr/bin/env bash
# Time to 1 % relative standard error in every IPRT A6 direction (iprt_a6.toml), forward and
# backward walks. Usage: tools/bench_a6/bench.sh [SIMULATE [THREADS [METHODS]]]
#   SIMULATE: the binary (default target/release/simulate), THREADS: -j (default 2),
#   METHODS: "forward backward" (default).
# Prints per method: wall and user CPU seconds, samples per direction, max relative stderr of I.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
sim="${1:-target/release/simulate}"
threads="${2:-2}"
methods="${3:-forward backward}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
printf '%-9s %8s %8s %12s %10s\n' method wall_s user_s samples max_rel
for m in $methods; do
    sed "s/^type = \"backward\"$/type = \"$m\"/" "$here/iprt_a6.toml" >"$work/a6_$m.toml"
    /usr/bin/time -f "%e %U" -o "$work/time" "$sim" run "$work/a6_$m.toml" -o "$work/out_$m" -j "$threads" -q --fresh >/dev/null 2>"$work/log"
    read -r wall user <"$work/time"
    python3 - "$work/out_$m/results.csv" "$m" "$wall" "$user" <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
rel = max(float(r["brf_stderr"]) / abs(float(r["brf"])) for r in rows)
n = max(int(r["n_samples"]) for r in rows)
print(f"{sys.argv[2]:<9} {float(sys.argv[3]):8.2f} {float(sys.argv[4]):8.2f} {n:12d} {rel:10.4%}")
PY
done
