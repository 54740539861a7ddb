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

# The scene with its live device replaced by the recording the VM made.
replay_scene() {
    awk -v rec="$PWD/out/run.isorec" '
        /^devices:/ { print; print "  - {name: mouse, kind: replay, file: " rec "}"; skip = 1; next }
        skip && /^  - / { next }
        { skip = 0; print }' "$SCEN/scene.yaml" >replay.yaml
}

# The VM's live run and the host's replay of its recording move the mesh to
# the same bits (the vertices' checksum).
replay_same_bits() {
    replay_scene
    "$ISO_BIN" run replay.yaml --fast --no-display >replay.log 2>&1 || { cat replay.log; hfail "the replay failed"; }
    live=$(sed -n 's/.*vertices checksum \([0-9a-f]*\).*/\1/p' out/run.log | tail -1)
    here=$(sed -n 's/.*vertices checksum \([0-9a-f]*\).*/\1/p' replay.log | tail -1)
    sub=$(sed -n 's/.*"substeps": *\([0-9]*\).*/\1/p' out/stats.json)
    echo "vertices checksum: VM live run $live, host replay $here (live sub-steps: ${sub:-?})"
    [ -n "$live" ] && [ "$live" = "$here" ] || { cat replay.log; hfail "the host's replay does not give the VM run's vertices"; }
}

# The recording holds the sequence the guest played (check_rec.c), mapped
# with the scenes' sensitivity (data/mapping.yaml's).
check_sequence() {
    "$ISO_BIN" replay out/run.isorec --fast --print-ticks --sensitivity "$VM_LIN,$VM_ROT" \
        >ticks.txt 2>replay_ticks.err || { cat replay_ticks.err; hfail "isoshape replay --print-ticks failed"; }
    "$CHECK_REC" "$VM_DATA/$1" out/run.isorec ticks.txt "$VM_LIN" "$VM_ROT" ||
        hfail "the recording is not the sequence played"
}
