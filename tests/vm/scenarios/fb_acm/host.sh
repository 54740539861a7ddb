# What the MCU applied and how the link went, from its log and the run's.
. "$VM_HOST_LIB"
fb_report fb
