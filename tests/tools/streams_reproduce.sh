#!/bin/sh
# tests/tools/streams_reproduce.sh MAKE_STREAMS STREAMS SCRATCH -- runs
# make_streams into SCRATCH (emptied first) and holds every recording it
# writes to the committed one in STREAMS, byte for byte, and the two sets of
# names to each other (ctest streams_reproduce).
make_streams=$1 streams=$2 scratch=$3
rm -rf "$scratch" && mkdir -p "$scratch" || exit 1
"$make_streams" "$scratch" || { echo "streams_reproduce: make_streams failed"; exit 1; }
made=$(cd "$scratch" && ls *.isorec) committed=$(cd "$streams" && ls *.isorec)
if [ "$made" != "$committed" ]; then
    echo "streams_reproduce: make_streams writes {$made}, tests/streams holds {$committed}"
    exit 1
fi
status=0
for f in $made; do
    cmp "$streams/$f" "$scratch/$f" || status=1
done
[ $status = 0 ] && echo "streams_reproduce:" $made "reproduced byte for byte"
exit $status
