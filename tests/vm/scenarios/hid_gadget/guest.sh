#!/bin/sh
# A SpaceNavigator as a USB gadget, in both descriptor layouts the device
# has shipped with: `rel` (with unit items; hid-logitech's rel->abs fixup
# misses it, evdev axes stay relative) and `fixup` (without them; the fixup
# makes the evdev axes absolute). hidraw gives the same bytes either way;
# `isoshape run` reads each through hidapi while the sequence plays.
. /test/lib.sh
mods usbhid hid-logitech hid-generic evdev usb_f_hid
gadget_init
for layout in rel fixup; do
    "$HIDPLAY" desc "$layout" >/tmp/desc.$layout
    gadget_new sn 046d c626 SpaceNavigator
    gadget_hid sn /tmp/desc.$layout
    gadget_plug sn
    wait_cmd hidraw_of 046D C626 || fail "$layout: no hidraw node for 046d:c626 ($(dmesg | tail -5))"
    raw=$(hidraw_of 046D C626)
    input=$(ls -d /sys/class/hidraw/$(basename "$raw")/device/input/input* | head -1)
    note "$layout: $raw, evdev capabilities: abs $(cat "$input/capabilities/abs") rel $(cat "$input/capabilities/rel")"
    dmesg | grep -i "fixing up rel/abs" >"$OUT/fixup.$layout.txt"
    if [ "$layout" = fixup ]; then
        [ -s "$OUT/fixup.$layout.txt" ] || fail "fixup: hid-logitech did not fix the descriptor up"
        [ "$(cat "$input/capabilities/abs")" != 0 ] || fail "fixup: the evdev axes are not absolute"
    else
        [ "$(cat "$input/capabilities/rel")" != 0 ] || fail "rel: the evdev axes are not relative"
    fi
    dmesg -c >/dev/null
    hid_start hidg /dev/hidg0 "$OUT/hidplay.$layout.log"
    scene_start "$layout" /test/scene.yaml
    hid "play /test/spacemouse.seq"
    scene_stop
    hid_stop
    gadget_unplug sn
    wait_cmd no_hidraw 046D C626 || fail "$layout: the hidraw node stayed after the unplug"
    gadget_remove sn
done
