#!/bin/sh
# PID 1 of the user-mode-linux guest started by run-vcan.sh. It must never
# exit or fail (that panics the guest): everything that can fail runs in a
# subshell, the result goes to a file on the host, then the guest powers off.
export PATH=/usr/sbin:/usr/bin:/sbin:/bin
job="$TCPEST_VCAN_JOB"

(
  set -e
  mount -t proc proc /proc
  mount -t sysfs sysfs /sys
  modules="/usr/lib/uml/modules/$(uname -r)/kernel"
  # Order matters: can-raw and vcan need can, vcan needs can-dev.
  for module in net/can/can.ko net/can/can-raw.ko drivers/net/can/dev/can-dev.ko drivers/net/can/vcan.ko; do
    insmod "$modules/$module"
  done
  # For the full-TX-queue test (tc plug); optional.
  insmod "$modules/net/sched/sch_plug.ko" || echo "sch_plug not loaded"
  iface="$(cat "$job/iface")"
  ip link add dev "$iface" type vcan
  ip link set up "$iface"
) >"$job/setup.log" 2>&1
setup=$?

if [ "$setup" -eq 0 ]; then
  (
    cd "$(cat "$job/cwd")" || exit 1
    export TCPEST_VCAN_IFACE="$(cat "$job/iface")"
    export TCPEST_VCAN_IN_GUEST=1
    eval "exec timeout --kill-after=5 $(cat "$job/timeout") $(cat "$job/cmd")"
  ) >"$job/output.log" 2>&1 </dev/null
  echo "$?" >"$job/rc.tmp"
else
  echo "guest setup failed (status $setup)" >>"$job/setup.log"
  echo 1 >"$job/rc.tmp"
fi
mv "$job/rc.tmp" "$job/rc"
sync
poweroff -f
