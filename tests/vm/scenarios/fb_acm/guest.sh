#!/bin/sh
# The firmware bridge over a USB serial link, as to a USB-connected MCU:
# a configfs ACM gadget on dummy_hcd; cdc_acm gives the host /dev/ttyACM0,
# which libserialport lists with its USB ids and `isoshape run` streams
# setpoints over; the MCU's logic (vm_mcu) answers on /dev/ttyGS0. The
# handshake, setpoints, then the cable pulled: the link is lost and the
# MCU goes safe by its own watchdog; plugged in again: the run reconnects
# and re-arms it; at the end SAFE: the MCU obeys it.
. /test/lib.sh
MCU=$(cat /test/mcu.path)
mods cdc-acm usb_f_acm
gadget_init
gadget_new mcu 1209 0001 "isoshape VM MCU"
gadget_acm mcu
gadget_plug mcu
wait_for -c /dev/ttyACM0 || fail "no /dev/ttyACM0 ($(dmesg | tail -3))"
wait_for -c /dev/ttyGS0 || fail "no /dev/ttyGS0"
"$ISO" devices >"$OUT/devices.txt" 2>&1
cat "$OUT/devices.txt"
grep "/dev/ttyACM0" "$OUT/devices.txt" | grep -q "1209:0001" || fail "libserialport does not list /dev/ttyACM0 with its USB ids"
"$MCU" /dev/ttyGS0 "$OUT/mcu.log" &
MCU_PID=$!
SCENE_UP="actuators:" scene_start fb /test/scene.yaml
wait_line "$OUT/mcu.log" "state ARMED" || fail "the MCU was never armed ($(cat "$OUT/fb.log"))"
note "the MCU is armed"
sleep 2
mark unplug
gadget_unplug mcu
wait_line "$OUT/fb.log" "LINK LOST" || fail "the run did not say the link was lost"
wait_line "$OUT/mcu.log" "state SAFE" || fail "the MCU did not go safe by its watchdog"
note "link lost, the MCU safe"
sleep 1
mark plug
gadget_plug mcu
WAIT_S=30 wait_line "$OUT/fb.log" "armed again" || fail "the run did not re-arm the MCU after the replug"
note "re-armed"
sleep 2
scene_stop
sleep 1
kill -TERM "$MCU_PID"
wait "$MCU_PID"
cat "$OUT/mcu.log"
[ "$(grep -c 'state ARMED' "$OUT/mcu.log")" -ge 2 ] || fail "the MCU was not armed again after the replug"
tail -2 "$OUT/mcu.log" | grep -q "state SAFE" || fail "the MCU did not end in its safe state"
grep -q "obeyed SAFE" "$OUT/fb.log" || fail "the run's SAFE was not obeyed"
grep -q " 0 echo mismatches" "$OUT/fb.json" || fail "acknowledged setpoints differ from the sent ones"
