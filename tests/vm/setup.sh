#!/bin/sh
# tests/vm/setup.sh -- the VM group's fixture: prepares, once per build
# folder, what every VM test boots (README.md in this folder says why each
# step is done the way it is).
#
#   usage: setup.sh VM_DIR SOURCE_DIR BINARY...
#
#   1. the kernel: Debian's linux-image-amd64 is resolved now (never pinned)
#      to its versioned image, downloaded with `apt-get download` (as any
#      user) and unpacked; the uncompressed vmlinux is cut out of the
#      bzImage (QEMU boots it through its PVH entry, 2-3 s sooner than the
#      bzImage's own xz decompression under TCG);
#   2. gpio-sim, which Debian does not build, out of tree from the matching
#      linux-source, linux-headers and linux-kbuild packages;
#   3. the base initramfs: busybox, the modules the tests load with their
#      dependencies, spacenavd, systemd-udevd (from the udev package), and
#      the system libraries the BINARYs need (ldd). Tests append their own
#      small archive to it.
#
# Everything lives under VM_DIR (the build folder) and is reused while the
# archive resolves to the same kernel and the BINARYs need the same
# libraries. When something cannot be had (no QEMU, no archive), this exits
# 77 and leaves the reason in VM_DIR/skip, which every VM test repeats.
set -eu

vm=$1
src=$2
shift 2
mkdir -p "$vm"
vm=$(cd "$vm" && pwd)
rm -f "$vm/skip" "$vm/env"
t_start=$(date +%s.%N)
date +%s.%N >"$vm/group_start"
: >"$vm/times"

skip() {
    echo "$*" >"$vm/skip"
    echo "SKIP vm_setup: $*"
    exit 77
}
say() { printf 'vm_setup: %s\n' "$*"; }
elapsed() { awk -v a="$1" -v b="$(date +%s.%N)" 'BEGIN { printf "%.1f", b - a }'; }

# ---- what the host must have ---------------------------------------------
qemu=$(command -v qemu-system-x86_64 || true)
[ -n "$qemu" ] || skip "qemu-system-x86_64 is not installed (apt-get install --no-install-recommends qemu-system-x86)"
bb=$(command -v busybox || true)
[ -n "$bb" ] || skip "busybox is not installed (apt-get install busybox-static)"
# A dynamic busybox would need its libraries in the guest before anything
# runs (ldd fails on a static one).
if ldd "$bb" >/dev/null 2>&1; then
    skip "$bb is dynamically linked; the guest's /init needs busybox-static (apt-get install busybox-static)"
fi
for tool in apt-get apt-cache dpkg-deb xz tar make gcc strip ldd; do
    command -v "$tool" >/dev/null || skip "$tool is not installed; the VM fixture needs it to prepare the kernel"
done

# ---- 1. the kernel --------------------------------------------------------
debs="$vm/debs"
mkdir -p "$debs"
# apt-get download writes into the current folder; as root it also warns
# that the _apt user cannot write there, which is harmless. Packages
# already here (name=version) are not fetched again.
fetch() {
    get=""
    for p in "$@"; do
        n=${p%%=*}
        v=${p#*=}
        [ "$v" != "$p" ] && ls "$debs/${n}_${v}_"*.deb >/dev/null 2>&1 && continue
        get="$get $p"
    done
    [ -n "$get" ] || return 0
    # shellcheck disable=SC2086
    if ! (cd "$debs" && apt-get download $get) >"$debs/fetch.log" 2>&1; then
        grep -v unsandboxed "$debs/fetch.log" >&2
        return 1
    fi
}
t=$(date +%s.%N)
meta_err=$(mktemp)
if (cd "$debs" && rm -f linux-image-amd64_*.deb && apt-get download linux-image-amd64) >"$meta_err" 2>&1; then
    meta=$(ls "$debs"/linux-image-amd64_*.deb)
    # Depends: linux-image-6.1.0-NN-amd64 (= 6.1.xxx-y)
    dep=$(dpkg-deb -f "$meta" Depends)
    pkg=$(echo "$dep" | sed -n 's/^\(linux-image-[^ ,]*\).*/\1/p')
    ver=$(echo "$dep" | sed -n 's/.*(= \([^)]*\)).*/\1/p')
    kver=${pkg#linux-image-}
    echo "$pkg $ver" >"$debs/resolved"
elif [ -s "$debs/resolved" ]; then
    read -r pkg ver <"$debs/resolved"
    kver=${pkg#linux-image-}
    say "cannot ask the archive ($(tail -1 "$meta_err")); using the kernel resolved before, $pkg $ver"
else
    why=$(tail -1 "$meta_err")
    rm -f "$meta_err"
    skip "cannot download linux-image-amd64 from the Debian archive ($why); the VM tests need it once per build folder"
fi
rm -f "$meta_err"
[ -n "$kver" ] && [ -n "$ver" ] || skip "linux-image-amd64 depends on '$dep', not on a versioned image"
upstream=$(echo "$ver" | sed 's/^\([0-9]*\.[0-9]*\).*/\1/') # 6.1
kdir="$vm/kernel/$kver"
# The image's half: vmlinux, and the modules the tests load with their
# dependencies (runs beside build_gpio_sim: each is mostly xz).
prepare_image() {
    img=$(ls "$debs/${pkg}_${ver}"_*.deb 2>/dev/null | head -1)
    [ -n "$img" ] || img=$(ls "$debs/$pkg"_*.deb | head -1)
    x="$kdir/x"
    mkdir -p "$x"
    # Only the bzImage and the module folders the tests use are written.
    dpkg-deb --fsys-tarfile "$img" |
        tar -x -C "$x" --wildcards './boot/vmlinuz-*' \
            "./lib/modules/$kver/kernel/drivers/hid/*" "./lib/modules/$kver/kernel/drivers/usb/*" \
            "./lib/modules/$kver/kernel/drivers/input/*" "./lib/modules/$kver/kernel/fs/configfs/*" \
            "./lib/modules/$kver/modules.builtin" "./lib/modules/$kver/modules.order"
    # vmlinux from the bzImage, as scripts/extract-vmlinux does: the xz
    # stream's first magic, decompressed until the stream ends.
    bz="$x/boot/vmlinuz-$kver"
    off=$(LC_ALL=C grep -abo "$(printf '\3757zXZ')" "$bz" | head -1 | cut -d: -f1)
    [ -n "$off" ] || skip "no xz stream in $bz (was the kernel built with another compressor?)"
    tail -c +$((off + 1)) "$bz" | xz -dc --single-stream >"$kdir/vmlinux" 2>/dev/null || true
    head -c 4 "$kdir/vmlinux" | grep -q 'ELF' || skip "could not extract vmlinux from $bz"
    m="$kdir/modules/lib/modules/$kver"
    mkdir -p "$m/extra"
    want="uhid hid-generic hid-logitech usbhid evdev configfs dummy_hcd libcomposite usb_f_hid usb_f_acm cdc-acm"
    done_list=" "
    while [ -n "$want" ]; do
        next=""
        for name in $want; do
            case "$done_list" in *" $name "*) continue ;; esac
            done_list="$done_list$name "
            # module names treat - and _ alike; files use either
            pat=$(echo "$name" | sed 's/[-_]/[-_]/g')
            f=$(find "$x/lib/modules/$kver/kernel" -name "$pat.ko" | head -1)
            [ -n "$f" ] || skip "module $name is not in $pkg"
            rel=${f#"$x/lib/modules/$kver/"}
            mkdir -p "$m/$(dirname "$rel")"
            strip --strip-debug -o "$m/$rel" "$f"
            # the .modinfo section's depends= string (busybox modinfo
            # would look for the running kernel's modules.dep)
            deps=$(tr '\0' '\n' <"$f" | sed -n 's/^depends=//p' | head -1 | tr ',' ' ')
            next="$next $deps"
        done
        want=$next
    done
    cp "$x/lib/modules/$kver/modules.builtin" "$x/lib/modules/$kver/modules.order" "$m/"
    # udev's daemon: the package's systemd-udevd is a link to udevadm, which
    # acts as the daemon when called by that name.
    mkdir -p "$kdir/udev"
    dpkg-deb -x "$(ls "$debs"/udev_*.deb | tail -1)" "$kdir/udev"
    [ -x "$kdir/udev/bin/udevadm" ] || skip "the udev package has no bin/udevadm"
    rm -f "$kdir/udev/lib/systemd/systemd-udevd"
    cp "$kdir/udev/bin/udevadm" "$kdir/udev/lib/systemd/systemd-udevd"
    rm -rf "$x"
}

# ---- 2. gpio-sim, out of tree ----------------------------------------------------
build_gpio_sim() {
    h="$kdir/headers"
    mkdir -p "$h"
    for d in "$debs/linux-headers-${kver}_${ver}"_*.deb "$debs/linux-headers-${common}-common_${ver}"_*.deb \
        "$debs/linux-kbuild-${upstream}_${ver}"_*.deb; do
        dpkg-deb -x "$d" "$h"
    done
    hk="$h/usr/src/linux-headers-$kver"
    # The flavour's Makefile includes the common one by its installed,
    # absolute path; point it into this tree (scripts/ and tools/ are
    # relative links into linux-kbuild already).
    sed -i "s|^include /usr/src/|include $h/usr/src/|" "$hk/Makefile"
    gs="$kdir/gpio-sim"
    mkdir -p "$gs"
    srcdeb=$(ls "$debs/linux-source-${upstream}_${ver}"_*.deb | head -1)
    # Three files of the source tarball; tar stops reading once it has
    # them (--occurrence), which ends the pipe early: that is expected.
    (dpkg-deb --fsys-tarfile "$srcdeb" | tar -xO "./usr/src/linux-source-$upstream.tar.xz" |
        xz -dc | tar -x -C "$gs" --strip-components=3 --occurrence=1 \
            "linux-source-$upstream/drivers/gpio/gpio-sim.c" \
            "linux-source-$upstream/drivers/gpio/gpiolib.h" \
            "linux-source-$upstream/kernel/irq/irq_sim.c") 2>/dev/null || true
    mv "$gs/gpio-sim.c" "$gs/gpio-sim-main.c" 2>/dev/null || true
    [ -f "$gs/gpio-sim-main.c" ] && [ -f "$gs/gpiolib.h" ] || skip "gpio-sim.c or gpiolib.h missing from linux-source-$upstream"
    # The irq simulator is built into the kernel only when a driver selects
    # it, and Debian's selects none: compile it into the module. Its
    # irq_to_desc() is not exported to modules; generic_handle_irq() does
    # the same lookup and call.
    sed -i 's/handle_simple_irq(irq_to_desc(irqnum))/generic_handle_irq(irqnum)/' "$gs/irq_sim.c"
    grep -q 'generic_handle_irq(irqnum)' "$gs/irq_sim.c" || skip "irq_sim.c of linux-source-$upstream changed; adapt tests/vm/setup.sh"
    printf 'obj-m := gpio-sim.o\ngpio-sim-y := gpio-sim-main.o irq_sim.o\n' >"$gs/Kbuild"
    make -s -C "$hk" M="$gs" modules >"$gs/build.log" 2>&1 ||
        { tail -20 "$gs/build.log"; skip "gpio-sim did not build against linux-headers-$kver (log: $gs/build.log)"; }
    rm -rf "$h"
}

if [ ! -f "$kdir/ready" ]; then
    rm -rf "$kdir"
    mkdir -p "$kdir"
    flavour=${kver##*-}          # amd64
    common=${kver%-"$flavour"}   # 6.1.0-NN
    need="$pkg=$ver linux-headers-$kver=$ver linux-headers-$common-common=$ver linux-kbuild-$upstream=$ver linux-source-$upstream=$ver udev"
    # shellcheck disable=SC2086
    fetch $need || skip "cannot download $need from the Debian archive"
    say "downloaded $pkg $ver and its build packages in $(elapsed "$t") s"
    t=$(date +%s.%N)
    # Both halves at once (each exits 77 through skip, leaving the reason).
    (prepare_image) &
    image_job=$!
    (build_gpio_sim) || { wait "$image_job"; exit 77; }
    wait "$image_job" || exit 77
    say "kernel $kver: vmlinux, modules and gpio-sim (built out of tree) ready in $(elapsed "$t") s"
    m="$kdir/modules/lib/modules/$kver"
    strip --strip-debug -o "$m/extra/gpio-sim.ko" "$kdir/gpio-sim/gpio-sim.ko"
    "$bb" depmod -b "$kdir/modules" "$kver"
    echo "$pkg $ver" >"$kdir/ready"
fi

# ---- 3. the base initramfs --------------------------------------------------
# Cached by kernel and by the libraries the binaries need: the system's only
# (the project's own, libisoshape, change with every build and go into each
# test's archive).
spnavd=$(command -v spacenavd || true)
[ -n "$spnavd" ] || skip "spacenavd is not installed (apt-get install spacenavd)"
libs=$(for b in "$@" "$spnavd" "$kdir/udev/lib/systemd/systemd-udevd" \
    /usr/bin/gpioinfo /usr/bin/gpioget; do
    [ -e "$b" ] || continue
    ldd "$b" 2>/dev/null | awk '/=> \// { print $3 } /^[ \t]*\/[^ ]*ld-linux/ { print $1 }'
done | grep -E '^/(usr/)?lib(64)?/' | sort -u)
missing=$(for b in "$@" "$spnavd" "$kdir/udev/lib/systemd/systemd-udevd"; do
    [ -e "$b" ] && ldd "$b" 2>/dev/null | awk '/not found/ { print $1 }'
done | sort -u | tr '\n' ' ')
[ -z "$missing" ] || skip "libraries not installed here: $missing"
key=$( (echo "$kver"; cat "$src/tests/vm/guest/init"; echo "$libs"; ls -l "$bb" "$spnavd") | cksum | cut -d' ' -f1)
base="$vm/base-$kver-$key.cpio"
if [ ! -f "$base" ]; then
    t=$(date +%s.%N)
    rm -f "$vm"/base-*.cpio
    r="$vm/base-root"
    rm -rf "$r"
    mkdir -p "$r/bin" "$r/sbin" "$r/usr/bin" "$r/usr/sbin" "$r/dev" "$r/proc" "$r/sys" "$r/tmp" \
        "$r/run" "$r/etc/udev/rules.d" "$r/lib/systemd" "$r/var" "$r/out" "$r/test"
    ln -s /run "$r/var/run"
    cp "$bb" "$r/bin/busybox"
    cp "$src/tests/vm/guest/init" "$r/init"
    chmod 755 "$r/init"
    cp -a "$kdir/modules/lib" "$r/"
    cp "$spnavd" "$r/usr/sbin/spacenavd"
    cp "$kdir/udev/lib/systemd/systemd-udevd" "$r/lib/systemd/"
    for tool in gpioinfo gpioget gpiodetect; do
        [ -x "/usr/bin/$tool" ] && cp "/usr/bin/$tool" "$r/usr/bin/"
    done
    for l in $libs; do
        mkdir -p "$r$(dirname "$l")"
        cp -L "$l" "$r$l"
    done
    echo "$libs" >"$vm/base-libs"
    (cd "$r" && find . | "$bb" cpio -o -H newc -R 0:0 2>/dev/null) >"$base.tmp"
    mv "$base.tmp" "$base"
    rm -rf "$r"
    say "base initramfs $(du -m "$base" | cut -f1) MB built in $(elapsed "$t") s"
fi

kvm=0
if [ -r /dev/kvm ] && [ -w /dev/kvm ] && grep -qE '(vmx|svm)' /proc/cpuinfo; then
    kvm=1
fi
{
    echo "QEMU=$qemu"
    echo "KVER=$kver"
    echo "VMLINUX=$kdir/vmlinux"
    echo "BASE=$base"
    echo "KVM=$kvm"
} >"$vm/env"
echo "setup $(elapsed "$t_start")" >>"$vm/times"
say "ready: kernel $kver ($pkg $ver), $( [ $kvm = 1 ] && echo KVM || echo 'TCG: /dev/kvm cannot run a stock kernel here'), setup took $(elapsed "$t_start") s"
