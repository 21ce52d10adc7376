#!/usr/bin/env bash
# Cancel jobs started by submit.sh (Snakemake calls this on Ctrl-C): cancel.sh ID...
dir=${LOCAL_CLUSTER_DIR:-.snakemake/local-cluster}
for id in "$@"; do
    pid=$(cat "$dir/$id.pid" 2>/dev/null) || continue
    kill -TERM -- "-$pid" 2>/dev/null || true # the job's process group (see submit.sh)
done
