# The host's half: the recording replays here to the VM run's bits, and it
# holds the sequence the guest played.
. "$VM_HOST_LIB"
replay_same_bits uhid
check_sequence uhid spacemouse.seq
replay_same_bits slow "$SCEN/scene_slow.yaml"
check_sequence slow overflow.seq 0.005 0.001
