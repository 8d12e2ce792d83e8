#!/usr/bin/env bash
# Time to 1 % relative standard error in every IPRT A6 direction (iprt_a6.toml), forward and
# backward walks (BENCHMARKS.md, "BRDF importance sampling (issue 14)").
#
# Usage: tools/bench_a6/bench.sh [SIMULATE [THREADS [METHODS [SPP]]]]
#   SIMULATE: the binary (default target/release/simulate); THREADS: -j (default 2);
#   METHODS: "forward backward" (default); SPP: if given, a fixed number of samples per
#   direction instead of the 1 % target (for runs that would take hours), and the time to 1 %
#   is extrapolated as wall × (max_rel / 1 %)² (standard errors fall as 1/√N).
# Prints per method: wall and user CPU seconds, samples per direction, the largest relative
# standard error of I over the 208 directions and where it is, and the (extrapolated) time to 1 %.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
sim="${1:-target/release/simulate}"
threads="${2:-2}"
methods="${3:-forward backward}"
spp="${4:-}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
printf '%-9s %8s %8s %10s %9s %-16s %10s\n' method wall_s user_s samples max_rel "worst (vza,vaa)" t_1pct_s
for m in $methods; do
    sed "s/^type = \"backward\"$/type = \"$m\"/" "$here/iprt_a6.toml" >"$work/a6_$m.toml"
    if [ -n "$spp" ]; then
        sed -i "s/^spp = .*/spp = $spp/; /^target_rel_stderr/d" "$work/a6_$m.toml"
    fi
    /usr/bin/time -f "%e %U" -o "$work/time" "$sim" run "$work/a6_$m.toml" -o "$work/out_$m" \
        -j "$threads" -q --fresh >/dev/null 2>"$work/log"
    read -r wall user <"$work/time"
    python3 - "$work/out_$m/results.csv" "$m" "$wall" "$user" <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
worst = max(rows, key=lambda r: float(r["brf_stderr"]) / abs(float(r["brf"])))
rel = float(worst["brf_stderr"]) / abs(float(worst["brf"]))
n = max(int(r["n_samples"]) for r in rows)
wall, user = float(sys.argv[3]), float(sys.argv[4])
where = f"({float(worst['vza']):.0f}, {float(worst['vaa']):.0f})"
t1 = wall * max(rel / 0.01, 0.0) ** 2
print(f"{sys.argv[2]:<9} {wall:8.2f} {user:8.2f} {n:10d} {rel:9.3%} {where:<16} {t1:10.1f}")
PY
done
