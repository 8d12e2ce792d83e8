#!/usr/bin/env bash
# The Slurm test (issue 19; run by tests/slurm.rs, so by `cargo test --release --workspace`):
# the Grenoble ortho render split over a real, one-node Slurm and merged, compared byte for byte
# with an unsplit local run; then one array task is cancelled while it runs, `simulate merge`
# must name it, and re-running that task alone must recover the same products.
#
#   tests/slurm/run.sh SIMULATE SCENEGEN REPO SHARED WORK
#
# SIMULATE, SCENEGEN: the release binaries; REPO: the repository; SHARED: the shared data folder
# (its data/ holds the Copernicus DEM the Grenoble region reads); WORK: an empty temporary
# folder. Needs root, Debian's slurm-wlm and munge (scripts/setup.sh installs them). Exits 1
# with the reason on the first failure; the daemons are stopped on exit.
set -euo pipefail

SIMULATE="$1" SCENEGEN="$2" REPO="$3" SHARED="$4" WORK="$5"
SPP="${SLURM_TEST_SPP:-16}"
SHARDS=4

fail() {
    echo "slurm test FAILED: $*" >&2
    exit 1
}
step() { echo "slurm test: $*"; }
seconds() { date +%s.%N; }
since() { awk -v a="$1" -v b="$(seconds)" 'BEGIN { printf "%.1f", b - a }'; }

# shellcheck source=tests/slurm/cluster.sh
source "$REPO/tests/slurm/cluster.sh"
trap cluster_stop EXIT
trap 'echo "slurm test FAILED: command at line $LINENO of tests/slurm/run.sh exited $?" >&2' ERR

# The Grenoble example as in a fresh clone: T/repo/examples/grenoble beside T/shared.
mkdir -p "$WORK/repo/examples"
cp -r "$REPO/examples/grenoble" "$WORK/repo/examples/"
ln -s "$(cd "$SHARED" && pwd)" "$WORK/shared"
cd "$WORK/repo"
t=$(seconds)
"$SCENEGEN" -q build examples/grenoble/region.toml -o out/grenoble >"$WORK/build.log" 2>&1 ||
    { tail -n 20 "$WORK/build.log" >&2; fail "scenegen build of examples/grenoble/region.toml"; }
step "bundle built in $(since "$t") s"

t=$(seconds)
cluster_start "$WORK/cluster" || fail "Slurm did not start (reason above)"
step "one-node Slurm up in $(since "$t") s ($(sinfo -h -o '%n %c CPUs %t'))"

# The example renders to a target precision, which keeps each (wavelength, measure) whole; the
# same render at a fixed sample count is also cut into pixel tiles, which this test exercises.
sed '/^target_rel_stderr/d' examples/grenoble/render.toml >examples/grenoble/render_fixed.toml
EXP=examples/grenoble/render_fixed.toml
t=$(seconds)
"$SIMULATE" -q run "$EXP" -o out/local --spp "$SPP" >/dev/null || fail "local run"
step "unsplit local run (--spp $SPP) in $(since "$t") s"

# The products of a run: every plain file of its folder but checkpoints, shards, logs and the
# plan's own files.
products() { (cd "$1" && find . -maxdepth 1 -type f ! -name 'plan.toml' ! -name 'job.sh' ! -name '.*' | sort); }

same_as_local() {
    local dir="$1" ref="${2:-out/local}" n=0
    [ "$(products "$ref")" = "$(products "$dir")" ] ||
        fail "$dir holds other files than the local run: $(products "$dir" | tr '\n' ' ') vs $(products "$ref" | tr '\n' ' ')"
    for f in $(products "$ref"); do
        cmp "$ref/$f" "$dir/$f" || fail "$dir/$f differs from the unsplit run's ($ref)"
        n=$((n + 1))
    done
    [ "$n" -ge 5 ] || fail "only $n products to compare"
    step "$dir: all $n products equal the unsplit run's byte for byte"
}

# Wait until every task of job $1 has left the queue (at most $2 s).
wait_gone() {
    for _ in $(seq 1 $(($2 * 5))); do
        [ -z "$(squeue -h -j "$1" 2>/dev/null)" ] && return 0
        sleep 0.2
    done
    fail "job $1 still queued after $2 s: $(squeue -j "$1")"
}

# 1. Plan, submit, wait, merge, compare.
t=$(seconds)
"$SIMULATE" -q plan "$EXP" --shards "$SHARDS" -o out/plan --spp "$SPP" --cpus-per-task 1 ||
    fail "simulate plan"
grep -q "^#SBATCH --array=0-$((SHARDS - 1))$" out/plan/job.sh || fail "job.sh has no --array=0-$((SHARDS - 1))"
job=$(sbatch --parsable out/plan/job.sh) || fail "sbatch out/plan/job.sh"
step "planned and submitted job $job ($SHARDS array tasks)"
wait_gone "$job" 600
for k in $(seq 0 $((SHARDS - 1))); do
    [ "$(cat "out/plan/shards/$k/status" 2>/dev/null)" = 0 ] ||
        { cat "out/plan/logs/shard_$k.log" >&2 || true; fail "array task $k did not exit 0"; }
done
step "$SHARDS shards done in $(since "$t") s (plan, queue and runs)"
t=$(seconds)
"$SIMULATE" -q merge out/plan >/dev/null || fail "simulate merge out/plan"
step "merged in $(since "$t") s"
same_as_local out/plan

# 2. Cancel one task while it runs; merge must name it; re-run it alone; merge again. The
# example's three wavelengths share their walks (`spectral_walk = "alis"`), one unit per tile;
# walked independently they are three units per tile, so a shard stores a unit and then goes on
# to the next, and the cancel can fall between them.
KILL=2
sed 's/^spectral_walk.*/spectral_walk = "independent"/' "$EXP" >examples/grenoble/render_fixed_independent.toml
EXP=examples/grenoble/render_fixed_independent.toml
"$SIMULATE" -q run "$EXP" -o out/local_independent --spp "$SPP" >/dev/null || fail "local run (independent walks)"
"$SIMULATE" -q plan "$EXP" --shards "$SHARDS" -o out/plan_kill --spp "$SPP" --cpus-per-task 1 ||
    fail "simulate plan (second plan)"
job=$(sbatch --parsable out/plan_kill/job.sh) || fail "sbatch out/plan_kill/job.sh"
state=""
for _ in $(seq 1 1500); do
    state=$(squeue -h -j "${job}_$KILL" -o %T 2>/dev/null || true)
    [ "$state" = RUNNING ] && break
    sleep 0.1
done
[ "$state" = RUNNING ] || fail "array task $KILL of job $job never seen running (last state '${state:-gone}')"
# Cancel it once its first unit is stored (each shard has 3 units), so that the re-run must
# keep that unit and compute only the others.
ck="out/plan_kill/shards/$KILL/checkpoints"
first=""
for _ in $(seq 1 3000); do
    first=$(find "$ck" -maxdepth 1 -name '*.json' 2>/dev/null | head -n 1 || true)
    [ -n "$first" ] && break
    [ -f "out/plan_kill/shards/$KILL/status" ] && break
    sleep 0.02
done
scancel "${job}_$KILL" || fail "scancel ${job}_$KILL"
[ -n "$first" ] || fail "task $KILL stored no unit before it ended or within 60 s"
stamp=$(stat -c %Y.%y "$first")
step "cancelled array task ${job}_$KILL while it ran, after it stored $(basename "$first")"
wait_gone "$job" 600
[ ! -f "out/plan_kill/shards/$KILL/status" ] ||
    fail "task $KILL finished (status $(cat "out/plan_kill/shards/$KILL/status")) before it was cancelled; the recovery was not exercised"
if "$SIMULATE" -q merge out/plan_kill >"$WORK/merge.out" 2>"$WORK/merge.err"; then
    fail "simulate merge succeeded with task $KILL cancelled"
fi
grep -q "shard $KILL:" "$WORK/merge.err" || { cat "$WORK/merge.err" >&2; fail "merge did not name shard $KILL"; }
grep -q -- "--array=$KILL " "$WORK/merge.err" || { cat "$WORK/merge.err" >&2; fail "merge did not give the re-run command"; }
step "merge refused and named the cancelled shard: $(grep "shard $KILL:" "$WORK/merge.err" | sed 's/^ *//')"
t=$(seconds)
job=$(sbatch --parsable --array="$KILL" out/plan_kill/job.sh) || fail "sbatch --array=$KILL out/plan_kill/job.sh"
wait_gone "$job" 600
[ "$(cat "out/plan_kill/shards/$KILL/status" 2>/dev/null)" = 0 ] ||
    { cat "out/plan_kill/logs/shard_$KILL.log" >&2 || true; fail "the re-run of task $KILL did not exit 0"; }
step "task $KILL re-run alone in $(since "$t") s"
[ "$(stat -c %Y.%y "$first")" = "$stamp" ] || fail "the re-run rewrote $first instead of resuming from it"
step "the re-run kept the unit stored before the cancel ($(basename "$first")) and ran the others"
"$SIMULATE" -q merge out/plan_kill >/dev/null || fail "simulate merge out/plan_kill after the re-run"
same_as_local out/plan_kill out/local_independent
step "passed"
