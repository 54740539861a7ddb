#!/bin/sh
# A gpio-sim chip with an e-stop on line 4 (active low, pulled up while
# released). `isoshape run` moves the handle by script and streams it to
# the native emulated MCU. The line pulled low: the handles stop and the
# MCU goes to its safe state; released: the run re-arms and moves on. Then
# the chip goes away under the run: that counts as pressed too.
. /test/lib.sh
mods configfs gpio-sim
grep -q configfs /proc/mounts || mount -t configfs none /sys/kernel/config
c=/sys/kernel/config/gpio-sim/vm
mkdir -p "$c/bank0/line4"
echo 8 >"$c/bank0/num_lines"
echo estop >"$c/bank0/line4/name"
echo 1 >"$c/live" || fail "gpio-sim did not go live ($(dmesg | tail -3))"
chip=$(cat "$c/bank0/chip_name")
pull=/sys/devices/platform/$(cat "$c/dev_name")/$chip/sim_gpio4/pull
echo pull-up >"$pull"
note "gpio-sim: $chip, e-stop line 4 at $pull ($(gpioinfo "$chip" | grep -c line) lines)"
sed "s/chip: gpiochip0/chip: $chip/" /test/scene.yaml >/tmp/scene.yaml
scene_start estop /tmp/scene.yaml
wait_line "$OUT/estop.log" "emulated MCU" || fail "no emulated MCU ($(cat "$OUT/estop.log"))"
sleep 2
mark press
echo pull-down >"$pull"
wait_line "$OUT/estop.log" "reports its safe state" || fail "the MCU did not report its safe state after the press"
mark safe-seen
sleep 1
mark release
echo pull-up >"$pull"
wait_line "$OUT/estop.log" "e-stop released" || fail "the run did not see the release"
sleep 2
mark vanish
echo 0 >"$c/live"
WAIT_S=30 wait_line "$OUT/estop.log" "went away" || fail "the run did not notice the chip went away"
n=$(grep -c "reports its safe state" "$OUT/estop.log")
[ "$n" -ge 2 ] || { sleep 2; n=$(grep -c "reports its safe state" "$OUT/estop.log"); }
[ "$n" -ge 2 ] || fail "the MCU did not go safe when the e-stop line went away"
mark vanish-safe-seen
sleep 1
scene_stop
