# spacenavd's axes came back to the device's own: the recordings hold the
# sequence played (in the device's frame and counts, both layouts), and
# replay here to the VM runs' bits. The kill: GONE is recorded within the
# stated bound of the kill, and input flows again after BACK.
. "$VM_HOST_LIB"
for layout in abs rel; do
    replay_same_bits $layout
done
check_sequence rel spacemouse.seq
check_sequence abs spacemouse_kill.seq
gone_within abs
# Nothing went away in the run nobody unplugged: a GONE there would be the
# hub's own doing, not the device's.
! grep -q "went away" out/rel.log || hfail "rel: the run said a source went away, and nothing was killed"
