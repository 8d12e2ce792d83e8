#!/usr/bin/env bash
# A one-node Slurm cluster on this machine, for the tests (tests/slurm.rs, tests/slurm/run.sh).
#
#   source tests/slurm/cluster.sh; cluster_start DIR; ...; cluster_stop
#
# cluster_start writes DIR/slurm.conf (one node, "localnode", 2 CPUs unless SLURM_TEST_CPUS;
# no cgroups: proctrack/linuxproc, task/none, no accounting), starts munged with its own key and
# socket in DIR, then slurmctld and slurmd (as root: every state and spool folder is under DIR),
# exports SLURM_CONF so that sbatch, squeue and sacct... find it, and waits until the node is idle.
# Any step that fails prints the reason with the tail of the daemon's log and returns 1.
# cluster_stop cancels the jobs still queued, then ends the three daemons it started (by their
# pid files).

cluster_fail() {
    echo "slurm test cluster: $1" >&2
    if [ -n "${2:-}" ] && [ -f "$2" ]; then
        echo "--- last lines of $2:" >&2
        tail -n 20 "$2" >&2
    fi
    return 1
}

cluster_start() {
    local dir="$1"
    for c in munged slurmctld slurmd sbatch squeue scontrol sinfo; do
        command -v "$c" >/dev/null 2>&1 ||
            { cluster_fail "$c not found: install Debian's slurm-wlm and munge (bash scripts/setup.sh)"; return 1; }
    done
    [ "$(id -u)" -eq 0 ] ||
        { cluster_fail "the daemons must run as root here (SlurmdUser=root); run as root"; return 1; }
    mkdir -p "$dir"/{munge,state,spool,log}
    chmod 700 "$dir" "$dir/munge"
    CLUSTER_DIR="$(cd "$dir" && pwd)"
    dir="$CLUSTER_DIR"

    # munge: a fresh key and a private socket (no system munged needed).
    dd if=/dev/urandom of="$dir/munge/munge.key" bs=1024 count=1 status=none
    chmod 400 "$dir/munge/munge.key"
    munged --force --key-file="$dir/munge/munge.key" --socket="$dir/munge/socket" \
        --pid-file="$dir/munge/munged.pid" --log-file="$dir/log/munged.log" \
        --seed-file="$dir/munge/seed" ||
        { cluster_fail "munged did not start" "$dir/log/munged.log"; return 1; }

    # Ports: one pair per run, so that two test runs on one machine do not collide.
    local base=$((20000 + ($$ % 20000) * 2))
    local cpus="${SLURM_TEST_CPUS:-2}"
    local mem=$(($(awk '/MemTotal/ {print $2}' /proc/meminfo) / 1024 / 2))
    cat >"$dir/slurm.conf" <<CONF
ClusterName=testcluster
SlurmctldHost=localhost(127.0.0.1)
SlurmctldPort=$base
SlurmdPort=$((base + 1))
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$dir/munge/socket
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
SchedulerType=sched/builtin
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
MpiDefault=none
ReturnToService=2
SlurmctldTimeout=30
SlurmdTimeout=30
MailProg=/bin/true
MinJobAge=600
NodeName=localnode NodeHostname=$(hostname) NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=test Nodes=localnode Default=YES MaxTime=INFINITE State=UP
CONF
    export SLURM_CONF="$dir/slurm.conf"

    slurmctld -f "$SLURM_CONF" -c -i ||
        { cluster_fail "slurmctld did not start" "$dir/log/slurmctld.log"; return 1; }
    slurmd -f "$SLURM_CONF" -N localnode ||
        { cluster_fail "slurmd did not start" "$dir/log/slurmd.log"; return 1; }

    local state=""
    for _ in $(seq 1 60); do
        state=$(sinfo -h -n localnode -o %t 2>/dev/null || true)
        case "$state" in
            idle | mix | alloc) return 0 ;;
        esac
        sleep 1
    done
    cluster_fail "node localnode is not up after 60 s (state: '${state:-no answer}')" "$dir/log/slurmd.log"
    tail -n 20 "$dir/log/slurmctld.log" >&2
    return 1
}

cluster_stop() {
    local dir="${CLUSTER_DIR:-}"
    [ -n "$dir" ] || return 0
    # Cancel what is still queued or running, and let slurmd reap it, before the daemons go.
    if [ -f "$dir/slurmctld.pid" ] && kill -0 "$(cat "$dir/slurmctld.pid")" 2>/dev/null; then
        scancel --quiet --user="$(id -un)" 2>/dev/null || true
        for _ in $(seq 1 50); do
            [ -z "$(squeue -h 2>/dev/null)" ] && break
            sleep 0.2
        done
    fi
    for f in slurmd.pid slurmctld.pid munge/munged.pid; do
        if [ -f "$dir/$f" ]; then
            local pid
            pid=$(cat "$dir/$f")
            kill "$pid" 2>/dev/null || true
            for _ in $(seq 1 20); do kill -0 "$pid" 2>/dev/null || break; sleep 0.25; done
            kill -9 "$pid" 2>/dev/null || true
        fi
    done
}
