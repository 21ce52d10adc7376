#!/usr/bin/env bash
# Status of a job started by submit.sh: prints running, success or failed (what
# --cluster-generic-status-cmd must print). A job whose process is gone without an exit
# status (killed outright, machine restarted) is failed, so Snakemake never waits forever.
set -euo pipefail
dir=${LOCAL_CLUSTER_DIR:-.snakemake/local-cluster}
id=$1

alive() { # the process exists and is not a zombie (dead, not yet reaped)
    kill -0 "$1" 2>/dev/null || return 1
    [ ! -r "/proc/$1/stat" ] || [ "$(sed 's/.*) //' "/proc/$1/stat" | cut -c1)" != Z ]
}

exit_status() {
    if [ "$(cat "$dir/$id.exit")" = 0 ]; then echo success; else echo failed; fi
}

if [ -f "$dir/$id.exit" ]; then
    exit_status
elif [ -f "$dir/$id.pid" ] && alive "$(cat "$dir/$id.pid")"; then
    echo running
elif [ -f "$dir/$id.exit" ]; then # it ended between the two checks
    exit_status
else
    echo failed
fi
