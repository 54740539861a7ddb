# Both layouts: each recording replays here to its VM run's bits and holds
# the sequence played (hidraw's bytes do not depend on the layout).
. "$VM_HOST_LIB"
for layout in rel fixup; do
    replay_same_bits $layout
    check_sequence $layout spacemouse.seq
done
