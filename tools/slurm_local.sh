#!/usr/bin/env bash
# A single-node Slurm cluster on localhost, for the farm tests and for trying `wavetrace slurm`
# on one machine: munge and Slurm's two daemons started as root without systemd, every file in
# one scratch folder.
#
#   tools/slurm_local.sh start [DIR]   starts munged, slurmctld and slurmd; prints the
#                                      `export SLURM_CONF=...` line that sbatch/squeue need
#   tools/slurm_local.sh stop [DIR]    stops them (by their pid files)
#
# DIR defaults to ${TMPDIR:-/tmp}/wavetrace-slurm. Needs root and Debian's `slurm-wlm` and
# `munge` packages (`apt-get install -y slurm-wlm munge`).
set -euo pipefail
action="${1:-}"
dir="${2:-${TMPDIR:-/tmp}/wavetrace-slurm}"

stop_cluster() {
    for name in slurmd slurmctld munged; do
        pidfile="$dir/$name.pid"
        if [ -f "$pidfile" ]; then
            pid="$(cat "$pidfile")"
            kill "$pid" 2>/dev/null || true
            for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
            rm -f "$pidfile"
        fi
    done
}

case "$action" in
start)
    for tool in munged slurmctld slurmd sbatch; do
        command -v "$tool" >/dev/null || { echo "error: $tool not found; apt-get install -y slurm-wlm munge" >&2; exit 1; }
    done
    [ "$(id -u)" = 0 ] || { echo "error: the local cluster starts as root" >&2; exit 1; }
    stop_cluster
    mkdir -p "$dir/munge" "$dir/spool/ctld" "$dir/spool/d" "$dir/log"
    chmod 755 "$dir" "$dir/munge"
    [ -f "$dir/munge/munge.key" ] || dd if=/dev/urandom of="$dir/munge/munge.key" bs=1024 count=1 status=none
    chmod 400 "$dir/munge/munge.key"
    munged --force --key-file="$dir/munge/munge.key" --socket="$dir/munge/munge.socket" \
        --pid-file="$dir/munged.pid" --log-file="$dir/log/munged.log" --seed-file="$dir/munge/seed"
    cpus="$(nproc)"
    mem_mib="$(awk '/MemTotal/ { printf "%d", $2 / 1024 * 0.9 }' /proc/meminfo)"
    cat > "$dir/slurm.conf" <<CONF
ClusterName=wavetrace-local
SlurmctldHost=localhost
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$dir/munge/munge.socket
MpiDefault=none
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerType=sched/backfill
SchedulerParameters=sched_interval=1
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
JobCompType=jobcomp/none
ReturnToService=2
StateSaveLocation=$dir/spool/ctld
SlurmdSpoolDir=$dir/spool/d
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
SlurmctldPort=16817
SlurmdPort=16818
MinJobAge=300
NodeName=localhost NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$mem_mib State=UNKNOWN
PartitionName=local Nodes=localhost Default=YES MaxTime=INFINITE State=UP OverSubscribe=NO
CONF
    export SLURM_CONF="$dir/slurm.conf"
    slurmctld -i
    slurmd -N localhost
    for _ in $(seq 100); do
        if sinfo -h -o %T 2>/dev/null | grep -qE '^(idle|mixed|allocated)'; then
            echo "export SLURM_CONF=$dir/slurm.conf"
            exit 0
        fi
        sleep 0.1
    done
    echo "error: the local Slurm cluster did not come up; see $dir/log" >&2
    sinfo >&2 || true
    exit 1
    ;;
stop)
    stop_cluster
    ;;
*)
    echo "usage: $0 start|stop [DIR]" >&2
    exit 2
    ;;
esac
