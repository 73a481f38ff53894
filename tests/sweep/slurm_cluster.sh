#!/usr/bin/env bash
# A private single-node Slurm cluster on 127.0.0.1, for tests:
#   tests/sweep/slurm_cluster.sh start DIR    # prints "export SLURM_CONF=DIR/slurm.conf" when the node is idle
#   tests/sweep/slurm_cluster.sh stop DIR     # cancels its jobs, stops slurmd, slurmctld and munged by PID
# Everything lives in DIR: its own munge key and socket, slurm.conf (free ports picked at start), state,
# spool, PID and log files, so it touches neither /etc/slurm nor another cluster on the same machine.
# Installs nothing (scripts/setup.sh installs slurm-wlm and munge). Needs root: slurmd runs jobs as their
# submitting user and munged runs as the user munge.
# Exit codes: 0 done, 3 this machine cannot run it (not root, packages missing: a test should skip), 1 a
# daemon failed to start (see DIR/log/).
set -uo pipefail

usage() { echo "usage: $0 start|stop DIR" >&2; exit 2; }
[ $# -eq 2 ] || usage
action=$1
dir=$2

cannot() { echo "slurm_cluster: cannot run here: $*" >&2; exit 3; }
fail() { echo "slurm_cluster: $*" >&2; exit 1; }

# Stops the process whose PID is in a file: SIGTERM, up to 10 s, then SIGKILL.
stop_pid_file() {
  local file=$1 pid i
  [ -f "$file" ] || return 0
  pid=$(cat "$file")
  rm -f "$file"
  [ -n "$pid" ] && kill -0 "$pid" 2>/dev/null || return 0
  kill -TERM "$pid" 2>/dev/null
  for i in $(seq 100); do
    kill -0 "$pid" 2>/dev/null || return 0
    sleep 0.1
  done
  kill -KILL "$pid" 2>/dev/null
  return 0
}

stop_cluster() {
  export SLURM_CONF=$dir/slurm.conf
  if [ -f "$SLURM_CONF" ] && [ -f "$dir/run/slurmctld.pid" ]; then
    # Jobs first, so that no slurmstepd outlives its slurmd.
    scancel --quiet --full --user="$(id -un)" 2>/dev/null
    for _ in $(seq 100); do
      [ -z "$(squeue -h -t RUNNING,COMPLETING,CONFIGURING -o %i 2>/dev/null)" ] && break
      sleep 0.1
    done
  fi
  stop_pid_file "$dir/run/slurmd.pid"
  stop_pid_file "$dir/run/slurmctld.pid"
  stop_pid_file "$dir/run/munged.pid"
}

free_port() {
  python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}

start_cluster() {
  [ "$(id -u)" -eq 0 ] || cannot "needs root (slurmd and munged), running as $(id -un)"
  local tool
  for tool in munged mungekey slurmctld slurmd sbatch squeue sinfo scontrol scancel setpriv python3; do
    command -v "$tool" >/dev/null || [ -x "/usr/sbin/$tool" ] ||
      cannot "$tool not installed (scripts/setup.sh installs slurm-wlm and munge)"
  done
  id munge >/dev/null 2>&1 || cannot "no user munge (the munge package creates it)"
  [ -e "$dir/run/slurmctld.pid" ] && fail "$dir already has a running cluster (stop it first)"

  mkdir -p "$dir"
  dir=$(cd "$dir" && pwd)
  # munged refuses directories others may write, and the user munge must reach its own directory.
  chmod 0755 "$dir"
  mkdir -p "$dir/munge" "$dir/state" "$dir/spool" "$dir/log" "$dir/run"
  chown munge:munge "$dir/munge"
  chmod 0755 "$dir/munge"
  setpriv --reuid=munge --regid=munge --init-groups test -x "$dir/munge" ||
    fail "the user munge cannot reach $dir (a directory above it is not searchable by others)"
  local key=$dir/munge/munge.key socket=$dir/munge/munge.socket
  rm -f "$key" "$socket"
  /usr/sbin/mungekey --create --keyfile="$key" >"$dir/log/mungekey.out" 2>&1 ||
    fail "mungekey failed: $(cat "$dir/log/mungekey.out")"
  chown munge:munge "$key"
  chmod 0600 "$key"

  # munged in the foreground as munge (setpriv execs, so $! is munged's own PID).
  setpriv --reuid=munge --regid=munge --init-groups /usr/sbin/munged -F --socket="$socket" --key-file="$key" \
    --pid-file="$dir/munge/munged.pid" --log-file="$dir/munge/munged.log" --seed-file="$dir/munge/munged.seed" \
    </dev/null >"$dir/log/munged.out" 2>&1 &
  echo $! >"$dir/run/munged.pid"
  local i
  for i in $(seq 100); do
    [ -S "$socket" ] && break
    kill -0 "$(cat "$dir/run/munged.pid")" 2>/dev/null || break
    sleep 0.1
  done
  if [ ! -S "$socket" ]; then
    local why
    why=$(cat "$dir/log/munged.out" "$dir/munge/munged.log" 2>/dev/null | grep -m 3 -E 'Error|Fatal' ||
      tail -n 3 "$dir/log/munged.out")
    stop_cluster
    fail "munged did not start: $why"
  fi

  local host memory cpus ctld_port slurmd_port
  host=$(hostname -s)
  cpus=$(nproc --all)
  # slurmd -C prints the node's own line; take its memory (MB), leaving 1 GB to the system.
  memory=$(slurmd -C 2>/dev/null | sed -n 's/.*RealMemory=\([0-9]*\).*/\1/p' | head -n 1)
  memory=$(( ${memory:-2048} > 2048 ? ${memory:-2048} - 1024 : ${memory:-2048} ))
  ctld_port=$(free_port)
  slurmd_port=$(free_port)
  while [ "$slurmd_port" = "$ctld_port" ]; do slurmd_port=$(free_port); done
  cat >"$dir/slurm.conf" <<EOF
# Written by tests/sweep/slurm_cluster.sh: one node on 127.0.0.1, private paths and ports.
ClusterName=hlttest
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
# cred_expire: how long a killed job's credential stays revoked, and so how long a requeued job waits before it
# may start again (default 120 s; its relaunch would be refused before that).
AuthInfo=socket=$socket,cred_expire=5
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
MpiDefault=none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerType=sched/backfill
ReturnToService=2
KillWait=5
MinJobAge=600
InactiveLimit=0
MailProg=/bin/true
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/state/slurmctld.pid
SlurmdPidFile=$dir/spool/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
NodeName=$host NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$memory State=UNKNOWN
PartitionName=debug Nodes=ALL Default=YES MaxTime=INFINITE State=UP
EOF
  export SLURM_CONF=$dir/slurm.conf
  # -c: no state from an earlier cluster in the same directory; -D: foreground, so $! is the daemon.
  slurmctld -D -c -f "$SLURM_CONF" </dev/null >"$dir/log/slurmctld.out" 2>&1 &
  echo $! >"$dir/run/slurmctld.pid"
  slurmd -D -N "$host" -f "$SLURM_CONF" </dev/null >"$dir/log/slurmd.out" 2>&1 &
  echo $! >"$dir/run/slurmd.pid"

  local state=""
  for i in $(seq 300); do
    state=$(sinfo -h -o %T 2>/dev/null | head -n 1)
    [ "$state" = idle ] && break
    if ! kill -0 "$(cat "$dir/run/slurmctld.pid")" 2>/dev/null ||
       ! kill -0 "$(cat "$dir/run/slurmd.pid")" 2>/dev/null; then
      break
    fi
    sleep 0.1
  done
  if [ "$state" != idle ]; then
    local why
    why=$(tail -n 3 "$dir/log/slurmctld.log" "$dir/log/slurmd.log" "$dir/log/slurmctld.out" "$dir/log/slurmd.out" 2>/dev/null)
    stop_cluster
    fail "the node did not become idle (state '${state:-none}'):
$why"
  fi
  echo "export SLURM_CONF=$SLURM_CONF"
}

case "$action" in
  start) start_cluster ;;
  stop)
    [ -d "$dir" ] || exit 0
    dir=$(cd "$dir" && pwd)
    stop_cluster
    ;;
  *) usage ;;
esac
