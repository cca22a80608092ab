#!/bin/sh
# PID 1 of the guest started by run-vcan.sh, user-mode-linux or KVM (there
# after the initramfs' kvm-initramfs-init.sh). It must never exit or fail
# (that panics the guest): everything that can fail runs in a subshell, the
# result goes to a file on the host, then the guest powers off.
export PATH=/usr/sbin:/usr/bin:/sbin:/bin
job="$TCPEST_VCAN_JOB"

(
  set -e
  mount -t proc proc /proc
  mount -t sysfs sysfs /sys
  modules="/usr/lib/uml/modules/$(uname -r)/kernel"
  # The KVM guest's initramfs has loaded them already (its kernel's modules
  # are not on the host's /): load only what is not there.
  load() { [ -d "/sys/module/$1" ] || insmod "$modules/$2"; }
  # Order matters: can-raw and vcan need can, vcan needs can-dev.
  load can net/can/can.ko
  load can_raw net/can/can-raw.ko
  load can_dev drivers/net/can/dev/can-dev.ko
  load vcan drivers/net/can/vcan.ko
  # For the full-TX-queue test (tc plug); optional.
  load sch_plug net/sched/sch_plug.ko || echo "sch_plug not loaded"
  iface="$(cat "$job/iface")"
  ip link add dev "$iface" type vcan
  ip link set up "$iface"
) >"$job/setup.log" 2>&1
setup=$?

if [ "$setup" -eq 0 ]; then
  (
    cd "$(cat "$job/cwd")" || exit 1
    TCPEST_VCAN_IFACE="$(cat "$job/iface")"
    export TCPEST_VCAN_IFACE
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
