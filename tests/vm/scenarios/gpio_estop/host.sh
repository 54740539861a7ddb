# The press and the vanished line in the recording and the commands: the
# e-stop holds from the press to the release and from the chip's
# disappearance to the end; the recording replays here to the VM run's
# bits; the bound from the line's edge to the MCU's safe state is printed.
. "$VM_HOST_LIB"
replay_same_bits estop
estop_report estop
