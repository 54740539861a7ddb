#!/bin/sh
# tests/tools/check_docs.sh SOURCE_DIR -- the references into the design
# documents hold (CTest: test_docs):
#   - every "docs/NAME.md" that a source, script or document names exists;
#   - every "docs/method.md property N" (or "properties N, M and K-L") that
#     a test cites is a numbered property of docs/method.md ("N. **...");
#   - every relative link [text](path) in README.md and docs/*.md points
#     at a file or folder of the repository.
# Exits 0 when all hold, 1 listing what does not.
set -u
src=$1
cd "$src" || exit 1
if git rev-parse --is-inside-work-tree >/dev/null 2>&1; then
    files=$(git ls-files '*.c' '*.h' '*.md' '*.sh' '*.yaml' '*.txt' '*.in')
else
    files=$(find . -path ./build -prune -o -type f \( -name '*.[ch]' -o -name '*.md' \
        -o -name '*.sh' -o -name '*.yaml' -o -name '*.txt' -o -name '*.in' \) -print)
fi
files=$(printf '%s\n' $files | grep -v 'check_docs\.sh$') # its own examples
bad=0
say() {
    echo "$*"
    bad=$((bad + 1))
}

# Named documents.
for f in $files; do
    for d in $(grep -o 'docs/[A-Za-z_]*\.md' "$f" | sort -u); do
        [ -f "$d" ] || say "$f names $d, which does not exist"
    done
done

# Cited properties: the numbers after "docs/method.md propert(y|ies)".
props=$(sed -n 's/^\([0-9][0-9]*\)\. \*\*.*/\1/p' docs/method.md | tr '\n' ' ')
[ -n "$props" ] || say "docs/method.md has no numbered properties (\"N. **...\")"
for f in $files; do
    grep -o 'docs/method\.md propert[a-z]* [0-9][-0-9, and]*' "$f" |
        sed 's/.*propert[a-z]* //; s/ and /,/g; s/ //g' | tr ',' '\n' | while read -r n; do
        [ -n "$n" ] || continue
        case $n in
        *-*) seq_list=$(seq "${n%-*}" "${n#*-}") ;;
        *) seq_list=$n ;;
        esac
        for k in $seq_list; do
            case " $props " in
            *" $k "*) ;;
            *) echo "$f cites docs/method.md property $k, which docs/method.md does not number" ;;
            esac
        done
    done
done >"${TMPDIR:-/tmp}/check_docs.$$"
while read -r line; do say "$line"; done <"${TMPDIR:-/tmp}/check_docs.$$"
rm -f "${TMPDIR:-/tmp}/check_docs.$$"

# Relative links in the documents.
for f in README.md docs/*.md; do
    dir=$(dirname "$f")
    for l in $(grep -o '\]([^)#]*' "$f" | sed 's/^](//' | grep -v -e '^[a-z]*:' -e '^$'); do
        [ -e "$dir/$l" ] || say "$f links to $l, which does not exist"
    done
done

echo "check_docs: $bad problem(s); properties numbered in docs/method.md: $props"
[ "$bad" -eq 0 ]
