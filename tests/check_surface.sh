#!/bin/sh
# tests/check_surface.sh -- the installed library's public surface, as a user
# meets it (tests/CMakeLists.txt runs both modes as CTest tests).
#
#   check_surface.sh headers BUILD_DIR TMP_DIR CC
#       installs BUILD_DIR into a temporary prefix and compiles every
#       installed header on its own, twice included, with
#       -std=c11 -Wall -Wextra -Werror -pedantic and the Cflags of the
#       installed isoshape.pc: a header that needs another one first, or
#       includes one that is not installed, fails here.
#   check_surface.sh exports BUILD_DIR TMP_DIR LIBRARY
#       installs likewise and compares LIBRARY's dynamic symbols with the
#       functions and tables (the enums' name arrays) the installed headers
#       declare ISO_API: each must be the other's. Beyond them only the linker's own (_edata, _end,
#       __bss_start) and AddressSanitizer's __odr_asan.* may appear.
#   check_surface.sh libs BUILD_DIR TMP_DIR LIBRARY
#       installs likewise and compares the installed isoshape.pc's
#       Libs.private with the shared LIBRARY's NEEDED entries: every library
#       it needs is listed, and every library listed is needed, except the C
#       library's own parts (m, dl, pthread, rt), which glibc may provide
#       without a library of their own. The C library itself and a
#       sanitizer's runtime (ISO_SANITIZE: -fsanitize brings it) are not
#       listed.
#   check_surface.sh static BUILD_DIR TMP_DIR CC ARCHIVE [LDFLAGS...]
#       installs likewise with ARCHIVE (the library's objects as a static
#       archive) as the only libisoshape, then compiles and links a program
#       with `pkg-config --cflags` and `pkg-config --static --libs isoshape`,
#       every object of the archive forced in (--whole-archive), so that a
#       library missing from Libs.private is an undefined reference here;
#       the program must print the version isoshape.pc states.
#
# Exits 0 if all is well, 1 with the offenders listed, 77 (skip) with a
# reason when a tool it needs is missing.
set -u
mode=$1 build=$2 tmp=$3 tool=$4

skip() {
    echo "SKIP check_surface $mode: $*"
    exit 77
}
for t in cmake pkg-config nm; do
    command -v "$t" >/dev/null 2>&1 || skip "$t is not installed"
done
[ "$mode" != libs ] || command -v readelf >/dev/null 2>&1 || skip "readelf is not installed"

prefix=$tmp/surface-$mode
rm -rf "$prefix"
cmake --install "$build" --prefix "$prefix" >"$tmp/surface-$mode.log" 2>&1 || {
    cat "$tmp/surface-$mode.log"
    echo "check_surface: cmake --install $build --prefix $prefix failed"
    exit 1
}
headers=$prefix/include/isoshape
pc=$(find "$prefix" -name isoshape.pc | head -n 1)
[ -n "$pc" ] || { echo "check_surface: no isoshape.pc under $prefix"; exit 1; }
PKG_CONFIG_PATH=$(dirname "$pc")
export PKG_CONFIG_PATH

if [ "$mode" = headers ]; then
    cflags=$(pkg-config --cflags isoshape) || exit 1
    n=0 bad=0
    for h in "$headers"/*.h; do
        name=$(basename "$h")
        printf '#include "%s"\n#include "%s"\ntypedef int check_surface_one;\n' "$name" "$name" \
            >"$tmp/surface-one.c"
        # shellcheck disable=SC2086 # cflags is a list of options
        if ! "$tool" -std=c11 -Wall -Wextra -Werror -pedantic $cflags -fsyntax-only \
            "$tmp/surface-one.c" 2>"$tmp/surface-one.err"; then
            echo "installed header $name does not compile on its own:"
            cat "$tmp/surface-one.err"
            bad=$((bad + 1))
        fi
        n=$((n + 1))
    done
    [ "$n" -gt 0 ] || { echo "check_surface: no headers installed under $headers"; exit 1; }
    echo "$n installed headers, $bad that do not compile on their own"
    [ "$bad" -eq 0 ]
    exit
fi

if [ "$mode" = libs ]; then
    # the names: -lfoo and libfoo.so.N both as foo
    sed -n 's/^Libs.private://p' "$pc" | tr ' ' '\n' | sed -n 's/^-l//p' | sort -u \
        >"$tmp/surface-listed.txt"
    readelf -d "$tool" | sed -n 's/.*(NEEDED).*\[lib\(.*\)\.so.*\]/\1/p' |
        grep -v -x -e c -e asan -e ubsan -e tsan -e lsan | sort -u >"$tmp/surface-needed.txt"
    unlisted=$(comm -13 "$tmp/surface-listed.txt" "$tmp/surface-needed.txt")
    unneeded=$(comm -23 "$tmp/surface-listed.txt" "$tmp/surface-needed.txt" |
        grep -v -x -e m -e dl -e pthread -e rt)
    echo "Libs.private: $(tr '\n' ' ' <"$tmp/surface-listed.txt")"
    echo "$(basename "$tool") needs: $(tr '\n' ' ' <"$tmp/surface-needed.txt")"
    [ -z "$unlisted" ] || printf 'needed by the library but not in Libs.private:\n%s\n' "$unlisted"
    [ -z "$unneeded" ] || printf 'in Libs.private but not needed by the library:\n%s\n' "$unneeded"
    [ -z "$unlisted" ] && [ -z "$unneeded" ]
    exit
fi

if [ "$mode" = static ]; then
    archive=$5
    shift 5
    libdir=$(pkg-config --variable=libdir isoshape) || exit 1
    rm -f "$libdir"/libisoshape.so*
    [ "$archive" -ef "$libdir/libisoshape.a" ] || cp "$archive" "$libdir/libisoshape.a" || exit 1
    cat >"$tmp/surface-static-prog.c" <<'PROGRAM'
#include <stdio.h>
#include <string.h>

#include "iso_version.h"

int main(void)
{
    printf("%s\n", iso_version());
    return strcmp(iso_version(), ISO_VERSION_STRING) != 0 ||
           iso_version_number() != ISO_VERSION_NUMBER;
}
PROGRAM
    cflags=$(pkg-config --cflags isoshape) || exit 1
    libs=$(pkg-config --static --libs isoshape) || exit 1
    whole=$(printf '%s\n' "$libs" |
        sed 's/\(^\| \)-lisoshape\( \|$\)/ -Wl,--whole-archive -lisoshape -Wl,--no-whole-archive /')
    echo "linking with: $whole $*"
    # shellcheck disable=SC2086 # cflags and whole are lists of options
    "$tool" -std=c11 $cflags -o "$tmp/surface-static-prog" "$tmp/surface-static-prog.c" $whole "$@" || {
        echo "check_surface: a static link through pkg-config --static --libs isoshape failed"
        exit 1
    }
    got=$("$tmp/surface-static-prog") || { echo "check_surface: the static program failed ($got)"; exit 1; }
    want=$(pkg-config --modversion isoshape)
    echo "static program: iso_version() = $got, isoshape.pc: $want"
    [ "$got" = "$want" ]
    exit
fi

[ "$mode" = exports ] || { echo "check_surface: unknown mode '$mode'"; exit 2; }
# The name of each ISO_API function: the last identifier before the first
# '(' after ISO_API on its line (declarations keep the two on one line);
# and of each ISO_API table: the identifier before its '['.
{
    grep -ho 'ISO_API[^(]*(' "$headers"/*.h | sed -n 's/.*\b\(iso_[A-Za-z0-9_]*\) *($/\1/p'
    grep -ho 'ISO_API extern [^(]*\[' "$headers"/*.h | sed -n 's/.*\b\(iso_[A-Za-z0-9_]*\) *\[$/\1/p'
} | sort -u >"$tmp/surface-declared.txt"
nm -D --defined-only "$tool" | awk '{ print $NF }' |
    grep -v -e '^_edata$' -e '^_end$' -e '^__bss_start$' -e '^__odr_asan\.' |
    sort -u >"$tmp/surface-exported.txt"
extra=$(comm -13 "$tmp/surface-declared.txt" "$tmp/surface-exported.txt")
missing=$(comm -23 "$tmp/surface-declared.txt" "$tmp/surface-exported.txt")
echo "$(wc -l <"$tmp/surface-declared.txt") functions and tables declared ISO_API," \
    "$(wc -l <"$tmp/surface-exported.txt") exported by $(basename "$tool")"
[ -z "$extra" ] || printf 'exported but not declared ISO_API in an installed header:\n%s\n' "$extra"
[ -z "$missing" ] || printf 'declared ISO_API but not exported:\n%s\n' "$missing"
[ -z "$extra" ] && [ -z "$missing" ]
