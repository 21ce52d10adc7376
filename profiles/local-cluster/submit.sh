#!/usr/bin/env bash
# A stand-in for sbatch: run a Snakemake job script on this machine, in the background, and
# print a job id. Used by profiles/local-cluster (the CI's cluster run).
#   submit.sh RULE JOBID THREADS MEM_MB RUNTIME_MIN JOBSCRIPT
# Snakemake appends JOBSCRIPT itself. Each submission is one line of submissions.log, so a
# test can check that the rule's resources reached the "scheduler". State goes to
# $LOCAL_CLUSTER_DIR (default .snakemake/local-cluster): <id>.out (the job's output),
# <id>.pid, and <id>.exit once the job has ended.
set -euo pipefail
if [ "$#" -ne 6 ]; then
    echo "usage: submit.sh RULE JOBID THREADS MEM_MB RUNTIME_MIN JOBSCRIPT" >&2
    exit 2
fi
rule=$1 jobid=$2 threads=$3 mem_mb=$4 runtime=$5 jobscript=$6
dir=${LOCAL_CLUSTER_DIR:-.snakemake/local-cluster}
mkdir -p "$dir"
id="local-$(date +%s%N)-$$"
printf 'id=%s rule=%s jobid=%s threads=%s mem_mb=%s runtime=%s jobscript=%s\n' \
    "$id" "$rule" "$jobid" "$threads" "$mem_mb" "$runtime" "$jobscript" >>"$dir/submissions.log"
# The job runs in its own session, so that cancel.sh can stop its whole process group. The
# wrapper outlives a SIGTERM (trap :) to write the job's exit status, last and atomically,
# for status.sh.
setsid nohup bash -c 'trap : TERM; bash "$1" >"$2.out" 2>&1
    echo $? >"$2.exit.tmp"; mv "$2.exit.tmp" "$2.exit"' \
    job "$jobscript" "$dir/$id" </dev/null >/dev/null 2>&1 &
echo $! >"$dir/$id.pid"
echo "$id"
