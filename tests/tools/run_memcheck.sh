#!/bin/sh
# tests/tools/run_memcheck.sh VALGRIND ISOSHAPE SCENE LOG -- `isoshape run`
# on a short scene with the live view and emulated actuators under valgrind
# memcheck (ctest test_run_memcheck). Fails on any memcheck error or a
# definite leak, and unless both sinks said they ran.
valgrind=$1 bin=$2 scene=$3 log=$4
"$valgrind" --error-exitcode=1 --leak-check=full --errors-for-leak-kinds=definite \
    "$bin" run "$scene" --port 0 --no-rt --quiet 2>"$log"
rc=$?
cat "$log"
grep -q 'live view on' "$log" || { echo "run_memcheck: the live view did not start"; exit 1; }
grep -q 'emulated MCU' "$log" || { echo "run_memcheck: the actuators did not start"; exit 1; }
exit $rc
