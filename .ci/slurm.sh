#!/usr/bin/env bash
# A one-node SLURM cluster on this machine, for the tests of the cluster path
# (tests/test_slurm.py) in CI and for a developer who opts in (SPA_TEST_SLURM=1).
#
#   .ci/slurm.sh up [--accounting]   start munge, slurmctld and slurmd (with --accounting also
#                                    MariaDB and slurmdbd), wait until the node is idle
#   .ci/slurm.sh down                stop what `up` started, by its pid files
#   .ci/slurm.sh check               say why `up` would skip, or nothing
#   .ci/slurm.sh run [--accounting] CMD...   up, CMD, down (down in a trap, whatever happens)
#
# Exit status of `up`: 0 ready, 3 skipped (the reason is the last line of stderr), 1 failed (the
# daemons' logs are in $SPA_SLURM_DIR). `up` stops what it started if it fails half-way.
#
# It installs Debian 12's slurmctld, slurmd, slurm-client and munge (Slurm 22.05), and for
# --accounting slurmdbd and mariadb-server, with apt-get only when they are missing. It never
# overwrites an existing /etc/slurm/slurm.conf (one it did not write), /etc/slurm/slurmdbd.conf
# or munge key, and it skips when ports 6817/6818 (6819 with accounting) are busy. State, pid
# files and the daemons' logs go to $SPA_SLURM_DIR (default /tmp/spa-slurm); `down` removes the
# slurm.conf it wrote and keeps the logs.
#
# What a lab's cluster needs from its administrator (what these tests needed from this one):
# - the repository and its .venv on a file system that the login and compute nodes share;
# - `slurm.conf` where the Slurm commands find it without SLURM_CONF (/etc/slurm/, or
#   configless mode): the job step clears SLURM_* from the environment before its inner
#   `srun` (snakemake-executor-plugin-slurm issue #164), so a cluster whose slurm.conf is
#   found only through SLURM_CONF fails every job;
# - either accounting (slurmdbd, so that `sacct` answers: the plugin's default status query),
#   or a MinJobAge comfortably longer than the status interval, so that finished jobs stay in
#   `squeue` long enough to be seen (run with `--slurm-status-command squeue`);
# - a partition that accepts jobs of the sizes the rules ask for (workflow/rules/*.smk), and
#   an account if the cluster requires one.
set -euo pipefail

DIR=${SPA_SLURM_DIR:-/tmp/spa-slurm}
CONF=/etc/slurm/slurm.conf
DBDCONF=/etc/slurm/slurmdbd.conf
MARK="# written by spa's .ci/slurm.sh"
MUNGE_KEY=/etc/munge/munge.key
MUNGE_SOCKET=/run/munge/munge.socket.2

skip() {
    echo "slurm.sh: skip: $*" >&2
    exit 3
}
say() { echo "slurm.sh: $*" >&2; }

as_root() {
    if [ "$(id -u)" -eq 0 ]; then "$@"; else sudo -n "$@"; fi
}

port_busy() { # a TCP port somebody listens on, from /proc (no ss/netstat needed)
    local hex
    hex=$(printf '%04X' "$1")
    awk -v p=":$hex" '$4 == "0A" && $2 ~ p"$" {found=1} END {exit !found}' \
        /proc/net/tcp /proc/net/tcp6 2>/dev/null
}

ours() { [ -f "$1" ] && head -1 "$1" | grep -qF "$MARK"; }

why_not() { # the reason `up` cannot run here, or nothing
    local accounting=$1
    if [ "$(id -u)" -ne 0 ] && ! sudo -n true 2>/dev/null; then
        echo "needs root or password-less sudo (apt-get, daemons, /etc/slurm)"
        return
    fi
    if ! command -v apt-get >/dev/null && ! command -v slurmctld >/dev/null; then
        echo "Slurm is not installed and there is no apt-get to install it"
        return
    fi
    if [ -e "$CONF" ] && ! ours "$CONF"; then
        echo "$CONF exists and was not written by .ci/slurm.sh: not overwriting a real cluster's configuration"
        return
    fi
    if [ "$accounting" = 1 ] && [ -e "$DBDCONF" ] && ! ours "$DBDCONF"; then
        echo "$DBDCONF exists and was not written by .ci/slurm.sh"
        return
    fi
    if [ ! -f "$DIR/slurmctld.pid" ]; then
        local port
        for port in 6817 6818 $([ "$accounting" = 1 ] && echo 6819); do
            if port_busy "$port"; then
                echo "port $port is busy (another Slurm daemon?)"
                return
            fi
        done
    fi
}

install_missing() {
    local want=(slurmctld slurmd slurm-client munge) missing=() p
    [ "$1" = 1 ] && want+=(slurmdbd mariadb-server)
    for p in "${want[@]}"; do
        dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "ok installed" || missing+=("$p")
    done
    [ "${#missing[@]}" -eq 0 ] && return
    say "installing ${missing[*]} (apt-get)"
    as_root env DEBIAN_FRONTEND=noninteractive apt-get update -qq
    # policy-rc.d: the packages' maintainer scripts must not start daemons themselves
    as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
        "${missing[@]}" >"$DIR/apt.log" 2>&1 || {
        tail -20 "$DIR/apt.log" >&2
        return 1
    }
}

write_conf() {
    local host cpus mem accounting=$1
    host=$(hostname -s)
    cpus=$(nproc)
    # RealMemory a little below MemTotal, so that slurmd does not drain the node as too small
    mem=$(awk '/MemTotal/ {printf "%d", $2 / 1024 * 0.95}' /proc/meminfo)
    as_root mkdir -p /etc/slurm
    as_root tee "$CONF" >/dev/null <<EOF
$MARK for tests; removed by \`.ci/slurm.sh down\`.
ClusterName=spa-test
SlurmctldHost=$host
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
SlurmctldPort=6817
SlurmdPort=6818
StateSaveLocation=$DIR/ctld
SlurmdSpoolDir=$DIR/spool
SlurmctldPidFile=$DIR/slurmctld.pid
SlurmdPidFile=$DIR/slurmd.pid
SlurmctldLogFile=$DIR/slurmctld.log
SlurmdLogFile=$DIR/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
# no systemd and no delegated cgroups in a CI container: processes are tracked through /proc
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/linux
JobAcctGatherFrequency=task=2
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
DefMemPerCPU=1000
SchedulerType=sched/backfill
MpiDefault=none
# finished jobs stay in squeue for 5 min: longer than the status interval, so that
# --slurm-status-command squeue sees every job end
MinJobAge=300
# a node that comes back (slurmd restarted) returns to service instead of staying down
ReturnToService=2
# a job over its time limit, or cancelled, is killed 5 s after its SIGTERM (default 30 s)
KillWait=5
# the tests' hook: a task waits while the file named by its SPA_SLURM_HOLD exists, so that a
# test can cancel a job that squeue shows running before it ends (tests/test_slurm.py)
TaskProlog=$DIR/task_prolog.sh
$(if [ "$accounting" = 1 ]; then
        echo "AccountingStorageType=accounting_storage/slurmdbd"
        echo "AccountingStorageHost=$host"
        echo "JobCompType=jobcomp/none"
    else
        echo "AccountingStorageType=accounting_storage/none"
        echo "JobCompType=jobcomp/none"
    fi)
NodeName=$host CPUs=$cpus RealMemory=$mem State=UNKNOWN
# two jobs may share a core: the tests hold jobs that only sleep (the TaskProlog), which must
# not keep the other tests' jobs waiting for a core
PartitionName=main Nodes=ALL Default=YES MaxTime=INFINITE State=UP OverSubscribe=FORCE:2
EOF
    cat >"$DIR/task_prolog.sh" <<EOF
#!/bin/sh
# TaskProlog of the test cluster (tests/test_slurm.py): while the file named by the job's
# SPA_SLURM_HOLD exists, and <hold>.<job id>.go does not, the task waits; <hold>.held.<job id>
# says so meanwhile.
h=\${SPA_SLURM_HOLD:-}
if [ -n "\$h" ] && [ -e "\$h" ]; then
    : >"\$h.held.\$SLURM_JOB_ID"
    while [ -e "\$h" ] && [ ! -e "\$h.\$SLURM_JOB_ID.go" ]; do sleep 0.2; done
    rm -f "\$h.held.\$SLURM_JOB_ID"
fi
EOF
    chmod 755 "$DIR/task_prolog.sh"
}

start_munge() {
    if [ ! -f "$MUNGE_KEY" ]; then # created, never replaced
        as_root mkdir -p /etc/munge
        as_root mungekey --create --keyfile "$MUNGE_KEY"
        as_root chown munge:munge "$MUNGE_KEY" 2>/dev/null || true
        as_root chmod 400 "$MUNGE_KEY"
        : >"$DIR/munge-key-created"
    fi
    if [ -S "$MUNGE_SOCKET" ] && munge -n 2>/dev/null | unmunge >/dev/null 2>&1; then
        say "munged already runs: using it (it will not be stopped)"
        return
    fi
    as_root mkdir -p /run/munge /var/log/munge /var/lib/munge
    as_root chown munge:munge /run/munge /var/log/munge /var/lib/munge 2>/dev/null || true
    as_root runuser -u munge -- /usr/sbin/munged --pid-file="$DIR/munged.pid" \
        --log-file="$DIR/munged.log" 2>>"$DIR/munged.log" ||
        as_root /usr/sbin/munged --force --pid-file="$DIR/munged.pid" --log-file="$DIR/munged.log"
    local i
    for i in $(seq 50); do
        [ -S "$MUNGE_SOCKET" ] && munge -n 2>/dev/null | unmunge >/dev/null 2>&1 && return
        sleep 0.1
    done
    say "munged did not start: $DIR/munged.log"
    return 1
}

start_accounting() {
    local host
    host=$(hostname -s)
    as_root mkdir -p /run/mysqld "$DIR/mariadb"
    as_root chown mysql:mysql /run/mysqld "$DIR/mariadb"
    if ! mysqladmin ping >/dev/null 2>&1; then # MariaDB on its socket alone, no TCP port
        as_root setsid /usr/sbin/mariadbd --user=mysql --datadir=/var/lib/mysql \
            --socket=/run/mysqld/mysqld.sock --skip-networking \
            --pid-file="$DIR/mariadb/mariadb.pid" --log-error="$DIR/mariadb/mariadb.log" \
            </dev/null >"$DIR/mariadb.out" 2>&1 &
        local i
        for i in $(seq 150); do
            mysqladmin ping >/dev/null 2>&1 && break
            sleep 0.2
        done
    fi
    mysql -e "CREATE DATABASE IF NOT EXISTS spa_slurm_acct;
        CREATE USER IF NOT EXISTS 'slurm'@'localhost' IDENTIFIED BY 'spa-test';
        GRANT ALL ON spa_slurm_acct.* TO 'slurm'@'localhost';"
    as_root tee "$DBDCONF" >/dev/null <<EOF
$MARK for tests; removed by \`.ci/slurm.sh down\`.
AuthType=auth/munge
DbdHost=$host
DbdPort=6819
SlurmUser=root
PidFile=$DIR/slurmdbd.pid
LogFile=$DIR/slurmdbd.log
StorageType=accounting_storage/mysql
StorageHost=localhost
StorageUser=slurm
StoragePass=spa-test
StorageLoc=spa_slurm_acct
EOF
    as_root chmod 600 "$DBDCONF"
    as_root setsid /usr/sbin/slurmdbd </dev/null >>"$DIR/slurmdbd.out" 2>&1
    local i
    for i in $(seq 100); do
        sacctmgr -i -n list cluster >/dev/null 2>&1 && break
        sleep 0.2
    done
    sacctmgr -i add cluster spa-test >/dev/null 2>&1 || true
    sacctmgr -i add account spa-lab Description=tests Organization=spa >/dev/null 2>&1 || true
    sacctmgr -i add user "$(id -un)" Account=spa-lab >/dev/null 2>&1 || true
}

wait_idle() {
    local i state
    for i in $(seq 150); do
        state=$(sinfo -h -N -o '%T' 2>/dev/null | head -1 || true)
        case "$state" in
        idle*) return 0 ;;
        esac
        sleep 0.2
    done
    say "the node is '$state', not idle, after 30 s: logs in $DIR"
    return 1
}

up() {
    local accounting=0
    [ "${1:-}" = --accounting ] && accounting=1
    if [ -f "$DIR/slurmctld.pid" ] && kill -0 "$(cat "$DIR/slurmctld.pid")" 2>/dev/null; then
        if [ "$accounting" = 1 ] && [ ! -f "$DIR/slurmdbd.pid" ]; then
            down # restart with accounting
        else
            wait_idle
            echo "ready"
            return
        fi
    fi
    local reason
    reason=$(why_not "$accounting")
    [ -z "$reason" ] || skip "$reason"
    mkdir -p "$DIR/ctld" "$DIR/spool"
    install_missing "$accounting"
    # stop whatever started if a step fails (a failed `up` leaves no daemon behind)
    trap 'say "up failed: stopping what started; logs in $DIR"; down' ERR
    write_conf "$accounting"
    start_munge
    [ "$accounting" = 1 ] && start_accounting
    as_root setsid /usr/sbin/slurmctld -i </dev/null >>"$DIR/slurmctld.out" 2>&1
    as_root setsid /usr/sbin/slurmd </dev/null >>"$DIR/slurmd.out" 2>&1
    wait_idle
    trap - ERR
    echo "ready"
}

stop_pid() { # stop the daemon of a pid file, TERM then KILL after 10 s
    local file=$1 pid i
    [ -f "$file" ] || return 0
    pid=$(cat "$file")
    if [ -n "$pid" ] && kill -0 "$pid" 2>/dev/null; then
        as_root kill -TERM "$pid" 2>/dev/null || true
        for i in $(seq 50); do
            kill -0 "$pid" 2>/dev/null || break
            sleep 0.2
        done
        kill -0 "$pid" 2>/dev/null && as_root kill -KILL "$pid" 2>/dev/null || true
    fi
    rm -f "$file"
}

down() {
    trap - ERR
    set +e
    if [ -f "$DIR/slurmctld.pid" ]; then # every job of this private cluster
        scancel --full --signal=KILL --user "$(id -un)" >/dev/null 2>&1
        scancel --user "$(id -un)" >/dev/null 2>&1
    fi
    stop_pid "$DIR/slurmd.pid"
    pkill_steps
    stop_pid "$DIR/slurmctld.pid"
    stop_pid "$DIR/slurmdbd.pid"
    stop_pid "$DIR/mariadb/mariadb.pid"
    stop_pid "$DIR/munged.pid"
    ours "$CONF" && as_root rm -f "$CONF"
    ours "$DBDCONF" && as_root rm -f "$DBDCONF"
    rm -rf "$DIR/ctld" "$DIR/spool"
    set -e
    return 0
}

pkill_steps() { # slurmstepd processes left behind, by pid from /proc, only when the machine's
    # slurm.conf is the one `up` wrote (no other Slurm runs here)
    local p
    ours "$CONF" || return 0
    for p in /proc/[0-9]*; do
        [ "$(cat "$p/comm" 2>/dev/null)" = slurmstepd ] || continue
        as_root kill -KILL "${p#/proc/}" 2>/dev/null || true
    done
}

case "${1:-}" in
up)
    shift
    up "$@"
    ;;
down) down ;;
check)
    why_not "$([ "${2:-}" = --accounting ] && echo 1 || echo 0)"
    ;;
run)
    shift
    flag=()
    if [ "${1:-}" = --accounting ]; then
        flag=(--accounting)
        shift
    fi
    trap down EXIT INT TERM
    up "${flag[@]}"
    "$@"
    ;;
*)
    echo "usage: .ci/slurm.sh up [--accounting] | down | check [--accounting] | run [--accounting] CMD..." >&2
    exit 2
    ;;
esac
