#!/bin/sh
# The SpaceNavigator gadget unplugged (its UDC unbound, as a cable pulled)
# while its cap is held over, and plugged in again: the run says it went
# away, holds the handle still while it is gone, picks it up again when
# it is back (libusb's hotplug, which needs udevd, or the retry interval),
# counts both in its summary, and the cap's motion flows again.
. /test/lib.sh
mods usbhid hid-logitech hid-generic usb_f_hid
udevd_start
gadget_init
"$HIDPLAY" desc fixup >/tmp/desc
gadget_new sn 046d c626 SpaceNavigator
gadget_hid sn /tmp/desc
gadget_plug sn
wait_cmd hidraw_of 046D C626 || fail "no hidraw node for 046d:c626"
hid_start hidg /dev/hidg0 "$OUT/hidplay.log"
scene_start usb /test/scene.yaml
hid "play /test/spacemouse.seq"
hid_send "axes 250 0 0 0 0 0 2500"
usleep 800000
mark unplug
gadget_unplug sn
wait_cmd no_hidraw 046D C626 || fail "the hidraw node stayed after the unplug"
mark hidraw-gone
wait_line "$OUT/usb.log" "went away" || fail "the run did not say the device went away"
usleep 1000000
mark plug
gadget_plug sn
wait_cmd hidraw_of 046D C626 || fail "no hidraw node after the replug"
mark hidraw-back
# (not "is back" alone: the went-away line says "until it is back")
wait_line "$OUT/usb.log" "hidraw[0-9]* is back" || fail "the run did not pick the device up again"
mark run-back
hid_wait
hid "axes 250 0 0 0 0 0 400"
hid "play /test/after.seq"
scene_stop
grep -q "gone 1, back 1" "$OUT/usb.log" || fail "the summary does not count the unplug and the replug"
hid_stop
