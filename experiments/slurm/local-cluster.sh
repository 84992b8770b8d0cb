#!/usr/bin/env bash
# A one-node Slurm cluster on this machine, for testing the job scripts with the real
# scheduler (Debian's slurm-wlm, 22.05 on Debian 12). Needs root.
#
#   experiments/slurm/local-cluster.sh up       # install slurm-wlm + munge if missing, write the
#                                                # config, start munged, slurmctld, slurmd; wait until idle
#   eval "$(experiments/slurm/local-cluster.sh env)"   # SLURM_CONF for sbatch/squeue/scontrol
#   experiments/slurm/local-cluster.sh status
#   experiments/slurm/local-cluster.sh down     # cancel jobs, stop every daemon it started
#
# Everything lives under $PHOTONLAB_SLURM_DIR (default /tmp/photonlab-slurm): config,
# munge key and socket, spool, state, logs, pid files. Nothing under /etc is changed,
# so the machine's own Slurm (if any) is untouched; the ports are
# $PHOTONLAB_SLURM_PORT and +1 (default 6817, 6818). The node offers
# $PHOTONLAB_SLURM_CPUS task slots (default 4; more than the cores is fine: the
# config overrides the hardware count), scheduled per CPU (select/cons_tres, CR_CPU).
# Process tracking without cgroups (proctrack/linuxproc, task/none), so it runs in
# containers and VMs without systemd.
set -euo pipefail

D=${PHOTONLAB_SLURM_DIR:-/tmp/photonlab-slurm}
PORT=${PHOTONLAB_SLURM_PORT:-6817}
CPUS=${PHOTONLAB_SLURM_CPUS:-4}
CONF=$D/etc/slurm.conf
SOCK=$D/munge/munge.socket.2
HOST=$(hostname -s)

die() { echo "local-cluster: $*" >&2; exit 1; }
say() { echo "local-cluster: $*" >&2; }

install_if_missing() {
    if command -v slurmctld >/dev/null && command -v slurmd >/dev/null && command -v munged >/dev/null && command -v sbatch >/dev/null; then
        return
    fi
    command -v apt-get >/dev/null || die "slurm-wlm and munge are not installed and there is no apt-get to install them"
    [[ $(id -u) == 0 ]] || die "slurm-wlm and munge are not installed; installing them needs root"
    say "installing slurm-wlm and munge (apt-get)"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq >&2 || die "apt-get update failed"
    apt-get install -y -qq slurm-wlm munge >&2 || die "apt-get install slurm-wlm munge failed"
}

# Processes started by this script (marked in their environment) or running a job of
# this cluster: the only ones `down` stops.
our_pids() {
    local p env
    for p in /proc/[0-9]*; do
        p=${p#/proc/}
        [[ $p == "$$" ]] && continue
        env=$( { tr '\0' '\n' <"/proc/$p/environ"; } 2>/dev/null) || continue
        if grep -qxF "PHOTONLAB_LOCAL_SLURM=$D" <<<"$env" \
            || { grep -qxF "SLURM_CONF=$CONF" <<<"$env" && grep -q '^SLURM_JOB_ID=' <<<"$env"; }; then
            echo "$p"
        fi
    done
}

# Alive and not a zombie (a zombie waits for its parent, it runs nothing).
running() {
    local st
    st=$( { sed 's/.*) //' "/proc/$1/stat" | cut -d' ' -f1; } 2>/dev/null) || return 1
    [[ -n $st && $st != Z ]]
}

write_config() {
    mkdir -p "$D"/{etc,munge,log,state/ctld,state/d,run}
    chmod 700 "$D/munge"
    if [[ ! -s $D/munge/munge.key ]]; then
        dd if=/dev/urandom of="$D/munge/munge.key" bs=1024 count=1 status=none
        chmod 400 "$D/munge/munge.key"
    fi
    local mem
    mem=$(awk '/MemTotal/ { printf "%d", $2 / 1024 * 0.8 }' /proc/meminfo)
    cat >"$CONF" <<EOF
# Written by experiments/slurm/local-cluster.sh: a one-node test cluster.
ClusterName=photonlab
SlurmctldHost=$HOST(127.0.0.1)
SlurmctldPort=$PORT
SlurmdPort=$((PORT + 1))
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
# cred_expire: how long a requeued job waits before it may start again (default 120 s).
AuthInfo=socket=$SOCK,cred_expire=10
StateSaveLocation=$D/state/ctld
SlurmdSpoolDir=$D/state/d
SlurmctldPidFile=$D/run/slurmctld.pid
SlurmdPidFile=$D/run/slurmd.pid
SlurmctldLogFile=$D/log/slurmctld.log
SlurmdLogFile=$D/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SchedulerType=sched/backfill
SlurmdParameters=config_overrides
ReturnToService=2
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MpiDefault=none
MinJobAge=600
KillWait=5
InactiveLimit=0
SlurmdTimeout=60
NodeName=$HOST NodeAddr=127.0.0.1 CPUs=$CPUS RealMemory=$mem State=UNKNOWN
PartitionName=main Nodes=$HOST Default=YES MaxTime=INFINITE State=UP
EOF
}

wait_idle() {
    local i state
    for i in $(seq 1 60); do
        state=$(SLURM_CONF=$CONF sinfo -h -n "$HOST" -o %T 2>/dev/null | head -1 || true)
        case $state in
            idle*|mixed*|allocated*) return 0 ;;
            drain*|down*|fail*)
                SLURM_CONF=$CONF scontrol update nodename="$HOST" state=resume >/dev/null 2>&1 || true ;;
        esac
        sleep 1
    done
    say "the node did not become idle (state: ${state:-none}); logs:"
    tail -n 20 "$D/log/slurmctld.log" "$D/log/slurmd.log" "$D/log/munged.log" >&2 2>/dev/null || true
    return 1
}

up() {
    install_if_missing
    [[ $(id -u) == 0 ]] || die "starting munged, slurmctld and slurmd as configured here needs root"
    if [[ -n $(our_pids) ]]; then
        say "already running (pids $(our_pids | tr '\n' ' ')); run down first to restart"
        wait_idle || die "cluster in $D is running but not usable"
        return
    fi
    write_config
    export PHOTONLAB_LOCAL_SLURM=$D SLURM_CONF=$CONF
    munged --force --socket="$SOCK" --key-file="$D/munge/munge.key" --pid-file="$D/run/munged.pid" \
        --log-file="$D/log/munged.log" --seed-file="$D/munge/munged.seed" \
        || die "munged did not start; see $D/log/munged.log"
    munge --socket="$SOCK" -n </dev/null | unmunge --socket="$SOCK" >/dev/null || die "munge credentials do not round-trip"
    slurmctld -f "$CONF" || die "slurmctld did not start; see $D/log/slurmctld.log"
    slurmd -f "$CONF" || die "slurmd did not start; see $D/log/slurmd.log"
    if ! wait_idle; then
        down
        die "Slurm did not come up"
    fi
    say "up: one node ($HOST, $CPUS task slots), partition main; SLURM_CONF=$CONF"
}

down() {
    export SLURM_CONF=$CONF
    if [[ -f $CONF ]] && command -v squeue >/dev/null; then
        local jobs
        jobs=$(squeue -h -o %A 2>/dev/null | sort -u | tr '\n' ' ' || true)
        if [[ -n ${jobs// /} ]]; then
            say "cancelling jobs $jobs"
            # shellcheck disable=SC2086
            scancel $jobs 2>/dev/null || true
            for _ in $(seq 1 20); do
                [[ -z $(squeue -h -o %A 2>/dev/null || true) ]] && break
                sleep 1
            done
        fi
    fi
    local f pid pids alive
    pids=$(our_pids | tr '\n' ' ')
    for f in slurmd slurmctld munged; do
        pid=$(cat "$D/run/$f.pid" 2>/dev/null || true)
        # Only the daemon itself: a stale pid file may name a reused pid.
        if [[ -n $pid && $(cat "/proc/$pid/comm" 2>/dev/null) == "$f" ]]; then
            pids="$pids $pid"
            kill "$pid" 2>/dev/null || true
        fi
    done
    # Wait until every process seen before is gone (an exiting process's environ is
    # no longer readable, so look at the pids themselves).
    for _ in $(seq 1 40); do
        alive=
        for pid in $pids; do if running "$pid"; then alive="$alive $pid"; fi; done
        [[ -z $alive && -z $(our_pids) ]] && break
        sleep 0.5
    done
    alive=$(for pid in $pids $(our_pids); do if running "$pid"; then echo "$pid"; fi; done | sort -u | tr '\n' ' ')
    if [[ -n ${alive// /} ]]; then
        say "killing leftover processes $alive"
        # shellcheck disable=SC2086
        kill -9 $alive 2>/dev/null || true
        sleep 1
    fi
    rm -f "$D"/run/*.pid
    alive=$(for pid in $pids $(our_pids); do if running "$pid"; then echo "$pid"; fi; done | sort -u | tr '\n' ' ')
    [[ -z ${alive// /} ]] || die "processes still running: $alive"
    say "down: nothing of the cluster in $D is running"
}

case ${1:-} in
    up) up ;;
    down) down ;;
    env) echo "export SLURM_CONF=$CONF" ;;
    status)
        export SLURM_CONF=$CONF
        echo "processes: $(our_pids | tr '\n' ' ')"
        sinfo 2>&1 || true
        squeue 2>&1 || true ;;
    *) die "usage: $0 up|down|env|status" ;;
esac
