#!/bin/sh
# tests/vm/run.sh -- one VM test: packs the test's own archive, boots the
# kernel the fixture prepared in QEMU with a time limit, reads back what the
# guest left in /out, runs the host's half of the checks, and exits with
# the guest test's status (77 with the reason when QEMU or the kernel could
# not be had).
#
#   usage: run.sh VM_DIR SCENARIO_DIR LIMIT_S [FILE...]
#
# SCENARIO_DIR holds guest.sh (the guest's /test/run.sh) and optionally
# host.sh (run here afterwards, in the test's output folder, with the
# guest's /out in ./out) and any other files the scenario needs; they all go
# into /test. Each FILE (the project's programs) goes in at its own path,
# with the libraries ldd lists that the base archive lacks, so the programs
# run unchanged: their RUNPATH still finds libisoshape where it was built.
# The guest script finds the common helpers in /test/lib.sh.
set -eu

vm=$(cd "$1" && pwd)
scen=$(cd "$2" && pwd)
limit=$3
shift 3
name=$(basename "$scen")
here=$(cd "$(dirname "$0")" && pwd)

if [ -s "$vm/skip" ]; then
    echo "SKIP vm_$name: $(cat "$vm/skip")"
    exit 77
fi
if [ ! -s "$vm/env" ]; then
    echo "SKIP vm_$name: the VM fixture has not run (ctest runs vm_setup first; run it, e.g. ctest -R vm_)"
    exit 77
fi
. "$vm/env"
for f in "$QEMU" "$VMLINUX" "$BASE"; do
    if [ ! -e "$f" ]; then
        echo "SKIP vm_$name: $f is gone; run vm_setup again"
        exit 77
    fi
done

out="$vm/run/$name"
rm -rf "$out"
mkdir -p "$out/root/test" "$out/root/out" "$out/out"
t0=$(date +%s.%N)
elapsed() { awk -v a="$1" -v b="$(date +%s.%N)" 'BEGIN { printf "%.1f", b - a }'; }

# ---- the test's archive -----------------------------------------------------
r="$out/root"
cp -a "$scen/." "$r/test/"
cp "$here/guest/lib.sh" "$r/test/lib.sh"
cp "$here/data/"* "$r/test/"
mv "$r/test/guest.sh" "$r/test/run.sh"
chmod 755 "$r/test/run.sh"
rm -f "$r/test/host.sh"
for f in "$@"; do
    mkdir -p "$r$(dirname "$f")"
    # Debug information is not needed to run; it would triple the archive.
    strip --strip-debug -o "$r$f" "$f" 2>/dev/null || cp "$f" "$r$f"
    chmod 755 "$r$f"
    # where the guest script finds it: /test/isoshape.path, /test/hidplay.path
    base=$(basename "$f")
    echo "$f" >"$r/test/${base#vm_}.path"
    ldd "$f" 2>/dev/null | awk '/=> \// { print $3 }' | while read -r l; do
        grep -qx "$l" "$vm/base-libs" && continue
        [ -e "$r$l" ] && continue
        mkdir -p "$r$(dirname "$l")"
        strip --strip-debug -o "$r$l" "$l" 2>/dev/null || cp -L "$l" "$r$l"
    done
done
(cd "$r" && find . | busybox cpio -o -H newc -R 0:0 2>/dev/null) >"$out/test.cpio"
cat "$BASE" "$out/test.cpio" >"$out/initrd"

# ---- boot -------------------------------------------------------------------
# TCG unless KVM can run a stock kernel here (the fixture checked for vmx
# or svm: a paravirtual /dev/kvm cannot). The console goes to a file: with
# stdin at /dev/null, -serial stdio floods it with NULs.
if [ "$KVM" = 1 ]; then
    accel="-accel kvm -cpu host"
else
    accel="-accel tcg -cpu max"
fi
# Kernel work a throw-away test VM does not need is switched off: each
# costs boot time under TCG.
append="console=ttyS0 loglevel=4 panic=-1 tsc=reliable no_timer_check mitigations=off"
append="$append cryptomgr.notests audit=0 apparmor=0 security=none ${VM_APPEND:-}"
t1=$(date +%s.%N)
set +e
# shellcheck disable=SC2086
timeout -k 5 "$limit" "$QEMU" $accel -m "${VM_MEM:-1024}" -smp 1 -M pc -nodefaults \
    -display none -no-reboot -monitor none \
    -kernel "$VMLINUX" -initrd "$out/initrd" -append "$append" \
    -serial "file:$out/console.log" -serial "file:$out/out.tar" </dev/null >"$out/qemu.log" 2>&1
qrc=$?
set -e
boot_s=$(elapsed "$t1")
if [ "$qrc" = 124 ] || [ "$qrc" = 137 ]; then
    echo "vm_$name: the VM did not finish within ${limit} s; its console:"
    tail -n 80 "$out/console.log"
    echo "vm_$name: FAILED (time limit ${limit} s; console in $out/console.log)"
    exit 1
fi
if [ "$qrc" != 0 ]; then
    cat "$out/qemu.log"
    echo "vm_$name: FAILED: QEMU exited with $qrc"
    exit 1
fi
tr -d '\000' <"$out/console.log" | sed -e 's/\r$//' -e 's/^/  | /'
if ! tar -x -f "$out/out.tar" -C "$out/out" 2>/dev/null || [ ! -s "$out/out/rc" ]; then
    echo "vm_$name: FAILED: the guest handed back no exit status (it crashed or powered off early)"
    exit 1
fi
rc=$(cat "$out/out/rc")
guest_s=$(cat "$out/out/uptime")
echo "vm_$name: guest exit status $rc; VM ${boot_s} s wall (guest clock ${guest_s} s), archive $(du -k "$out/test.cpio" | cut -f1) KB"

# ---- the host's half ----------------------------------------------------------
if [ "$rc" = 0 ] && [ -f "$scen/host.sh" ]; then
    set +e
    (cd "$out" && SCEN="$scen" VM_DATA="$here/data" VM_HOST_LIB="$here/host_lib.sh" sh "$scen/host.sh")
    rc=$?
    set -e
fi
echo "$name $(elapsed "$t0")" >>"$vm/times"
echo "vm_$name: $( [ "$rc" = 0 ] && echo passed || echo "FAILED (status $rc)") in $(elapsed "$t0") s"
exit "$rc"
