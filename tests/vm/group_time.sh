#!/bin/sh
# tests/vm/group_time.sh -- the VM group's cleanup (runs after its last
# test): prints what the group took, wall clock from the fixture's start,
# and each part, so every run shows the figure CI is held to (3 minutes).
vm=$1
if [ ! -f "$vm/group_start" ]; then
    echo "vm group: the fixture did not run"
    exit 0
fi
now=$(date +%s.%N)
start=$(cat "$vm/group_start")
echo "vm group: each part in seconds (setup: the fixture; the rest: one VM each, boot to host checks)"
sed 's/^/  /' "$vm/times"
awk -v a="$start" -v b="$now" 'BEGIN { printf "vm group: %.1f s wall from the fixture'"'"'s start to its cleanup\n", b - a }'
if [ -s "$vm/skip" ]; then
    echo "vm group: skipped: $(cat "$vm/skip")"
fi
