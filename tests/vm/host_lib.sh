# tests/vm/host_lib.sh -- the host's half of the VM tests (sourced by a
# scenario's host.sh, run by run.sh in the test's output folder with the
# guest's /out in ./out). $ISO_BIN is the isoshape command, $CHECK_REC the
# checker, $SCEN the scenario's folder, $VM_DATA the shared data.
export OPENBLAS_NUM_THREADS=1
export OPENBLAS_CORETYPE=Haswell

# The scenes' sensitivity at full deflection (m/s, rad/s). Small on
# purpose: a live tick that falls behind (TCG on a loaded machine) is
# split into sub-steps by its motion, which a replay does not repeat; at
# these speeds a tick needs one step however late (up to ~3 s).
VM_LIN=0.02
VM_ROT=0.005

hfail() {
    echo "FAIL (host): $*"
    exit 1
}

# replay_scene NAME SCENE: the scene with its live device replaced by the
# recording the VM made (out/NAME.isorec), as NAME.yaml.
replay_scene() {
    awk -v rec="$PWD/out/$1.isorec" '
        /^devices:/ { print; print "  - {name: mouse, kind: replay, file: " rec "}"; skip = 1; next }
        skip && /^  - / { next }
        { skip = 0; print }' "$2" >"$1.yaml"
}

# replay_same_bits NAME [SCENE]: the VM's live run NAME and the host's
# replay of its recording move the mesh to the same bits (the vertices'
# checksum), and `isoshape replay` gives the same commands checksum here as
# in the VM. SCENE: the scenario's scene.yaml unless given.
replay_same_bits() {
    replay_scene "$1" "${2:-$SCEN/scene.yaml}"
    "$ISO_BIN" run "$1.yaml" --fast --no-display >"$1.replay.log" 2>&1 ||
        { cat "$1.replay.log"; hfail "the replay of $1 failed"; }
    live=$(sed -n 's/.*vertices checksum \([0-9a-f]*\).*/\1/p' "out/$1.log" | tail -1)
    here=$(sed -n 's/.*vertices checksum \([0-9a-f]*\).*/\1/p' "$1.replay.log" | tail -1)
    sub=$(sed -n 's/.*"substeps": *\([0-9]*\).*/\1/p' "out/$1.json")
    echo "$1: vertices checksum: VM live run $live, host replay $here (live sub-steps: ${sub:-?})"
    [ -n "$live" ] && [ "$live" = "$here" ] ||
        { cat "$1.replay.log"; hfail "$1: the host's replay does not give the VM run's vertices"; }
    "$ISO_BIN" replay "out/$1.isorec" --fast >"$1.cmds" 2>&1 || { cat "$1.cmds"; hfail "isoshape replay $1 failed"; }
    vm_cmds=$(sed -n 's/.*commands checksum \([0-9a-f]*\).*/\1/p' "out/$1.replay")
    host_cmds=$(sed -n 's/.*commands checksum \([0-9a-f]*\).*/\1/p' "$1.cmds")
    echo "$1: isoshape replay's commands checksum: in the VM $vm_cmds, on the host $host_cmds"
    [ -n "$vm_cmds" ] && [ "$vm_cmds" = "$host_cmds" ] || hfail "$1: isoshape replay gives other commands here than in the VM"
}

# check_sequence NAME SEQ [LIN ROT]: the recording out/NAME.isorec holds
# the sequence the guest played (check_rec.c), mapped with the scenes'
# sensitivity (or LIN and ROT).
check_sequence() {
    lin=${3:-$VM_LIN}
    rot=${4:-$VM_ROT}
    "$ISO_BIN" replay "out/$1.isorec" --fast --print-ticks --sensitivity "$lin,$rot" \
        >"$1.ticks" 2>"$1.ticks.err" || { cat "$1.ticks.err"; hfail "isoshape replay --print-ticks failed"; }
    "$CHECK_REC" "$VM_DATA/$2" "out/$1.isorec" "$1.ticks" "$lin" "$rot" | tee "$1.check"
    grep -q "^check_rec: the recording is the sequence" "$1.check" ||
        hfail "$1: the recording is not the sequence played"
}

# gone_within NAME: the recording out/NAME.isorec marks its source GONE
# within one tick of the moment hidplay logged "mark kill" (the daemon's
# kill): the tick period plus the longest tick of that run (its summary),
# the stated bound; prints the measured time.
gone_within() {
    kill_ns=$(sed -n 's/^\([0-9]*\) kill$/\1/p' out/marks)
    gone_ns=$(sed -n 's/^GONE src 0 at \([0-9]*\) ns$/\1/p' "$1.check" | head -1)
    [ -n "$kill_ns" ] && [ -n "$gone_ns" ] || hfail "$1: no kill mark or no GONE record"
    awk -v k="$kill_ns" -v g="$gone_ns" -v j="$(cat "out/$1.json")" 'BEGIN {
        match(j, /"period_ms": *[0-9.]+/); p = substr(j, RSTART, RLENGTH); sub(/.*: */, "", p)
        match(j, /"tick_ms": *\{[^}]*"max": *[0-9.]+/); m = substr(j, RSTART, RLENGTH); sub(/.*"max": */, "", m)
        d = (g - k) / 1e6; b = p + m
        printf "%s: spacenavd killed; the run marked it gone %.1f ms later (bound: one tick, %.1f ms period + %.1f ms longest tick = %.1f ms)\n", ARGV[1], d, p, m, b
        exit !(d >= 0 && d <= b) }' "$1" || hfail "$1: the source went GONE later than one tick after the kill"
}

# marks_vs_records NAME: the guest's marks (out/marks: CLOCK_MONOTONIC ns
# and a word) beside the recording's GONE and BACK records (the check's
# output, NAME.check): each printed relative to the first mark. GONE must
# follow the unplug, BACK the plug.
marks_vs_records() {
    { cat out/marks; sed -n 's/^\(GONE\|BACK\) src 0 at \([0-9]*\) ns$/\2 \1-recorded/p' "$1.check"; } |
        sort -n | awk '
        NR == 1 { t0 = $1 }
        { printf "  %8.1f ms  %s\n", ($1 - t0) / 1e6, $2; at[$2] = $1 }
        END {
            if (!("GONE-recorded" in at) || !("BACK-recorded" in at)) { print "no GONE or BACK record"; exit 1 }
            if (at["GONE-recorded"] < at["unplug"] || at["BACK-recorded"] < at["plug"]) { print "out of order"; exit 1 }
            printf "unplug to GONE %.1f ms; replug to BACK %.1f ms (enumeration, binding, then the hub: libusb hotplug or its 500 ms retry)\n",
                (at["GONE-recorded"] - at["unplug"]) / 1e6, (at["BACK-recorded"] - at["plug"]) / 1e6 }' || hfail "$1: GONE and BACK do not follow the unplug and the plug"
}

# estop_report NAME: the e-stop's course in run NAME. From the recording
# (the kernel's edge times), the guest's marks and the run's stamped
# output, all CLOCK_MONOTONIC in the guest: how long from the line's edge
# to the run's E-STOP notice and to the MCU's report of its safe state (an
# upper bound: it includes printing and the pipe), for the press and for
# the line that went away. The press must bring the MCU to its safe state
# within 250 ms of the edge: the loop watchdog's default bound, the
# slowest way to safety the sink promises (natively it takes a few ms,
# tests/test_actuators.c; TCG runs 10 to 50 times slower). The replayed commands must hold the e-stop from
# the press to the release and from the chip's going to the end.
estop_report() {
    "$CHECK_REC" --events "out/$1.isorec" >"$1.events"
    "$ISO_BIN" replay "out/$1.isorec" --fast --print-ticks >"$1.ticks" 2>"$1.ticks.err" ||
        { cat "$1.ticks.err"; hfail "isoshape replay --print-ticks failed"; }
    # e-stop flag per tick: 0 ... 1 ... 0 ... 1 to the end
    awk '!/^[0-9.]+ h[0-9]/ { next } { e = / ESTOP/ ? 1 : 0; if (seq == "" || e != last) { seq = seq e; last = e } }
         END { print "e-stop in the replayed commands, tick by tick, as runs: " seq; exit seq != "0101" }' "$1.ticks" ||
        hfail "$1: the commands do not hold the e-stop exactly from the press to the release and from the vanished line on"
    { sed 's/^/M /' out/marks; sed 's/^/R /' "$1.events"; sed 's/^/S /' "out/$1.stamped"; } | awk '
        $1 == "M" { m[$3] = $2 }
        $1 == "R" && $3 == "estop" && $4 == 1 && !press { press = $2 }
        $1 == "R" && $3 == "GONE" && !gone { gone = $2 }
        $1 == "S" && /E-STOP/ { if (!stop1) stop1 = $2; else if (!stop2) stop2 = $2 }
        $1 == "S" && /reports its safe state/ {
            if (!safe1) { safe1 = $2; own1 = $0 } else if (!safe2) { safe2 = $2; own2 = $0 } }
        END {
            if (!press || !safe1 || !gone || !safe2) { print "missing: press " press " safe " safe1 " gone " gone " safe " safe2; exit 1 }
            sub(/.*safe state/, "safe state", own1); sub(/.*safe state/, "safe state", own2)
            printf "e-stop pressed: the line edge %.1f ms after the guest wrote the pull; E-STOP notice %.1f ms and the MCU safe (reported) %.1f ms after the edge; the sink: %s\n",
                (press - m["press"]) / 1e6, (stop1 - press) / 1e6, (safe1 - press) / 1e6, own1
            printf "e-stop line gone: GONE %.1f ms after the chip was removed; E-STOP notice %.1f ms and the MCU safe (reported) %.1f ms after it; the sink: %s\n",
                (gone - m["vanish"]) / 1e6, (stop2 - m["vanish"]) / 1e6, (safe2 - m["vanish"]) / 1e6, own2
            if ((safe1 - press) / 1e6 > 250) { print "the MCU was safe later than 250 ms after the edge"; exit 1 }
        }' || hfail "$1: the press or the vanished line did not bring the MCU to its safe state"
}

# fb_report NAME: the firmware bridge's course: setpoints the MCU applied,
# its state changes relative to the cable's unplug and replug (marks), and
# the run's counts.
fb_report() {
    { sed 's/^/M /' out/marks; awk 'NF == 3 && $2 == "state" { printf "S %.0f %s\n", $1 * 1e6, $3 }' out/mcu.log; } |
        sort -k2 -n | awk '
        NR == 1 { t0 = $2 }
        $1 == "M" { printf "  %8.1f ms  cable %s\n", ($2 - t0) / 1e6, $3 }
        $1 == "S" { printf "  %8.1f ms  MCU %s\n", ($2 - t0) / 1e6, $3 }'
    grep '^end:' out/mcu.log
    sed -n 's/.*"actuators": "\([^"]*\)".*/\1/p' "out/$1.json"
    applied=$(sed -n 's/^end: \([0-9]*\) setpoints applied.*/\1/p' out/mcu.log)
    [ "${applied:-0}" -gt 0 ] || hfail "$1: the MCU applied no setpoints"
}
