#!/bin/sh
# A SpaceMouse Compact (256f:c635, whose Y/Z spacenavd swaps and negates)
# over /dev/uhid with absolute axes (spacenavd rescales them to ±500), then
# with relative ones (the kernel passes no zero: spacenavd never hears the
# cap come back to rest), read by the real spacenavd and `isoshape run`
# through libspnav while the sequence plays. In the first run spacenavd is
# also killed while the cap is held and started again: the handle stops at
# once, and the run picks the daemon up again.
. /test/lib.sh
mods uhid hid-generic evdev
for layout in abs rel; do
    hid_start uhid 256f c635 "$layout" "$OUT/hidplay.$layout.log"
    wait_cmd hidraw_of 256F C635 || fail "no hidraw node for 256f:c635"
    spacenavd_start
    scene_start "$layout" /test/scene.yaml
    grep -q "spnav spacenavd (256f:c635" "$OUT/$layout.log" || fail "$layout: the spnav source does not name the device spacenavd serves"
    hid "play /test/spacemouse.seq"
    if [ "$layout" = abs ]; then
        # The cap held over to one side; the daemon killed under it.
        hid_send "axes 0 0 0 0 0 200 3000"
        usleep 800000
        mark kill
        spacenavd_kill
        note "spacenavd killed"
        hid_wait
        wait_line "$OUT/$layout.log" "went away" || fail "the run did not notice spacenavd was gone"
        hid "axes 0 0 0 0 0 0 200"
        spacenavd_start
        # (not "is back" alone: the went-away line says "until it is back")
        wait_line "$OUT/$layout.log" "spacenavd is back" || fail "the run did not pick spacenavd up again"
        mark back
        hid "play /test/after.seq"
    fi
    scene_stop
    spacenavd_kill
    hid_stop
    wait_cmd no_hidraw 256F C635
done
