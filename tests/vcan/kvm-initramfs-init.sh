#!/bin/busybox sh
# shellcheck shell=dash
# /init of the initramfs run-vcan.sh builds for its KVM guest (Debian's
# kernel under qemu). Only static busybox and the kernel's own modules are in
# the initramfs: this script loads the modules (those of the 9p root and the
# CAN ones, since that kernel's modules are not on the host's /), mounts the
# host's / over virtio-9p and hands over to tests/vcan/guest-init.sh there,
# the same PID 1 as the user-mode-linux guest. It must never exit (that
# panics the guest): on any error it says why on the console and powers off,
# and run-vcan.sh, finding no result file, prints the console.
/bin/busybox mkdir -p /bin /proc /sys /dev /newroot
/bin/busybox --install -s /bin
export PATH=/bin

mount -t devtmpfs devtmpfs /dev
# The kernel may have started us without a console (no /dev/console in the
# archive): write to the serial console run-vcan.sh captures.
exec </dev/null >/dev/console 2>&1

fail() {
  echo "tcpest-initramfs: FAILED: $*"
  poweroff -f
  sleep 5
  # Still alive: exiting panics the kernel, and panic=-1 with qemu's
  # -no-reboot ends qemu too.
  exit 1
}

mount -t proc proc /proc || fail "mount /proc"
mount -t sysfs sysfs /sys || fail "mount /sys"
# modules.order lists them dependencies first (run-vcan.sh resolved it from
# modinfo's depends).
while read -r module; do
  insmod "/modules/$module.ko" || fail "insmod $module"
done </modules/modules.order

# TCPEST_VCAN_JOB comes from the kernel command line (an unknown name=value
# parameter becomes an environment variable of init).
[ -n "${TCPEST_VCAN_JOB:-}" ] || fail "no TCPEST_VCAN_JOB on the kernel command line"
# cache=mmap: no page cache to go stale against the host, but mmap works as
# on a local file system.
mount -t 9p -o trans=virtio,version=9p2000.L,msize=262144,cache=mmap hostroot /newroot ||
  fail "mount the host's / (9p, tag hostroot)"
guest_init="$(cat "/newroot$TCPEST_VCAN_JOB/init")" || fail "no $TCPEST_VCAN_JOB/init on the host"
# The guest's own device nodes over the host's /dev (a mount in the guest
# only); guest-init.sh mounts proc and sys itself, as under user-mode-linux.
mount -t devtmpfs devtmpfs /newroot/dev || fail "mount /dev in the new root"
mkdir -p /newroot/dev/shm /newroot/dev/pts
mount -t tmpfs -o mode=1777 tmpfs /newroot/dev/shm || fail "mount /dev/shm"
mount -t devpts devpts /newroot/dev/pts || fail "mount /dev/pts"
# The console again, from the new root, so the old /dev can go.
exec </dev/null >/newroot/dev/console 2>&1
umount /proc /sys
# Busy for busybox (the console was opened there first): detach it lazily.
umount -l /dev
exec switch_root /newroot "$guest_init"
