#!/bin/sh
# tests/tools/check_format.sh SOURCE_DIR -- every C source and header of the
# repository is laid out as its .clang-format says (CTest: test_format).
#
# The layout is clang-format 14's (Debian 12), since other versions lay out
# the same file differently: with another version, or none, the check skips
# (77) and says which it found. Exits 1 listing the files to reformat
# (`clang-format -i FILE`), 0 when all are clean.
set -u
src=$1
command -v clang-format >/dev/null 2>&1 ||
    { echo "SKIP test_format: clang-format is not installed (apt-get install clang-format)"; exit 77; }
version=$(clang-format --version | sed -n 's/.*version \([0-9]*\)\..*/\1/p')
[ "$version" = 14 ] ||
    { echo "SKIP test_format: clang-format $version here; the layout is clang-format 14's"; exit 77; }
cd "$src" || exit 1
if [ -e .git ] && command -v git >/dev/null 2>&1; then  # a worktree's .git is a file
    files=$(git ls-files '*.c' '*.h')
else
    files=$(find common firmware-bridge mesh solver devices actuators sinks view config controller tests \
        -name '*.c' -o -name '*.h')
fi
n=0 bad=0
for f in $files; do
    n=$((n + 1))
    if ! clang-format --dry-run --Werror "$f" >/dev/null 2>&1; then
        echo "not formatted: $f"
        bad=$((bad + 1))
    fi
done
echo "$n files checked with clang-format $version, $bad not formatted"
[ "$n" -gt 0 ] && [ "$bad" -eq 0 ]
