#!/usr/bin/env bash
# Run the smoke workflow on a real, throw-away, one-node SLURM cluster and check that it gives
# the same results as a local run.  See tests/cluster/README.md.
#
#   bash tests/cluster/run_slurm_smoke.sh          # the study's smoke workflow (config/smoke.yaml)
#   bash tests/cluster/run_slurm_smoke.sh --mini   # tests/cluster/mini: SLURM plumbing only
#   bash tests/cluster/run_slurm_smoke.sh --stream # a small dense study's `stream` target
#                                                  # (config/stream_smoke.yaml): one job per take
#
# Exit codes: 0 pass; 1 outputs differ (or a check on the SLURM jobs failed); 2 the SLURM run
# failed; 3 the local reference run failed; 64 bad usage; 77 skipped, this machine cannot host
# the test cluster (reason printed on the last line as "SKIP: ...").
#
# Environment knobs: SLURM_SMOKE_TARGETS="file ..." builds only these targets (default: all);
# SLURM_SMOKE_KEEP=1 keeps the temp dir; SLURM_SMOKE_RUN_TIMEOUT (seconds,
# default 1800) bounds each snakemake run; SLURM_SMOKE_JOBS (default 4) is --jobs for SLURM;
# SLURM_SMOKE_TMP sets the parent of the temp dir (default /tmp).
set -uo pipefail

readonly EXIT_DIFF=1 EXIT_SLURM_RUN=2 EXIT_LOCAL_RUN=3 EXIT_USAGE=64 EXIT_SKIP=77

HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
ROOT="$(cd "$HERE/../.." && pwd)"
PROFILE="$ROOT/profiles/slurm"
RUN_TIMEOUT="${SLURM_SMOKE_RUN_TIMEOUT:-1800}"
JOBS="${SLURM_SMOKE_JOBS:-4}"

MODE=smoke
case "${1:-}" in
  "") ;;
  --mini) MODE=mini ;;
  --stream) MODE=stream ;;
  -h | --help) sed -n '2,17p' "${BASH_SOURCE[0]}"; exit 0 ;;
  *) echo "usage: $0 [--mini | --stream]" >&2; exit "$EXIT_USAGE" ;;
esac
if [[ $MODE == mini ]]; then
  SNAKEFILE="$HERE/mini/Snakefile"
  CONFIG_ARGS=()
else
  SNAKEFILE="$ROOT/Snakefile"
  CONFIG_ARGS=(--configfile "$ROOT/config/smoke.yaml")
fi
CONFIG_NAME=smoke.yaml
DEFAULT_TARGETS=""
if [[ $MODE == stream ]]; then
  CONFIG_NAME=stream_smoke.yaml
  DEFAULT_TARGETS=stream
fi

read -r -a TARGETS <<<"${SLURM_SMOKE_TARGETS:-$DEFAULT_TARGETS}" # given last: --configfile takes 1+ values

T0=$(date +%s)
log() { printf '[slurm-smoke %4ds] %s\n' "$(($(date +%s) - T0))" "$*"; }
skip() { # one line "... SKIP: <reason>" on stdout, exit 77
  log "SKIP: $*"
  exit "$EXIT_SKIP"
}

# ---------------------------------------------------------------------------------------------
# 0. Preconditions: root (daemons, apt), snakemake with the slurm executor plugin.
# ---------------------------------------------------------------------------------------------
[[ $(id -u) -eq 0 ]] || skip "needs root to install and run munged/slurmctld/slurmd (uid $(id -u))"

if [[ -x "$ROOT/.venv/bin/snakemake" ]]; then
  export PATH="$ROOT/.venv/bin:$PATH"
  export VIRTUAL_ENV="$ROOT/.venv"
fi
command -v snakemake >/dev/null || skip "snakemake not found (run 'make venv' first)"
PYTHON="$(dirname "$(command -v snakemake)")/python"
[[ -x $PYTHON ]] || PYTHON=python3
"$PYTHON" -c 'import snakemake_executor_plugin_slurm' 2>/dev/null ||
  skip "snakemake-executor-plugin-slurm is not installed in $(command -v snakemake) (make cluster)"

# ---------------------------------------------------------------------------------------------
# 1. Debian's SLURM and munge, if missing.
# ---------------------------------------------------------------------------------------------
need_pkgs=0
for bin in munged slurmctld slurmd sbatch squeue sinfo scontrol; do
  command -v "$bin" >/dev/null 2>&1 || need_pkgs=1
done
if ((need_pkgs)); then
  command -v apt-get >/dev/null || skip "SLURM is not installed and there is no apt-get"
  log "installing slurmctld slurmd slurm-client munge with apt-get"
  export DEBIAN_FRONTEND=noninteractive
  apt_install() {
    timeout 900 apt-get install -y -q --no-install-recommends \
      slurmctld slurmd slurm-client munge </dev/null >>"${APT_LOG:-/dev/null}" 2>&1
  }
  APT_LOG=$(mktemp)
  # Keep the packages' init scripts from starting system-wide daemons during installation
  # (Docker images usually ship this policy already; add it only for the install if missing).
  POLICY=/usr/sbin/policy-rc.d
  own_policy=0
  if [[ ! -e $POLICY ]]; then
    printf '#!/bin/sh\nexit 101\n' >"$POLICY" && chmod 755 "$POLICY" && own_policy=1
  fi
  apt_ok=0
  if apt_install; then
    apt_ok=1
  else
    timeout 300 apt-get update -q </dev/null >>"$APT_LOG" 2>&1
    apt_install && apt_ok=1
  fi
  ((own_policy)) && rm -f "$POLICY"
  if ((!apt_ok)); then
    tail -5 "$APT_LOG" | sed 's/^/    apt: /'
    skip "apt-get could not install slurmctld slurmd slurm-client munge"
  fi
  rm -f "$APT_LOG"
fi
for bin in munged munge slurmctld slurmd sbatch squeue sinfo scontrol scancel srun; do
  command -v "$bin" >/dev/null 2>&1 || skip "$bin still missing after installation"
done
log "$(slurmctld -V), munge $(munged -V 2>&1 | awk '{print $1}' | sed 's/munge-//')"

# ---------------------------------------------------------------------------------------------
# 2. A private munge + SLURM installation under a temp dir; nothing in /etc is touched.
# ---------------------------------------------------------------------------------------------
TMP="$(mktemp -d "${SLURM_SMOKE_TMP:-/tmp}/facemotion-slurm.XXXXXX")"
chmod 755 "$TMP" # munged requires the socket's directories to be traversable by everyone
PIDS=()
# shellcheck disable=SC2317  # invoked by the EXIT trap
cleanup() {
  local rc=$?
  trap - EXIT INT TERM
  if [[ -n ${SLURM_CONF:-} && -f ${SLURM_CONF:-} ]] && ((${#PIDS[@]})); then
    timeout 20 scancel --full --quiet --partition=debug 2>/dev/null || true
  fi
  # Stop what this script started, newest first: slurmd, slurmctld, munged.
  for ((i = ${#PIDS[@]} - 1; i >= 0; i--)); do
    kill "${PIDS[i]}" 2>/dev/null || true
  done
  for pid in "${PIDS[@]}"; do
    for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.2; done
    kill -9 "$pid" 2>/dev/null || true
  done
  if [[ ${SLURM_SMOKE_KEEP:-0} == 1 ]]; then
    log "kept $TMP"
  else
    rm -rf "$TMP"
  fi
  exit "$rc"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

mkdir -p "$TMP"/{munge,etc,state,spool,log,run}
chmod 755 "$TMP/munge"

# munge: fresh key, daemon in the foreground (backgrounded here so that we own its pid).
if command -v mungekey >/dev/null 2>&1; then
  mungekey --create --keyfile="$TMP/munge/munge.key" >/dev/null 2>&1
fi
if [[ ! -s $TMP/munge/munge.key ]]; then
  (umask 077 && dd if=/dev/urandom of="$TMP/munge/munge.key" bs=1024 count=1 status=none)
fi
chmod 600 "$TMP/munge/munge.key"
MUNGE_SOCKET="$TMP/munge/munge.socket"
munged --foreground --key-file="$TMP/munge/munge.key" --socket="$MUNGE_SOCKET" \
  --pid-file="$TMP/munge/munged.pid" --seed-file="$TMP/munge/munged.seed" \
  >"$TMP/log/munged.log" 2>&1 </dev/null &
PIDS+=($!)
ok=0
for _ in $(seq 50); do
  if munge -n -S "$MUNGE_SOCKET" 2>/dev/null | unmunge -S "$MUNGE_SOCKET" >/dev/null 2>&1; then
    ok=1
    break
  fi
  sleep 0.2
done
((ok)) || {
  tail -5 "$TMP/log/munged.log" | sed 's/^/    munged: /'
  skip "munged did not start"
}
log "munged running (pid ${PIDS[0]})"

# slurm.conf: one node with this machine's CPUs and memory, one default partition 'debug'.
HOST="$(hostname -s)"
CPUS="$(nproc)"
MEM_TOTAL="$(free -m | awk '/^Mem:/ {print $2}')"
REAL_MEMORY=$((MEM_TOTAL > 1024 ? MEM_TOTAL - 256 : MEM_TOTAL)) # slurmd drains a node that has less than configured
free_port() {
  "$PYTHON" -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}
CTLD_PORT="$(free_port)"
SLURMD_PORT="$(free_port)"
[[ $CTLD_PORT != "$SLURMD_PORT" ]] || SLURMD_PORT=$((CTLD_PORT + 1))
export SLURM_CONF="$TMP/etc/slurm.conf"
cat >"$SLURM_CONF" <<EOF
# Throw-away one-node cluster written by tests/cluster/run_slurm_smoke.sh
ClusterName=facemotion-ci
SlurmctldHost=$HOST(127.0.0.1)
SlurmctldPort=$CTLD_PORT
SlurmdPort=$SLURMD_PORT
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$MUNGE_SOCKET
StateSaveLocation=$TMP/state
SlurmdSpoolDir=$TMP/spool
SlurmctldPidFile=$TMP/run/slurmctld.pid
SlurmdPidFile=$TMP/run/slurmd.pid
SlurmctldLogFile=$TMP/log/slurmctld.log
SlurmdLogFile=$TMP/log/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
# no cgroups: plain process tracking, no task containment
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
MpiDefault=none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
SchedulerType=sched/backfill
# no slurmdbd; every finished job is appended to a text file instead
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
JobCompType=jobcomp/filetxt
JobCompLoc=$TMP/log/jobcomp.txt
# keep finished jobs visible to squeue/scontrol for an hour, so the executor can use squeue
MinJobAge=3600
ReturnToService=2
SlurmctldTimeout=30
SlurmdTimeout=60
NodeName=$HOST NodeAddr=127.0.0.1 CPUs=$CPUS RealMemory=$REAL_MEMORY State=UNKNOWN
PartitionName=debug Nodes=$HOST Default=YES MaxTime=INFINITE State=UP
EOF
: >"$TMP/etc/cgroup.conf" # present but unused (proctrack/linuxproc, task/none)

# The slurm.conf lives here rather than in /etc/slurm, so SLURM_CONF points to it. Inside each
# job, snakemake-executor-plugin-slurm-jobstep (0.6.1) strips every SLURM_* variable except the
# job's identity before its nested `srun`, SLURM_CONF included, so that srun would look for
# /etc/slurm/slurm.conf and then DNS SRV records and fail ("Could not establish a configuration
# source"). A real cluster has its slurm.conf at the default path on every node; here a
# one-line srun wrapper early in PATH (exported to jobs by sbatch --export=ALL) puts it back.
mkdir -p "$TMP/bin"
printf '#!/bin/sh\nSLURM_CONF=%q exec %q "$@"\n' "$SLURM_CONF" "$(command -v srun)" >"$TMP/bin/srun"
chmod 755 "$TMP/bin/srun"
export PATH="$TMP/bin:$PATH"

slurmctld -D -i -f "$SLURM_CONF" >"$TMP/log/slurmctld.stderr" 2>&1 </dev/null &
PIDS+=($!)
slurmd -D -f "$SLURM_CONF" -N "$HOST" >"$TMP/log/slurmd.stderr" 2>&1 </dev/null &
PIDS+=($!)

show_daemon_logs() {
  for f in slurmctld.stderr slurmctld.log slurmd.stderr slurmd.log; do
    [[ -s $TMP/log/$f ]] && tail -8 "$TMP/log/$f" | sed "s/^/    $f: /"
  done
}
state=""
deadline=$(($(date +%s) + 90))
while (($(date +%s) < deadline)); do
  for p in "${PIDS[@]:1}"; do
    kill -0 "$p" 2>/dev/null || {
      show_daemon_logs
      skip "slurmctld or slurmd exited during start-up (see logs above)"
    }
  done
  state="$(timeout 10 sinfo -h -n "$HOST" -o %T 2>/dev/null | head -1)"
  [[ $state == idle ]] && break
  if [[ $state == drain* || $state == down* ]]; then
    timeout 10 scontrol update NodeName="$HOST" State=RESUME >/dev/null 2>&1 || true
  fi
  sleep 1
done
if [[ $state != idle ]]; then
  show_daemon_logs
  timeout 10 scontrol show node "$HOST" 2>&1 | sed 's/^/    node: /'
  skip "node $HOST not idle after 90 s (state '${state:-unknown}')"
fi
log "cluster up: $(sinfo -h -o '%P %a %D %T %c CPUs %m MB' | head -1) (slurmctld :$CTLD_PORT, slurmd :$SLURMD_PORT)"

# A trivial job first, so that a machine that cannot launch jobs is reported as a skip.
if ! out="$(timeout 60 srun -p debug -N1 -n1 -t 1 --mem 100 hostname 2>&1)"; then
  echo "$out" | tail -5 | sed 's/^/    srun: /'
  show_daemon_logs
  skip "slurmd cannot launch a job step on this machine"
fi
log "srun test job ran on: $out"

# ---------------------------------------------------------------------------------------------
# 3. The workflow through SLURM.
# ---------------------------------------------------------------------------------------------
# Both runs use one snapshot of the code taken now (Snakefile, workflow/, scripts/, src/,
# config/), so that edits or commits made in the working tree while the test runs cannot make
# the two runs differ. PYTHONPATH puts the snapshot's package ahead of the editable install
# (sbatch --export=ALL passes it to the jobs). Outside a git checkout the provenance sidecars
# record commit "unknown" in both runs. The profile under test is the repository's.
if [[ $MODE != mini ]]; then
  SNAP="$TMP/snapshot/$(basename "$ROOT")"
  mkdir -p "$SNAP"
  tar -C "$ROOT" --exclude=./.venv --exclude=./.git --exclude=./results --exclude=./.snakemake \
    --exclude=./.pytest_cache --exclude=./.ruff_cache --exclude=./benchmarks/out \
    --exclude=__pycache__ -cf - . |
    tar -C "$SNAP" -xf - || skip "could not copy the workflow to $SNAP"
  # the real data live beside the project root (../shared/data)
  [[ -e $ROOT/../shared ]] && ln -s "$(cd "$ROOT/../shared" && pwd)" "$TMP/snapshot/shared"
  SNAKEFILE="$SNAP/Snakefile"
  CONFIG_ARGS=(--configfile "$SNAP/config/$CONFIG_NAME")
  export PYTHONPATH="$SNAP/src${PYTHONPATH:+:$PYTHONPATH}"
  log "code snapshot in $SNAP"
fi
SLURM_DIR="$TMP/slurm_run"
LOCAL_DIR="$TMP/local_run"
mkdir -p "$SLURM_DIR" "$LOCAL_DIR"
# Cluster-specific settings for this test cluster (not in the profile, which is for real
# clusters): squeue for job status (no slurmdbd here, sacct cannot answer; MinJobAge above
# keeps finished jobs visible), a short first status check, and keep the per-job SLURM logs.
SLURM_ARGS=(
  --slurm-status-command squeue
  --slurm-init-seconds-before-status-checks 5
  --slurm-keep-successful-logs
  --slurm-jobname-prefix facemotion_ci
)
log "SLURM run: snakemake -s $SNAKEFILE --directory $SLURM_DIR ${CONFIG_ARGS[*]} --profile $PROFILE --jobs $JOBS ${SLURM_ARGS[*]} ${TARGETS[*]}"
t=$(date +%s)
timeout -k 60 "$RUN_TIMEOUT" snakemake -s "$SNAKEFILE" --directory "$SLURM_DIR" "${CONFIG_ARGS[@]}" \
  --profile "$PROFILE" --jobs "$JOBS" "${SLURM_ARGS[@]}" "${TARGETS[@]}" \
  </dev/null >"$TMP/slurm_run.log" 2>&1
slurm_rc=$?
SLURM_SECONDS=$(($(date +%s) - t))
log "SLURM run finished with exit code $slurm_rc in ${SLURM_SECONDS}s"

RUN_ID="$(sed -n 's/.*SLURM run ID: //p' "$TMP/slurm_run.log" | head -1)"
N_SUBMITTED="$(grep -cE 'Job [0-9]+ has been submitted with SLURM jobid [0-9]+' "$TMP/slurm_run.log")"
# The SLURM side of the story: every job of this run, as slurmctld and jobcomp saw it.
SQUEUE="$(timeout 20 squeue --states=all --noheader --name "$RUN_ID" -o '%i|%T|%P|%C|%m|%l|%k' 2>/dev/null)"
N_SLURM_JOBS="$(grep -c . <<<"$SQUEUE")"
N_SLURM_COMPLETED="$(grep -c '|COMPLETED|' <<<"$SQUEUE")"
N_JOBCOMP="$(grep -c "Name=$RUN_ID .*JobState=COMPLETED" "$TMP/log/jobcomp.txt" 2>/dev/null)"
N_SLURM_LOGS="$(find "$SLURM_DIR/.snakemake/slurm_logs" -name '*.log' 2>/dev/null | wc -l)"
log "snakemake: $N_SUBMITTED jobs submitted with sbatch; squeue: $N_SLURM_JOBS jobs named $RUN_ID" \
  "($N_SLURM_COMPLETED COMPLETED); jobcomp: $N_JOBCOMP COMPLETED; $N_SLURM_LOGS SLURM job logs"
if [[ -n $SQUEUE ]]; then
  echo "    jobid|state|partition|cpus|mem|timelimit|comment"
  head -40 <<<"$SQUEUE" | sed 's/^/    /'
fi

if ((slurm_rc != 0)); then
  tail -40 "$TMP/slurm_run.log" | sed 's/^/    slurm run: /'
  if ((slurm_rc == 124 || slurm_rc == 137)); then
    log "FAIL: the SLURM run timed out after ${RUN_TIMEOUT}s (SLURM_SMOKE_RUN_TIMEOUT)"
  else
    log "FAIL: the workflow failed on SLURM (exit $slurm_rc)"
  fi
  SLURM_SMOKE_KEEP=1
  exit "$EXIT_SLURM_RUN"
fi

# ---------------------------------------------------------------------------------------------
# 4. The same workflow locally, then compare every result file.
# ---------------------------------------------------------------------------------------------
log "local run: snakemake -s $SNAKEFILE --directory $LOCAL_DIR ${CONFIG_ARGS[*]} --cores 2 ${TARGETS[*]}"
t=$(date +%s)
timeout -k 60 "$RUN_TIMEOUT" snakemake -s "$SNAKEFILE" --directory "$LOCAL_DIR" "${CONFIG_ARGS[@]}" \
  --cores 2 "${TARGETS[@]}" </dev/null >"$TMP/local_run.log" 2>&1
local_rc=$?
LOCAL_SECONDS=$(($(date +%s) - t))
log "local run finished with exit code $local_rc in ${LOCAL_SECONDS}s"
if ((local_rc != 0)); then
  tail -30 "$TMP/local_run.log" | sed 's/^/    local run: /'
  log "FAIL: the local reference run failed (exit $local_rc)"
  SLURM_SMOKE_KEEP=1
  exit "$EXIT_LOCAL_RUN"
fi

checksums() { # sha256 of every result except logs, benchmarks and HTML reports, relative to $1
  (cd "$1" && find results -type f ! -path 'results/logs/*' ! -path 'results/*/logs/*' \
    ! -path 'results/*/benchmarks/*' ! -name '*.html' -print0 |
    LC_ALL=C sort -z | xargs -0 -r sha256sum)
}
checksums "$SLURM_DIR" >"$TMP/slurm.sha256"
checksums "$LOCAL_DIR" >"$TMP/local.sha256"
N_FILES="$(wc -l <"$TMP/local.sha256")"
failures=()
if ! diff -u "$TMP/local.sha256" "$TMP/slurm.sha256" >"$TMP/checksums.diff"; then
  sed 's/^/    /' "$TMP/checksums.diff" | head -60
  failures+=("result files differ between the SLURM and the local run (diff above)")
fi
((N_FILES > 0)) || failures+=("no result files to compare")
((N_SUBMITTED > 0)) || failures+=("snakemake reported no sbatch submissions")
((N_SLURM_COMPLETED == N_SUBMITTED)) ||
  failures+=("snakemake submitted $N_SUBMITTED jobs but SLURM shows $N_SLURM_COMPLETED COMPLETED")
[[ ! -f $TMP/log/jobcomp.txt ]] || ((N_JOBCOMP == N_SUBMITTED)) ||
  failures+=("snakemake submitted $N_SUBMITTED jobs but jobcomp records $N_JOBCOMP COMPLETED")
if [[ $MODE == mini ]]; then
  # the mini workflow's logs carry the SLURM job id of the job that wrote them
  bad="$(grep -L 'slurm_job_id=[0-9]' "$SLURM_DIR"/results/logs/*/*.log)"
  [[ -z $bad ]] || failures+=("not run inside a SLURM job: $bad")
fi

echo
echo "==== SLURM smoke test summary ($MODE workflow) ===="
echo "cluster:          $(sinfo -h -o '%P %D node(s) %c CPUs %m MB' | head -1), $(slurmctld -V)"
echo "SLURM run:        exit $slurm_rc, ${SLURM_SECONDS}s, $N_SUBMITTED jobs via sbatch, $N_SLURM_COMPLETED COMPLETED in squeue, $N_JOBCOMP in jobcomp"
echo "local run:        exit $local_rc, ${LOCAL_SECONDS}s"
echo "files compared:   $N_FILES (results/ minus logs, benchmarks and *.html)"
echo "total time:       $(($(date +%s) - T0))s"
if ((${#failures[@]})); then
  printf 'FAIL: %s\n' "${failures[@]}"
  SLURM_SMOKE_KEEP=1
  exit "$EXIT_DIFF"
fi
echo "PASS: identical results from SLURM and local execution"
exit 0
