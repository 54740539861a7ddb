#!/bin/sh
# tests/tools/check_sizes.sh SOURCE_DIR -- the library's files and functions
# stay a size a reader can hold (CTest: test_sizes): no C source or header
# outside tests/ longer than 750 lines, and no function longer than 100.
# A function is counted from its opening brace in the first column to its
# closing one (the layout .clang-format gives every function definition).
# Exits 1 listing what is over, 0 when nothing is.
set -u
src=$1
cd "$src" || exit 1
if [ -e .git ] && command -v git >/dev/null 2>&1; then # a worktree's .git is a file
    files=$(git ls-files '*.c' '*.h' | grep -v '^tests/')
else
    files=$(find common firmware-bridge mesh solver devices actuators sinks view config controller \
        -name '*.c' -o -name '*.h')
fi
bad=0
for f in $files; do
    n=$(wc -l <"$f")
    if [ "$n" -gt 750 ]; then
        echo "over 750 lines: $f ($n)"
        bad=$((bad + 1))
    fi
    over=$(awk '
        /^[A-Za-z_].*\(/ && !/;[[:space:]]*$/ { name = $0 }
        /^\{/ { start = NR; inside = 1; next }
        /^\}/ && inside { if (NR - start - 1 > 100) printf "%s:%d: %d lines: %s\n", FILENAME, start, NR - start - 1, name; inside = 0 }
    ' "$f")
    if [ -n "$over" ]; then
        echo "function over 100 lines: $over"
        bad=$((bad + 1))
    fi
done
echo "check_sizes: $bad problem(s)"
[ "$bad" -eq 0 ]
