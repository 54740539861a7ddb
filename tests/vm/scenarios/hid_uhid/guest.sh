#!/bin/sh
# A SpaceMouse Compact over /dev/uhid: hid-generic binds it and makes a
# hidraw node; `isoshape run` reads it through hidapi while the scripted
# sequence plays, recording it. Then again with ticks slower than the
# kernel's hidraw buffer lasts.
. /test/lib.sh
mods uhid hid-generic
hid_start uhid 256f c635 abs "$OUT/hidplay.log"
wait_cmd hidraw_of 256F C635 || fail "no hidraw node for 256f:c635 ($(dmesg | tail -5))"
note "hidraw: $(hidraw_of 256F C635)"
# hidapi lists a device once per top-level collection; isoshape once.
"$ISO" devices >"$OUT/devices.txt" 2>&1
cat "$OUT/devices.txt"
[ "$(grep -c "$(hidraw_of 256F C635)" "$OUT/devices.txt")" = 1 ] || fail "isoshape devices lists the hidraw node more than once"
scene_start uhid /test/scene.yaml
hid "play /test/spacemouse.seq"
scene_stop
# Ticks slower than hidraw's buffer lasts, a device reporting every 4 ms:
# whatever the kernel drops, the run must end at rest.
scene_start slow /test/scene_slow.yaml
hid "repeat 4"
hid "play /test/overflow.seq"
scene_stop
hid_stop
