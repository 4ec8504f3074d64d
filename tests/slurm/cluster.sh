#!/usr/bin/env bash
# A one-node Slurm cluster on this machine, for tests/slurm.rs (and for trying deploy/slurm/ by
# hand): its own munge daemon and key, slurmctld and slurmd, all under DIR, on the given ports.
#
#   tests/slurm/cluster.sh up DIR CTLD_PORT SLURMD_PORT   # then: export SLURM_CONF=DIR/slurm.conf
#   tests/slurm/cluster.sh down DIR
#
# Needs Debian's slurm-wlm and munge (`apt-get install slurm-wlm munge`; .ci/run installs them)
# and root, as slurmd starts jobs as their user. Both daemons are addressed on loopback, so the
# machine's name need not resolve.
set -euo pipefail

usage() { echo "usage: $0 up DIR CTLD_PORT SLURMD_PORT | down DIR" >&2; exit 2; }
[ $# -ge 2 ] || usage
verb=$1
dir=$(realpath -m "$2")

up() {
    local ctld_port=$1 slurmd_port=$2
    for tool in munged slurmctld slurmd sbatch sinfo scontrol; do
        command -v "$tool" >/dev/null || { echo "$0: $tool not found: apt-get install slurm-wlm munge" >&2; exit 1; }
    done
    mkdir -p "$dir/state" "$dir/spool" "$dir/log"
    head -c 1024 /dev/urandom >"$dir/munge.key"
    chmod 600 "$dir/munge.key"
    # --force: munged refuses to run as root without it.
    munged --force --key-file="$dir/munge.key" --socket="$dir/munge.sock" --pid-file="$dir/munged.pid" \
        --log-file="$dir/log/munged.log" --seed-file="$dir/munge.seed"
    local host mem
    host=$(hostname -s)
    mem=$(awk '/MemTotal/ { print int($2 / 1024 / 2) }' /proc/meminfo)
    cat >"$dir/slurm.conf" <<CONF
ClusterName=marvin-test
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$dir/munge.sock
SlurmUser=root
SlurmdUser=root
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SchedulerType=sched/backfill
JobCompType=jobcomp/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
MpiDefault=none
ReturnToService=2
NodeName=$host NodeAddr=127.0.0.1 CPUs=$(nproc) RealMemory=$mem State=UNKNOWN
PartitionName=test Nodes=ALL Default=YES MaxTime=INFINITE State=UP
CONF
    export SLURM_CONF=$dir/slurm.conf
    # -i: ignore any state a cluster of this name left.
    slurmctld -i -f "$SLURM_CONF"
    slurmd -f "$SLURM_CONF"
    for _ in $(seq 1 120); do
        if [ "$(sinfo -h -o %T 2>/dev/null)" = idle ]; then
            echo "$SLURM_CONF"
            return 0
        fi
        sleep 0.5
    done
    echo "$0: the node did not come up in 60 s; logs in $dir/log:" >&2
    tail -n 20 "$dir"/log/*.log >&2 || true
    down
    exit 1
}

down() {
    export SLURM_CONF=$dir/slurm.conf
    scontrol shutdown >/dev/null 2>&1 || true
    for pidfile in slurmd.pid slurmctld.pid munged.pid; do
        local pid
        pid=$(cat "$dir/$pidfile" 2>/dev/null) || continue
        kill "$pid" 2>/dev/null || true
        for _ in $(seq 1 50); do
            kill -0 "$pid" 2>/dev/null || break
            sleep 0.1
        done
        kill -9 "$pid" 2>/dev/null || true
    done
}

case $verb in
    up) [ $# -eq 4 ] || usage; up "$3" "$4" ;;
    down) down ;;
    *) usage ;;
esac
