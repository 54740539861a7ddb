# tests/vm/guest/lib.sh -- what the guest scripts share (sourced from
# /test/run.sh as /test/lib.sh): loading modules, waiting, USB gadgets on
# dummy_hcd, udevd, spacenavd, the scripted HID device, and checks.
# busybox sh; every failure ends the test with a sentence.

export OPENBLAS_NUM_THREADS=1
# The same BLAS kernels as the host's replay, whatever the CPU model says.
export OPENBLAS_CORETYPE=Haswell
ISO=$(cat /test/isoshape.path)
HIDPLAY=$(cat /test/hidplay.path 2>/dev/null)
OUT=/out
G=/sys/kernel/config/usb_gadget

fail() {
    echo "FAIL: $*"
    exit 1
}
note() { echo "vm $(cut -d' ' -f1 /proc/uptime): $*"; }

mods() {
    for m in "$@"; do
        modprobe "$m" || fail "modprobe $m"
    done
}

# wait_for TEST_ARGS... : polls `test ARGS` every 50 ms for up to WAIT_S
# seconds (default 20: TCG is slow).
wait_for() {
    n=$((${WAIT_S:-20} * 20))
    while ! test "$@"; do
        n=$((n - 1))
        [ "$n" -gt 0 ] || return 1
        usleep 50000
    done
}

# wait_line FILE PATTERN: until FILE has a line matching PATTERN.
wait_line() {
    n=$((${WAIT_S:-20} * 20))
    while ! grep -q "$2" "$1" 2>/dev/null; do
        n=$((n - 1))
        [ "$n" -gt 0 ] || return 1
        usleep 50000
    done
}

# ---- the scripted HID device ---------------------------------------------------
# hid_start ARGS...: hidplay ARGS in the background, commands through fifos.
hid_start() {
    rm -f /tmp/hid.in /tmp/hid.out
    mkfifo /tmp/hid.in /tmp/hid.out
    "$HIDPLAY" "$@" </tmp/hid.in >/tmp/hid.out 2>"$OUT/hidplay.err" &
    HID_PID=$!
    exec 7>/tmp/hid.in 8</tmp/hid.out
}
# hid CMD: one command, waits for its answer; hid_send and hid_wait split
# the two, to act while a step plays.
hid_send() {
    HID_CMD=$*
    echo "$*" >&7
}
hid_wait() {
    read -r reply <&8 || fail "hidplay died during '$HID_CMD' ($(cat "$OUT/hidplay.err"))"
    [ "$reply" = ok ] || fail "hidplay: '$HID_CMD': $reply"
}
hid() {
    hid_send "$@"
    hid_wait
}
hid_stop() {
    echo quit >&7
    wait "$HID_PID"
    exec 7>&- 8<&-
}

# ---- USB gadgets on dummy_hcd ---------------------------------------------------
gadget_init() {
    mods configfs dummy_hcd libcomposite
    grep -q configfs /proc/mounts || mount -t configfs none /sys/kernel/config
    UDC=$(ls /sys/class/udc | head -1)
    [ -n "$UDC" ] || fail "no UDC after loading dummy_hcd"
}

# gadget_new NAME VID PID PRODUCT
gadget_new() {
    g=$G/$1
    mkdir -p "$g/strings/0x409" "$g/configs/c.1/strings/0x409"
    echo "0x$2" >"$g/idVendor"
    echo "0x$3" >"$g/idProduct"
    echo 0x0200 >"$g/bcdUSB"
    echo 0x0100 >"$g/bcdDevice"
    echo 3Dconnexion >"$g/strings/0x409/manufacturer"
    echo "$4" >"$g/strings/0x409/product"
    echo "vm-$1" >"$g/strings/0x409/serialnumber"
    echo config >"$g/configs/c.1/strings/0x409/configuration"
    echo 100 >"$g/configs/c.1/MaxPower"
}

# gadget_hid NAME DESCFILE: a HID function with 7-byte reports
gadget_hid() {
    f=$G/$1/functions/hid.usb0
    mkdir -p "$f"
    echo 0 >"$f/protocol"
    echo 0 >"$f/subclass"
    echo 7 >"$f/report_length"
    cat "$2" >"$f/report_desc"
    ln -s "$f" "$G/$1/configs/c.1/"
}

gadget_acm() {
    f=$G/$1/functions/acm.usb0
    mkdir -p "$f"
    ln -s "$f" "$G/$1/configs/c.1/"
}

gadget_plug() { echo "$UDC" >"$G/$1/UDC" || fail "cannot bind gadget $1 to $UDC"; }
gadget_unplug() { echo "" >"$G/$1/UDC" || fail "cannot unbind gadget $1"; }

# ---- daemons --------------------------------------------------------------------
udevd_start() {
    /lib/systemd/systemd-udevd --daemon --resolve-names=never || fail "systemd-udevd did not start"
}

# spacenavd in the foreground mode, from / (it binds run/spnav.sock
# relative to its working folder), with the socket where libspnav looks;
# returns once it serves a device. Its log (it truncates its own) is
# /out/spacenavd.N.log for the N-th start.
SPNAV_N=0
spacenavd_start() {
    SPNAV_N=$((SPNAV_N + 1))
    SPNAV_LOG=$OUT/spacenavd.$SPNAV_N.log
    (cd / && exec /usr/sbin/spacenavd -d -v -l "$SPNAV_LOG" >/dev/null 2>&1) &
    SPNAV_PID=$!
    wait_for -S /var/run/spnav.sock || fail "spacenavd made no socket ($(tail -3 "$SPNAV_LOG"))"
    wait_line "$SPNAV_LOG" "using device" || fail "spacenavd did not take the device ($(tail -5 "$SPNAV_LOG"))"
}
spacenavd_kill() {
    kill -9 "$SPNAV_PID"
    wait "$SPNAV_PID" 2>/dev/null
    rm -f /var/run/spnav.sock
}

# hidraw_of VID PID: the hidraw node of the device with those ids.
hidraw_of() {
    for h in /sys/class/hidraw/hidraw*; do
        [ -e "$h" ] || continue
        grep -qi "HID_ID=.*:0000$1:0000$2" "$h/device/uevent" && echo "/dev/$(basename "$h")" && return 0
    done
    return 1
}

# wait_cmd CMD...: runs CMD every 50 ms until it succeeds (WAIT_S seconds).
wait_cmd() {
    n=$((${WAIT_S:-20} * 20))
    while ! "$@" >/dev/null 2>&1; do
        n=$((n - 1))
        [ "$n" -gt 0 ] || return 1
        usleep 50000
    done
}

# ---- the project's own command ------------------------------------------------
# scene_start NAME SCENE [OPTIONS...]: `isoshape run` in the background,
# live, recording to /out/NAME.isorec (log NAME.log, summary NAME.json);
# returns once it has opened its devices. No real-time scheduling: on the
# one emulated CPU a SCHED_FIFO loop that falls behind would starve the
# device it reads.
scene_start() {
    RUN=$1
    s=$2
    shift 2
    # Its output goes to NAME.log, and to NAME.stamped each line behind the
    # time it arrived, for bounds measured against the recording's clock.
    (
        "$ISO" run "$s" --no-display --no-rt --duration 3600 --record "$OUT/$RUN.isorec" \
            --stats-json "$OUT/$RUN.json" "$@"
        echo $? >/tmp/run.rc
    ) 2>&1 | "$HIDPLAY" stamp "$OUT/$RUN.log" "$OUT/$RUN.stamped" &
    RUN_JOB=$!
    wait_line "$OUT/$RUN.log" "${SCENE_UP:-device 0:}" || fail "isoshape run did not start: $(cat "$OUT/$RUN.log")"
    ISO_PID=$(pidof isoshape)
    note "isoshape run is up: $(grep "${SCENE_UP:-device 0:}" "$OUT/$RUN.log" | head -1)"
}
# scene_stop: SIGTERM, as a user's Ctrl-C or a service manager would: the
# run ends after its tick, closes the recording whole, prints its summary
# and exits 143.
scene_stop() {
    kill -TERM "$ISO_PID"
    wait "$RUN_JOB"
    st=$(cat /tmp/run.rc)
    cat "$OUT/$RUN.log"
    [ "$st" = 143 ] || fail "isoshape run exited $st after SIGTERM, not 143"
    grep -q "vertices checksum" "$OUT/$RUN.log" || fail "isoshape run printed no summary"
    # the recording's commands here, to be compared with the host's (a
    # scene without devices records nothing)
    if [ -f "$OUT/$RUN.isorec" ]; then
        "$ISO" replay "$OUT/$RUN.isorec" --fast >"$OUT/$RUN.replay" 2>&1 || fail "isoshape replay failed here"
    fi
}

# gadget_remove NAME: unplugged already; takes its configfs tree down.
gadget_remove() {
    g=$G/$1
    for f in "$g"/configs/c.1/*.usb0; do
        [ -e "$f" ] && rm "$f"
    done
    rmdir "$g/configs/c.1/strings/0x409" "$g/configs/c.1"
    for f in "$g"/functions/*; do
        [ -e "$f" ] && rmdir "$f"
    done
    rmdir "$g/strings/0x409" "$g"
}
no_hidraw() { ! hidraw_of "$@"; }

# mark TEXT: TEXT with CLOCK_MONOTONIC (the clock of every recorded chunk)
# into /out/marks, for bounds the host measures.
mark() { echo "$("$HIDPLAY" now) $*" >>"$OUT/marks"; }
