#!/usr/bin/env bash
# Start / stop a real single-node SLURM cluster on loopback (for tests and local trials).
#
# Usage:  workflow/scripts/slurm_cluster.sh {start|stop|status|env} [STATE_DIR]
#
#   start   install the Debian packages if missing (slurmctld slurmd slurm-client munge),
#           write slurm.conf / cgroup.conf / gres.conf and a munge key into STATE_DIR,
#           link /etc/slurm/slurm.conf to STATE_DIR/slurm.conf (only if no such file
#           exists: srun inside Snakemake jobs does not see SLURM_CONF, see below),
#           start munged, slurmctld and slurmd as daemons, wait until `sinfo` shows the
#           node idle, record the daemons' PIDs in STATE_DIR/pids. Idempotent: a running
#           healthy cluster in STATE_DIR is left alone; a stale one is stopped and wiped.
#   stop    cancel every job, stop every daemon by its recorded PID (TERM, then KILL after
#           a bounded wait), kill leftover slurmstepd processes of this cluster (found by
#           their open files under STATE_DIR), remove our /etc/slurm/slurm.conf link and
#           STATE_DIR (logs kept when ANIGS_SLURM_KEEP_LOGS is set). Idempotent.
#   status  exit 0 when all daemons of STATE_DIR are alive and the node answers `sinfo`.
#   env     print `export SLURM_CONF=...` for clients (sbatch, squeue, snakemake).
#
# STATE_DIR defaults to $ANIGS_SLURM_DIR or /tmp/anigs-slurm. Other knobs (environment):
#   ANIGS_SLURM_CTLD_PORT (6817), ANIGS_SLURMD_PORT (6818), ANIGS_SLURM_GPUS (2: fake
#   GPUs declared as GRES so that jobs asking for `gpu`/`gres` can be scheduled on a
#   machine without one; slurmd logs "not a valid character device" for them, harmless),
#   ANIGS_SLURM_TIMEOUT (60: seconds to wait for the node to be idle),
#   ANIGS_SLURM_DEFAULT_CONF (/etc/slurm/slurm.conf: the compiled-in config path to link).
# Jobs, squeue and sbatch need SLURM_CONF=STATE_DIR/slurm.conf (`eval "$(... env)"`).
# slurm.conf follows what works on these machines (and in gVisor sandboxes): no cgroups
# (proctrack/linuxproc, task/none), no accounting (so Snakemake must use
# --slurm-status-command squeue; MinJobAge=600 keeps finished jobs visible to squeue),
# DefMemPerCPU so that a job does not take the whole node, KillWait=2 for fast scancel.
# Exit codes: 0 ok, 1 error, 2 usage, 3 packages missing and not installable here.
# Needs root (slurmd runs jobs as their submitting user). Every wait is bounded; the script
# never hangs. No systemd is used.
set -euo pipefail

ACTION="${1:-}"
STATE="${2:-${ANIGS_SLURM_DIR:-/tmp/anigs-slurm}}"
CTLD_PORT="${ANIGS_SLURM_CTLD_PORT:-6817}"
SLURMD_PORT="${ANIGS_SLURMD_PORT:-6818}"
NGPUS="${ANIGS_SLURM_GPUS:-2}"
WAIT_S="${ANIGS_SLURM_TIMEOUT:-60}"
CONF="$STATE/slurm.conf"
SOCK="$STATE/munge/munge.socket"
NODE="$(hostname -s)"
# Clients read SLURM_CONF, but the Snakemake jobstep plugin (0.6.x) strips every SLURM_*
# variable except the job id from the nested `srun` it runs inside each job, so that srun
# falls back to the compiled-in default path: point it at this cluster's config.
DEFAULT_CONF="${ANIGS_SLURM_DEFAULT_CONF:-/etc/slurm/slurm.conf}"

log() { echo "[slurm_cluster] $*" >&2; }
die() { log "ERROR: $*"; exit 1; }
no_packages() { log "ERROR: $*: install the Debian packages slurmctld slurmd slurm-client munge"; exit 3; }

# Run a client command with a bounded time and this cluster's config.
client() { SLURM_CONF="$CONF" timeout -k 2 10 "$@"; }

pid_alive() {  # the process exists and is not a zombie
    [[ -n "${1:-}" ]] && kill -0 "$1" 2>/dev/null || return 1
    local stat; stat="$(cat "/proc/$1/stat" 2>/dev/null)" || return 1
    stat="${stat##*) }"
    [[ "${stat:0:1}" != Z ]]
}

read_pid() {  # read_pid NAME -> PID recorded for daemon NAME, or nothing
    local f="$STATE/pids/$1"
    [[ -s "$f" ]] && tr -dc '0-9' <"$f" || true
}

wait_for() {  # wait_for SECONDS CMD... : poll CMD every 0.2 s until it succeeds
    local deadline=$((SECONDS + $1)); shift
    until "$@" >/dev/null 2>&1; do
        (( SECONDS >= deadline )) && return 1
        sleep 0.2
    done
}

install_packages() {
    local missing=()
    for b in munged slurmctld slurmd sinfo sbatch; do
        command -v "$b" >/dev/null 2>&1 || missing+=("$b")
    done
    (( ${#missing[@]} == 0 )) && return 0
    # Exit code 3: the packages are missing and cannot be installed here (callers may skip).
    [[ "$(id -u)" == 0 ]] || no_packages "missing ${missing[*]} and not root"
    command -v apt-get >/dev/null 2>&1 || no_packages "missing ${missing[*]} and no apt-get"
    log "installing slurmctld slurmd slurm-client munge (missing: ${missing[*]})"
    timeout -k 5 180 apt-get update -qq >&2 || no_packages "apt-get update failed or timed out"
    DEBIAN_FRONTEND=noninteractive timeout -k 5 300 apt-get install -y -qq --no-install-recommends \
        slurmctld slurmd slurm-client munge >&2 || no_packages "apt-get install of slurm/munge failed or timed out"
}

node_idle() {  # the node is up and free (idle), as sinfo reports it
    local st
    st="$(client sinfo -h -N -n "$NODE" -o '%T' 2>/dev/null)" || return 1
    [[ "$st" == idle* ]]
}

node_up() {  # the node answers and takes jobs (idle, mixed or allocated)
    local st
    st="$(client sinfo -h -N -n "$NODE" -o '%T' 2>/dev/null)" || return 1
    [[ "$st" == idle* || "$st" == mix* || "$st" == alloc* || "$st" == completing* ]]
}

is_running() {
    [[ -f "$CONF" ]] || return 1
    for d in munged slurmctld slurmd; do pid_alive "$(read_pid "$d")" || return 1; done
    node_up
}

write_config() {
    local cpus mem_total real_mem def_mem
    cpus="$(env -u OMP_NUM_THREADS -u OMP_THREAD_LIMIT nproc)"   # nproc alone obeys OMP_NUM_THREADS (a 1-CPU node)
    mem_total="$(awk '/MemTotal/ {print int($2/1024)}' /proc/meminfo)"
    real_mem=$(( mem_total * 9 / 10 ))            # slightly below the real value
    def_mem=$(( real_mem / cpus / 4 ))            # without it one job takes the whole node
    (( def_mem > 2048 )) && def_mem=2048
    mkdir -p "$STATE"/{spool/ctld,spool/d,log,pids,munge}
    chmod 0755 "$STATE"; chmod 0700 "$STATE/munge"

    local gres_line="" gres_types=""
    if (( NGPUS > 0 )); then
        gres_types="GresTypes=gpu"
        gres_line="Gres=gpu:$NGPUS"
        local i
        for (( i = 0; i < NGPUS; i++ )); do : >"$STATE/fakegpu$i"; done
        echo "NodeName=$NODE Name=gpu File=$STATE/fakegpu[0-$((NGPUS - 1))]" >"$STATE/gres.conf"
    else
        : >"$STATE/gres.conf"
    fi

    cat >"$CONF" <<EOF
# Written by workflow/scripts/slurm_cluster.sh: a single-node test cluster on loopback.
ClusterName=anigs-test
SlurmctldHost=$NODE(127.0.0.1)
SlurmctldPort=$CTLD_PORT
SlurmdPort=$SLURMD_PORT
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$SOCK
StateSaveLocation=$STATE/spool/ctld
SlurmdSpoolDir=$STATE/spool/d
SlurmctldPidFile=$STATE/slurmctld.pid
SlurmdPidFile=$STATE/slurmd.pid
SlurmctldLogFile=$STATE/log/slurmctld.log
SlurmdLogFile=$STATE/log/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU_Memory
SchedulerType=sched/backfill
DefMemPerCPU=$def_mem
# squeue must still see finished jobs when Snakemake asks (>= 3x its first status delay)
MinJobAge=600
ReturnToService=2
# seconds between SIGTERM and SIGKILL when a job is cancelled (default 30)
KillWait=2
InactiveLimit=0
SlurmdTimeout=60
MpiDefault=none
$gres_types
NodeName=$NODE NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$real_mem $gres_line State=UNKNOWN
PartitionName=main Nodes=$NODE Default=YES MaxTime=INFINITE State=UP
EOF
    # Only used if a cgroup plugin is ever enabled; proctrack/linuxproc + task/none need none,
    # and the file keeps slurmd from probing the host's (possibly absent) cgroup setup.
    cat >"$STATE/cgroup.conf" <<EOF
CgroupPlugin=autodetect
ConstrainCores=no
ConstrainRAMSpace=no
ConstrainDevices=no
EOF
    if [[ ! -s "$STATE/munge/munge.key" ]]; then
        ( umask 077; dd if=/dev/urandom of="$STATE/munge/munge.key" bs=1024 count=1 status=none )
    fi
    chmod 0400 "$STATE/munge/munge.key"
}

link_default_conf() {  # make $DEFAULT_CONF a symlink to $CONF (never overwrite a real file)
    if [[ -L "$DEFAULT_CONF" ]]; then
        local target; target="$(readlink "$DEFAULT_CONF")"
        if [[ "$target" != "$CONF" && -e "$target" ]]; then
            local other p
            other="$(dirname "$target")"
            for p in "$other"/pids/*; do
                if [[ -s "$p" ]] && pid_alive "$(tr -dc '0-9' <"$p")"; then
                    die "$DEFAULT_CONF links to $target of a running cluster; stop it first: $0 stop $other"
                fi
            done
            log "replacing $DEFAULT_CONF -> $target (its cluster is not running)"
        fi
        rm -f "$DEFAULT_CONF"   # link of a cluster that is gone
    elif [[ -e "$DEFAULT_CONF" ]]; then
        die "$DEFAULT_CONF exists (a real SLURM config?): refusing to replace it. Jobs' nested srun reads it, so this loopback cluster cannot run Snakemake jobs on this host"
    fi
    mkdir -p "$(dirname "$DEFAULT_CONF")"
    ln -s "$CONF" "$DEFAULT_CONF"
}

unlink_default_conf() {  # remove the symlink only if it is ours
    if [[ -L "$DEFAULT_CONF" && "$(readlink "$DEFAULT_CONF")" == "$CONF" ]]; then
        rm -f "$DEFAULT_CONF"
    fi
}

record_pid() {  # record_pid NAME PIDFILE: wait (bounded) for the daemon's pid file
    local name="$1" pidfile="$2"
    wait_for 15 test -s "$pidfile" || die "$name wrote no pid file $pidfile; see $STATE/log/"
    local pid; pid="$(tr -dc '0-9' <"$pidfile")"
    pid_alive "$pid" || die "$name (pid $pid) died right after start; see $STATE/log/$name.log"
    echo "$pid" >"$STATE/pids/$name"
}

start() {
    local t0=$SECONDS
    if is_running; then log "already running in $STATE"; return 0; fi
    # Exit 3 (cannot set up here): slurmd must run as root to start jobs as their users.
    [[ "$(id -u)" == 0 ]] || { log "ERROR: must run as root to start slurmd"; exit 3; }
    install_packages
    # Leftovers of a half-started cluster in the same dir: stop them first.
    if [[ -d "$STATE" ]]; then
        check_state_dir
        [[ -d "$STATE/pids" ]] && stop_daemons
        rm -rf "$STATE"   # stale state of an earlier cluster: start clean
    fi
    write_config
    link_default_conf

    timeout -k 2 15 munged --force --socket="$SOCK" --key-file="$STATE/munge/munge.key" \
        --pid-file="$STATE/munge/munged.pid" --log-file="$STATE/log/munged.log" \
        --seed-file="$STATE/munge/munged.seed" </dev/null >>"$STATE/log/start.log" 2>&1 \
        || die "munged failed to start; see $STATE/log/munged.log and $STATE/log/start.log"
    record_pid munged "$STATE/munge/munged.pid"
    wait_for 10 test -S "$SOCK" || die "munge socket $SOCK did not appear"

    env SLURM_CONF="$CONF" timeout -k 2 30 slurmctld -f "$CONF" \
        </dev/null >>"$STATE/log/start.log" 2>&1 || die "slurmctld failed; see $STATE/log/slurmctld.log"
    record_pid slurmctld "$STATE/slurmctld.pid"
    wait_for 20 client scontrol ping || die "slurmctld does not answer; see $STATE/log/slurmctld.log"

    env SLURM_CONF="$CONF" timeout -k 2 30 slurmd -f "$CONF" -N "$NODE" \
        </dev/null >>"$STATE/log/start.log" 2>&1 || die "slurmd failed; see $STATE/log/slurmd.log"
    record_pid slurmd "$STATE/slurmd.pid"

    if ! wait_for "$WAIT_S" node_idle; then
        log "node $NODE not idle after ${WAIT_S}s: $(client sinfo -N 2>&1 || true)"
        tail -n 20 "$STATE/log/slurmctld.log" "$STATE/log/slurmd.log" >&2 || true
        stop_daemons
        die "cluster did not come up"
    fi
    log "cluster up in $((SECONDS - t0))s: node $NODE idle, SLURM_CONF=$CONF"
}

kill_pid() {  # kill_pid NAME PID: TERM, wait up to 10 s, then KILL
    local name="$1" pid="$2"
    pid_alive "$pid" || return 0
    kill -TERM "$pid" 2>/dev/null || true
    if ! wait_for 10 bash -c "! kill -0 $pid"; then
        log "$name (pid $pid) ignored SIGTERM; sending SIGKILL"
        kill -KILL "$pid" 2>/dev/null || true
        wait_for 5 bash -c "! kill -0 $pid" || log "$name (pid $pid) still alive after SIGKILL"
    fi
}

marked_pids() {  # PIDs of live processes holding a file of this cluster's STATE dir open
    # (slurmstepd outlives slurmd and keeps slurmd.log open). /proc/PID/environ is not
    # readable for other processes in some sandboxes (gVisor), open files are.
    timeout -k 1 20 find /proc/[0-9]*/fd -maxdepth 1 -lname "$STATE/*" 2>/dev/null \
        | cut -d/ -f3 | sort -u || true
}

stop_daemons() {
    # Cancel every job while the controller still runs, give jobs a bounded time to end.
    if pid_alive "$(read_pid slurmctld)"; then
        client scancel --full --quiet --partition=main >/dev/null 2>&1 || true
        wait_for 15 bash -c "[[ -z \"\$(SLURM_CONF='$CONF' timeout 5 squeue -h -t PD,R,CG,S 2>/dev/null)\" ]]" \
            || log "jobs still listed after scancel; stopping daemons anyway"
    fi
    local d
    for d in slurmd slurmctld munged; do
        kill_pid "$d" "$(read_pid "$d")"
        rm -f "$STATE/pids/$d"
    done
    unlink_default_conf
    # slurmstepd processes of cancelled jobs can outlive slurmd.
    local p
    for p in $(marked_pids); do
        [[ "$p" == "$$" || "$p" == "$BASHPID" ]] && continue
        [[ "$(cat /proc/"$p"/comm 2>/dev/null)" == slurmstepd ]] || continue
        log "killing leftover process $p ($(tr '\0' ' ' </proc/"$p"/cmdline 2>/dev/null | cut -c1-80))"
        kill_pid leftover "$p"
    done
}

check_state_dir() {  # refuse to delete a directory this script did not write
    [[ "$STATE" == /* && "$STATE" != "/" ]] || die "STATE_DIR must be an absolute path other than /: '$STATE'"
    if [[ -n "$(ls -A "$STATE" 2>/dev/null)" ]] && ! grep -qs '^# Written by workflow/scripts/slurm_cluster.sh' "$CONF"; then
        die "$STATE is not empty and holds no slurm.conf written by this script; refusing to touch it"
    fi
}

stop() {
    [[ -d "$STATE" ]] || { log "nothing to stop in $STATE"; return 0; }
    check_state_dir
    stop_daemons
    # Keep logs of a failed run if asked; otherwise clean everything up.
    if [[ -n "${ANIGS_SLURM_KEEP_LOGS:-}" ]]; then
        rm -rf "$STATE/spool" "$STATE/munge"
        log "stopped; logs kept in $STATE/log"
    else
        rm -rf "$STATE"
        log "stopped; removed $STATE"
    fi
}

case "$ACTION" in
    start) start ;;
    stop) stop ;;
    status) is_running && { log "running in $STATE"; exit 0; } || { log "not running in $STATE"; exit 1; } ;;
    env) echo "export SLURM_CONF=$CONF" ;;
    *) echo "usage: $0 {start|stop|status|env} [STATE_DIR]" >&2; exit 2 ;;
esac
