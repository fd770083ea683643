#!/usr/bin/env bash
# A single-node SLURM on this machine, for trying and testing jobs/*.sbatch:
# munge, slurmctld and slurmd started directly (no systemd), one node with
# 2 CPUs in one partition `debug`, all addresses on loopback (127.0.0.1).
#
#   bash scripts/setup-slurm.sh install   Debian packages (slurmctld slurmd slurm-client munge)
#   bash scripts/setup-slurm.sh start     install, then start munged, slurmctld, slurmd (default)
#   bash scripts/setup-slurm.sh stop      stop the daemons this script started (munged too)
#   bash scripts/setup-slurm.sh status    exit 0 if the node answers and is usable
#   bash scripts/setup-slurm.sh env       print `export SLURM_CONF=...` for a shell to eval
#
# State (config, spool, logs, pid files) lives in $CORTEX_SLURM_DIR, by default
# /var/lib/cortex-slurm; $CORTEX_SLURM_CPUS sets the node's CPUs (default 2,
# at most what the machine has). The client commands (sbatch, squeue, ...)
# find the config through SLURM_CONF; where /etc/slurm/slurm.conf does not
# exist it is made a link to ours, so they also work without it.
#
# Idempotent: `start` on a running cluster is a no-op (unless it runs an older
# config than this script writes and no job is queued: then it is started
# again with this one), `stop` on a stopped one too; `start` and `stop` wait for each other (a lock in the state directory),
# so test sessions running at once start one cluster. A program that uses the
# cluster may hold a shared flock on $dir/sessions.lock; whoever wants to stop
# it should first take that lock exclusively (tests/test_slurm.py does both). Exit status 77 means "cannot be done here" (not root, no apt-get, or
# the packages cannot be installed), with the reason on stdout; the tests
# report that as a skip.
#
# Loopback only: the node, the controller and every client use 127.0.0.1.
# (slurmctld and slurmd have no bind-address setting; they accept only
# munge-authenticated requests signed with this machine's key.)
set -euo pipefail

dir=${CORTEX_SLURM_DIR:-/var/lib/cortex-slurm}
conf=$dir/slurm.conf
debs=(slurmctld slurmd slurm-client munge)

say() { echo "setup-slurm: $*"; }
cannot() { say "$*"; exit 77; }

need_root() {
    [[ $(id -u) == 0 ]] || cannot "must run as root to $1 (SLURM daemons and Debian packages); not done"
}

install() {
    local missing=() p
    for p in "${debs[@]}"; do
        dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q '^install ok installed' || missing+=("$p")
    done
    ((${#missing[@]})) || return 0
    need_root "install ${missing[*]}"
    command -v apt-get >/dev/null || cannot "needs Debian packages ${missing[*]} but there is no apt-get"
    say "apt-get install ${missing[*]}"
    export DEBIAN_FRONTEND=noninteractive
    apt-get -o DPkg::Lock::Timeout=600 update -qq || say "apt-get update failed; trying the package lists there are"
    apt-get -o DPkg::Lock::Timeout=600 install -y -qq --no-install-recommends "${missing[@]}" >/dev/null ||
        cannot "apt-get could not install ${missing[*]} (no package source or network?); not done"
}

alive() { [[ -f $1 ]] && kill -0 "$(cat "$1")" 2>/dev/null; }

usable() {  # the controller answers and our node is idle, mixed or allocated
    SLURM_CONF=$conf timeout 10 sinfo -h -N -o '%T' 2>/dev/null | grep -Eq '^(idle|mixed|allocated|completing)'
}

write_conf() {  # write_conf [FILE]: the config into FILE (default $conf, made live)
    local node cpus have out=${1:-$conf}
    node=$(hostname -s)
    have=$(nproc)
    cpus=${CORTEX_SLURM_CPUS:-2}
    ((cpus <= have)) || cpus=$have
    mkdir -p "$dir"/{ctld,spool,log,run}
    cat >"$out.tmp" <<EOF
# Written by scripts/setup-slurm.sh: a single-node SLURM on loopback.
ClusterName=cortex
SlurmctldHost=$node(127.0.0.1)
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
# A requeued job may start again cred_expire seconds after its requeue (120 by
# default), and the schedulers look at pending jobs every 2 s (not 60 and 30):
# a test sees a requeued job run again within seconds.
AuthInfo=cred_expire=10
StateSaveLocation=$dir/ctld
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/run/slurmctld.pid
SlurmdPidFile=$dir/run/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
MpiDefault=none
SwitchType=switch/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
SchedulerType=sched/backfill
SchedulerParameters=sched_interval=2,bf_interval=2
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
ReturnToService=2
# Short waits, so a test sees a time limit end a job within seconds.
KillWait=10
MinJobAge=600
InactiveLimit=0
NodeName=$node NodeAddr=127.0.0.1 NodeHostname=$node CPUs=$cpus State=UNKNOWN
PartitionName=debug Nodes=$node Default=YES MaxTime=INFINITE State=UP
EOF
    mv "$out.tmp" "$out"
    [[ $out == "$conf" ]] || return 0
    if [[ ! -e /etc/slurm/slurm.conf ]]; then
        mkdir -p /etc/slurm
        ln -s "$conf" /etc/slurm/slurm.conf
    fi
}

start_munge() {
    if munge -n 2>/dev/null | unmunge >/dev/null 2>&1; then return 0; fi
    [[ -s /etc/munge/munge.key ]] || runuser -u munge -- mungekey --create --keyfile=/etc/munge/munge.key
    mkdir -p /run/munge /var/log/munge /var/lib/munge
    chown munge:munge /run/munge /var/log/munge /var/lib/munge
    runuser -u munge -- /usr/sbin/munged 9>&-   # 9>&-: the daemons must not keep the set-up lock
    local i
    for i in $(seq 50); do
        if munge -n 2>/dev/null | unmunge >/dev/null 2>&1; then  # ours: `stop` ends it too
            mkdir -p "$dir/run"
            cp /run/munge/munged.pid "$dir/run/munged.pid" 2>/dev/null || true
            return 0
        fi
        sleep 0.1
    done
    say "munged did not come up"; exit 1
}

outdated() {  # the running cluster's config is not the one this script writes, and no job is queued
    [[ -f $conf ]] || return 1
    write_conf "$dir/run/slurm.conf.new"
    if cmp -s "$conf" "$dir/run/slurm.conf.new"; then rm -f "$dir/run/slurm.conf.new"; return 1; fi
    rm -f "$dir/run/slurm.conf.new"
    [[ -z $(SLURM_CONF=$conf timeout 10 squeue -h 2>/dev/null) ]]
}

start() {
    install
    if usable && ! outdated; then return 0; fi
    if usable; then  # started with an older config and idle: start it again with this one
        need_root "restart the SLURM daemons with a new config"
        say "the running cluster's config is outdated and no job is queued: restarting it"
        stop quiet slurmd slurmctld
    fi
    need_root "start the SLURM daemons"
    start_munge
    alive "$dir/run/slurmctld.pid" && alive "$dir/run/slurmd.pid" || {
        stop quiet slurmd slurmctld
        write_conf
        SLURM_CONF=$conf slurmctld -c -f "$conf" 9>&-   # -c: forget jobs of an earlier run
        SLURM_CONF=$conf slurmd -f "$conf" 9>&-
    }
    local i
    for i in $(seq 60); do
        if usable; then
            say "single-node SLURM up: SLURM_CONF=$conf ($(SLURM_CONF=$conf sinfo -h -o '%P %D node(s) %c CPUs %T'))"
            return 0
        fi
        sleep 0.5
    done
    say "SLURM did not become usable within 30 s; logs in $dir/log"
    tail -n 5 "$dir"/log/*.log >&2 || true
    exit 1
}

stop() {  # stop [quiet] [DAEMON...]: by default all three
    local quiet=${1:-} d pid i
    [[ $quiet == quiet ]] && shift || quiet=
    (($#)) || set -- slurmd slurmctld munged
    for d in "$@"; do
        [[ -f $dir/run/$d.pid ]] || continue
        need_root "stop $d"
        alive "$dir/run/$d.pid" || continue
        pid=$(cat "$dir/run/$d.pid")
        kill -TERM "$pid"
        for i in $(seq 100); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
        kill -0 "$pid" 2>/dev/null && kill -KILL "$pid"
        rm -f "$dir/run/$d.pid"
        [[ -n $quiet ]] || say "stopped $d ($pid)"
    done
    return 0
}

serialised() {  # run "$@" holding $dir/.setup.lock: two `start`s at once start one cluster
    mkdir -p "$dir" 2>/dev/null || need_root "create $dir"
    exec 9>"$dir/.setup.lock"
    flock -w 900 9 || { say "$dir/.setup.lock is held by another set-up"; exit 1; }
    "$@"
}

case ${1:-start} in
    install) install ;;
    start) serialised start ;;
    stop) serialised stop ;;
    status) usable ;;
    env) echo "export SLURM_CONF=$conf" ;;
    *) echo "usage: setup-slurm.sh [install|start|stop|status|env]" >&2; exit 2 ;;
esac
