# The unplug in the recording: GONE, rest while gone, BACK, motion again;
# it replays here to the VM run's bits. The times from the cable to the
# run's notice, and from the replug to BACK, are printed.
. "$VM_HOST_LIB"
replay_same_bits usb
check_sequence usb hotplug.expect
marks_vs_records usb
