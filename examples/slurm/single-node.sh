#!/usr/bin/env bash
# A one-node Slurm on this Debian machine, from Debian's packages (slurmctld, slurmd, munge), to
# run the job arrays of examples/slurm/ on a real scheduler and check them against
# single-process runs. As root:
#
#   examples/slurm/single-node.sh          # up, check, down
#   examples/slurm/single-node.sh up       # install (apt-get) and start munged, slurmctld, slurmd
#   examples/slurm/single-node.sh check    # submit the arrays and their merges, wait, compare
#   examples/slurm/single-node.sh down     # stop the daemons that `up` started
#
# The binary is $SPIBENCH, else `spibench` on PATH (`cargo install --path .`). Everything of
# this cluster lives in $SPIBENCH_SLURM_DIR (default /var/tmp/spibench-slurm): its slurm.conf
# (so /etc/slurm is left alone; clients find it through SLURM_CONF), state, logs and pid files.
# It listens on ports 16817/16818, not Slurm's 6817/6818, so that it cannot meet a real
# cluster's daemons. The settings need no cgroups (proctrack/linuxproc, task/none) and no
# accounting database, so they work in a container.
set -euo pipefail
cd "$(dirname "$0")/../.."
REPO=$PWD
DIR=${SPIBENCH_SLURM_DIR:-/var/tmp/spibench-slurm}
export SLURM_CONF=$DIR/slurm.conf
WORK=${SPIBENCH_SLURM_WORK:-$REPO/target/slurm-check}

say() { echo "single-node: $*" >&2; }
die() {
    say "$*"
    exit 1
}

install_packages() {
    [ "$(id -u)" = 0 ] || die "run as root (installs packages and starts daemons)"
    if ! command -v slurmctld >/dev/null || ! command -v slurmd >/dev/null ||
        ! command -v sbatch >/dev/null || ! command -v munged >/dev/null; then
        command -v apt-get >/dev/null || die "needs apt-get (Debian or Ubuntu) to install Slurm"
        say "installing slurmctld slurmd slurm-client munge (apt-get)"
        # A package's own start (invoke-rc.d) may fail in a container; the daemons are started
        # below, by hand, with this cluster's configuration.
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
            slurmctld slurmd slurm-client munge >/dev/null ||
            { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
                --no-install-recommends slurmctld slurmd slurm-client munge >/dev/null; }
    fi
}

write_conf() {
    local host node
    host=$(hostname -s)
    # The node as slurmd sees it (CPUs, sockets, cores, threads), less its memory and uptime:
    # no job asks for memory here, and a RealMemory above what the node reports would drain it.
    node=$(slurmd -C | head -n1 | sed -E 's/ RealMemory=[0-9]+//; s/ UpTime=.*//')
    mkdir -p "$DIR"/{state,spool,log,run}
    chown slurm:slurm "$DIR"/{state,log,run}
    cat >"$SLURM_CONF" <<CONF
# A one-node cluster for examples/slurm/single-node.sh (written by it; removed by its down).
ClusterName=spibench
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=16817
SlurmdPort=16818
SlurmUser=slurm
AuthType=auth/munge
StateSaveLocation=$DIR/state
SlurmdSpoolDir=$DIR/spool
SlurmctldPidFile=$DIR/run/slurmctld.pid
SlurmdPidFile=$DIR/run/slurmd.pid
SlurmctldLogFile=$DIR/log/slurmctld.log
SlurmdLogFile=$DIR/log/slurmd.log
# No cgroups (a container has none to give): processes tracked through /proc, tasks unbound.
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
MpiDefault=none
MailProg=/bin/true
ReturnToService=2
# Finished jobs stay visible to scontrol for 10 minutes (there is no accounting to ask).
MinJobAge=600
$node NodeAddr=127.0.0.1 State=UNKNOWN
PartitionName=debug Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
}

start_daemons() {
    if ! munge -n </dev/null >/dev/null 2>&1; then
        say "starting munged"
        install -d -o munge -g munge -m 0755 /run/munge
        runuser -u munge -- /usr/sbin/munged
        echo started >"$DIR/run/munged.ours"
    fi
    say "starting slurmctld and slurmd (SLURM_CONF=$SLURM_CONF)"
    slurmctld -c
    slurmd
    local state
    for _ in $(seq 60); do
        state=$(sinfo -h -N -o %T 2>/dev/null || true)
        case $state in
        idle*) say "node $(hostname -s) is idle"; return 0 ;;
        down* | drain*) scontrol update NodeName="$(hostname -s)" State=RESUME 2>/dev/null || true ;;
        esac
        sleep 1
    done
    die "the node did not come up (state: ${state:-none}); see $DIR/log"
}

not_running() {
    if [ -f "$DIR/run/slurmctld.pid" ] && kill -0 "$(cat "$DIR/run/slurmctld.pid")" 2>/dev/null; then
        die "a cluster from $DIR is already running (run: $0 down)"
    fi
}

up() {
    not_running
    install_packages
    write_conf
    start_daemons
    say "up; for sbatch, squeue, sinfo by hand: export SLURM_CONF=$SLURM_CONF"
}

stop_pidfile() {
    local file=$1 name=$2 pid
    [ -f "$file" ] || return 0
    pid=$(cat "$file")
    if kill -0 "$pid" 2>/dev/null; then
        say "stopping $name (pid $pid)"
        kill "$pid"
        for _ in $(seq 30); do
            kill -0 "$pid" 2>/dev/null || break
            sleep 1
        done
        kill -0 "$pid" 2>/dev/null && kill -9 "$pid"
    fi
    rm -f "$file"
}

down() {
    [ -d "$DIR" ] || return 0
    stop_pidfile "$DIR/run/slurmd.pid" slurmd
    stop_pidfile "$DIR/run/slurmctld.pid" slurmctld
    if [ -f "$DIR/run/munged.ours" ]; then
        stop_pidfile /run/munge/munged.pid munged
        rm -f "$DIR/run/munged.ours"
    fi
    rm -rf "$DIR"
}

check() {
    "$REPO/examples/slurm/check.sh" "$WORK"
}

case ${1:-all} in
up) up ;;
down) down ;;
check) check ;;
all)
    not_running
    command -v "${SPIBENCH:-spibench}" >/dev/null ||
        die "no spibench binary (set SPIBENCH or put spibench on PATH: cargo install --path .)"
    # On failure the daemons' logs are shown before down removes them.
    trap 'rc=$?; [ "$rc" = 0 ] || tail -n 20 "$DIR"/log/*.log >&2 || true; down' EXIT
    up
    check
    ;;
*) die "usage: $0 [up|check|down|all]" ;;
esac
