#!/usr/bin/env bash
# Runs a command where a vcan interface exists, so that SocketCAN code meets
# the kernel's real vcan driver, the first of these that this machine allows:
#   - on the host, when the host can have vcan0 (it exists, or we may create it);
#   - in a KVM guest: Debian 12's kernel under qemu-system-x86 (x86-64 hosts
#     whose /dev/kvm is hardware virtualisation), booted from a small busybox
#     initramfs that loads the 9p and CAN modules and mounts the host's /
#     over virtio-9p;
#   - in a user-mode-linux guest (Debian's user-mode-linux package) that sees
#     the host's / and loads can, can-raw, can-dev, vcan, sch_plug;
#   - in the same qemu guest without KVM (TCG, emulated CPU) when UML cannot
#     start either: slower, but the same kernel and driver.
# A guest boots once and runs the whole command, with guest-init.sh as PID 1
# and TCPEST_VCAN_GUEST=qemu-kvm, qemu-tcg or uml in its environment.
# Exit status: the command's; 77 (CTest "skipped", with a one-line reason)
# when there is no way to a vcan driver here. See README.md.
#
# Usage: tests/vcan/run-vcan.sh COMMAND [ARG...]
# Environment: TCPEST_VCAN_MODE=auto|host|kvm|uml (default auto; kvm is the
#                qemu guest, with KVM or else TCG),
#              TCPEST_VCAN_ACCEL=kvm|tcg to choose the qemu guest's accelerator,
#              TCPEST_VCAN_TIMEOUT=seconds for the whole run (default 300),
#              TCPEST_VCAN_IFACE (default vcan0),
#              TCPEST_VCAN_LOG=file to keep a copy of the command's output,
#              TCPEST_VCAN_CACHE=directory of the KVM guest's kernel and
#                initramfs (default /var/cache/tcpest-vcan as root, else
#                ~/.cache/tcpest-vcan).
set -euo pipefail

here="$(cd "$(dirname "$0")" && pwd)"
mode="${TCPEST_VCAN_MODE:-auto}"
timeout_s="${TCPEST_VCAN_TIMEOUT:-300}"
iface="${TCPEST_VCAN_IFACE:-vcan0}"
export TCPEST_VCAN_IFACE="$iface"
PATH="/usr/sbin:/sbin:$PATH"

log() { echo "run-vcan: $*" >&2; }

if [ "$#" -eq 0 ]; then
  echo "usage: $0 COMMAND [ARG...]" >&2
  exit 2
fi
case "$mode" in
  auto | host | kvm | uml) ;;
  *)
    log "TCPEST_VCAN_MODE=$mode: expected auto, host, kvm or uml"
    exit 2
    ;;
esac

# ---------------------------------------------------------------- host ----

# 0 when the host has (or could create) the interface; sets created=1 if created.
created=0
host_has_vcan() {
  if ip link show "$iface" >/dev/null 2>&1; then
    return 0
  fi
  [ "$(id -u)" -eq 0 ] || return 1
  modprobe vcan >/dev/null 2>&1 || true
  if ip link add dev "$iface" type vcan >/dev/null 2>&1; then
    created=1
    ip link set up "$iface" || return 1
    return 0
  fi
  return 1
}

if { [ "$mode" = "auto" ] || [ "$mode" = "host" ]; } && host_has_vcan; then
  log "host has $iface: running directly"
  # The command's status is the result: no -e while it runs.
  set +e
  if [ -n "${TCPEST_VCAN_LOG:-}" ]; then
    timeout --kill-after=10 "$timeout_s" "$@" 2>&1 | tee "$TCPEST_VCAN_LOG"
    rc=${PIPESTATUS[0]}
  else
    timeout --kill-after=10 "$timeout_s" "$@"
    rc=$?
  fi
  set -e
  if [ "$created" -eq 1 ]; then
    ip link delete "$iface" >/dev/null 2>&1 || true
  fi
  if [ "$rc" -eq 124 ]; then
    log "timed out after ${timeout_s}s"
  fi
  exit "$rc"
fi
if [ "$mode" = "host" ]; then
  log "TCPEST_VCAN_MODE=host but $iface is not available on this host"
  exit 1
fi

# ------------------------------------------------------ shared by guests ----

# Why each way was not taken, for the SKIPPED line.
declare -a not_here=("host: no $iface and 'ip link add type vcan' fails (no vcan module, or not root)")

# The job directory on the host's /, which the guests see: guest-init.sh reads
# the command from it and writes setup.log, output.log and rc into it.
job=""
new_job() {
  job="$(mktemp -d /tmp/tcpest-vcan.XXXXXX)"
  printf '%q ' "$@" >"$job/cmd"
  pwd >"$job/cwd"
  # The guest reports before the host gives up on it.
  echo $((timeout_s > 40 ? timeout_s - 20 : timeout_s * 2 / 3)) >"$job/timeout"
  echo "$iface" >"$job/iface"
  echo "$here/guest-init.sh" >"$job/init"
}

# Prints what the guest left, then exits with the command's status, or 1 when
# the guest never reported. $1: guest name, $2: its monitor's exit status
# (timeout's), $3, $4: start and end times.
finish_guest() {
  local name="$1" guest_rc="$2" start="$3" end="$4"
  if [ -s "$job/setup.log" ]; then
    log "guest setup:"
    cat "$job/setup.log" >&2
  fi
  if [ -f "$job/output.log" ]; then
    cat "$job/output.log"
    if [ -n "${TCPEST_VCAN_LOG:-}" ]; then
      cp "$job/output.log" "$TCPEST_VCAN_LOG"
    fi
  fi
  if [ ! -f "$job/rc" ]; then
    if [ "$guest_rc" -eq 124 ] || [ "$guest_rc" -eq 137 ]; then
      log "FAILED: the $name guest was stopped after ${timeout_s}s (TCPEST_VCAN_TIMEOUT)"
    else
      log "FAILED: the $name guest ended (status $guest_rc) without reporting a result"
    fi
    log "last lines of the guest console ($job/console.log):"
    tail -n 30 "$job/console.log" >&2
    exit 1
  fi
  local rc
  rc="$(cat "$job/rc")"
  log "$name guest finished: status $rc, $(awk -v a="$start" -v b="$end" 'BEGIN{printf "%.1f", b-a}')s including boot"
  if [ "$rc" -eq 0 ] || [ "$rc" -eq 77 ]; then
    rm -rf "$job"
  else
    log "kept $job for inspection (console.log, setup.log, output.log)"
  fi
  exit "$rc"
}

# ----------------------------------------------------------------- kvm ----

kvm_cache="${TCPEST_VCAN_CACHE:-}"
if [ -z "$kvm_cache" ]; then
  if [ "$(id -u)" -eq 0 ]; then
    kvm_cache=/var/cache/tcpest-vcan
  else
    kvm_cache="${XDG_CACHE_HOME:-$HOME/.cache}/tcpest-vcan"
  fi
fi
# The modules the initramfs loads (their dependencies are added): virtio-9p
# for the host's /, then what guest-init.sh would insmod under UML.
kvm_modules=(virtio_pci 9pnet_virtio 9p can can_raw can_dev vcan sch_plug)
qemu=""
kvm_reason=""
accel_reason=""

# 0 when KVM can run a stock kernel here; else sets accel_reason. KVM with
# hardware virtualisation (kvm_intel, kvm_amd) needs vmx or svm in the CPU
# flags; a /dev/kvm without them (kvm_pvm, as on the sandboxes this was
# written on) only runs kernels built as PVM guests: Debian's kernel stops
# there with a KVM emulation failure (cmpxchg16b, xrstor) after minutes.
kvm_hardware() {
  if [ ! -c /dev/kvm ]; then
    accel_reason="no /dev/kvm"
  elif [ ! -r /dev/kvm ] || [ ! -w /dev/kvm ]; then
    accel_reason="/dev/kvm is not readable and writable for $(id -un)"
  elif ! grep -qw -E 'vmx|svm' /proc/cpuinfo; then
    accel_reason="/dev/kvm without hardware virtualisation (no vmx/svm)"
    if [ -d /sys/module/kvm_pvm ]; then
      accel_reason="/dev/kvm without hardware virtualisation (no vmx/svm: kvm_pvm)"
    fi
  else
    return 0
  fi
  return 1
}

# 0 when this host can run the qemu guest at all; else sets kvm_reason.
kvm_possible() {
  if [ "$(uname -m)" != "x86_64" ]; then
    kvm_reason="kvm: not an x86-64 host ($(uname -m)); the guest is Debian's amd64 kernel"
    return 1
  fi
  qemu="$(command -v qemu-system-x86_64 || true)"
  if [ -z "$qemu" ]; then
    kvm_reason="kvm: no qemu-system-x86_64 (package qemu-system-x86)"
    return 1
  fi
  if [ ! -x /bin/busybox ] || ! file -L /bin/busybox 2>/dev/null | grep -q 'statically linked'; then
    # file(1) may be missing: then trust the package.
    if ! dpkg-query -W -f='${Status}' busybox-static 2>/dev/null | grep -q "install ok installed"; then
      kvm_reason="kvm: no static busybox for the initramfs (package busybox-static)"
      return 1
    fi
  fi
  return 0
}

# Fetches Debian's current amd64 kernel package (the one linux-image-amd64
# depends on) with apt-get download and keeps its vmlinuz and the modules
# kvm_modules need, dependencies first, in $kvm_cache/kernel. The package is
# extracted, never installed: no initramfs hooks or /boot changes on the host.
# Once there, the kernel is reused without asking the mirror again.
kvm_fetch_kernel() {
  local kdir="$kvm_cache/kernel"
  if [ -s "$kdir/vmlinuz" ] && [ -s "$kdir/modules/modules.order" ]; then
    return 0
  fi
  local tmp pkg
  tmp="$(mktemp -d "$kvm_cache/fetch.XXXXXX")"
  pkg="$(apt-cache depends linux-image-amd64 2>/dev/null | awk '/Depends: linux-image-[0-9]/ { print $2; exit }')"
  if [ -z "$pkg" ] && [ "$(id -u)" -eq 0 ]; then
    # No package lists yet on a fresh machine.
    apt-get update -qq >"$tmp/apt.log" 2>&1 || true
    pkg="$(apt-cache depends linux-image-amd64 2>/dev/null | awk '/Depends: linux-image-[0-9]/ { print $2; exit }')"
  fi
  if [ -z "$pkg" ]; then
    kvm_reason="kvm: apt-cache knows no linux-image-amd64 (run apt-get update)"
    rm -rf "$tmp"
    return 1
  fi
  log "kvm: fetching $pkg (apt-get download) into $kdir, once"
  # apt's sandbox user must be able to write the download directory.
  chmod 0777 "$tmp"
  if ! (cd "$tmp" && apt-get download -q "$pkg") >>"$tmp/apt.log" 2>&1; then
    kvm_reason="kvm: 'apt-get download $pkg' failed: $(grep -m1 -E '^(E|Err):' "$tmp/apt.log" || tail -n 1 "$tmp/apt.log")"
    rm -rf "$tmp"
    return 1
  fi
  local mdir
  rm -rf "$kdir.new"
  # (set -e does not hold in a function called from a condition: every step
  # that can fail is checked.)
  if ! dpkg-deb -x "$tmp"/linux-image-*.deb "$tmp/x" || ! mdir="$(echo "$tmp"/x/lib/modules/*)" ||
    [ ! -d "$mdir/kernel" ] || ! mkdir -p "$kdir.new/modules" ||
    ! cp "$tmp"/x/boot/vmlinuz-* "$kdir.new/vmlinuz" || ! basename "$mdir" >"$kdir.new/version"; then
    kvm_reason="kvm: could not extract vmlinuz and modules from $pkg"
    rm -rf "$tmp" "$kdir.new"
    return 1
  fi

  # Module file names use - or _; modinfo's depends and /sys/module use _.
  local -A file_of=() done_=()
  local f name
  while IFS= read -r f; do
    name="$(basename "$f" .ko)"
    file_of["${name//-/_}"]="$f"
  done < <(find "$mdir/kernel" -name '*.ko')
  # Depth first, dependencies before the module: insmod order.
  add_module() {
    local m="${1//-/_}" dep
    [ -z "${done_[$m]:-}" ] || return 0
    done_[$m]=1
    if [ -z "${file_of[$m]:-}" ]; then
      log "kvm: module $m not in $(basename "$mdir")"
      return 1
    fi
    for dep in $(modinfo -F depends "${file_of[$m]}" | tr ',' ' '); do
      add_module "$dep" || return 1
    done
    cp "${file_of[$m]}" "$kdir.new/modules/$m.ko" && echo "$m" >>"$kdir.new/modules/modules.order"
  }
  local m
  for m in "${kvm_modules[@]}"; do
    if ! add_module "$m"; then
      kvm_reason="kvm: $pkg lacks a module the guest needs ($m or a dependency)"
      rm -rf "$tmp" "$kdir.new"
      return 1
    fi
  done
  rm -rf "$tmp" "$kdir"
  mv "$kdir.new" "$kdir"
}

# (Re)builds $kvm_cache/initramfs.cpio.gz when missing or older than what it
# is made of: static busybox, kvm-initramfs-init.sh as /init, the modules.
kvm_build_initramfs() {
  local out="$kvm_cache/initramfs.cpio.gz"
  if [ -s "$out" ] && [ "$out" -nt "$here/kvm-initramfs-init.sh" ] &&
    [ "$out" -nt /bin/busybox ] && [ "$out" -nt "$kvm_cache/kernel/modules/modules.order" ]; then
    return 0
  fi
  local root ok=0
  root="$(mktemp -d "$kvm_cache/initramfs.XXXXXX")" || return 1
  if mkdir -p "$root/bin" "$root/dev" "$root/proc" "$root/sys" "$root/newroot" &&
    cp /bin/busybox "$root/bin/busybox" &&
    cp "$here/kvm-initramfs-init.sh" "$root/init" && chmod 0755 "$root/init" &&
    cp -r "$kvm_cache/kernel/modules" "$root/modules" &&
    (cd "$root" && find . | /bin/busybox cpio -o -H newc -R 0:0 2>/dev/null) | gzip -1 >"$out.tmp"; then
    mv "$out.tmp" "$out"
  else
    kvm_reason="kvm: could not build the initramfs in $kvm_cache"
    rm -f "$out.tmp"
    ok=1
  fi
  rm -rf "$root"
  return "$ok"
}

# 0 when kernel and initramfs are ready; else sets kvm_reason. Serialised:
# the vcan CTest tests may start side by side on a fresh cache.
kvm_prepare() {
  mkdir -p "$kvm_cache"
  exec 9>"$kvm_cache/lock"
  flock 9
  local ok=0
  kvm_fetch_kernel && kvm_build_initramfs || ok=1
  flock -u 9
  exec 9>&-
  return "$ok"
}

# $1: kvm or tcg; then the command.
run_kvm() {
  local accel="$1" name cpu
  shift
  new_job "$@"
  if [ "$accel" = "kvm" ]; then
    name=KVM
    cpu=(-enable-kvm -cpu host)
  else
    name="qemu (TCG)"
    cpu=(-accel tcg -cpu max)
  fi
  log "booting a $name guest (Debian kernel $(cat "$kvm_cache/kernel/version")) for: $*"
  local start end guest_rc=0
  start=$(date +%s.%N)
  # One vCPU, like the UML guest: loop-jitter.sh relies on its phases not
  # running side by side. The host's / is the guest's root over virtio-9p,
  # read-write as the host's root (passthrough), so the build tree, its
  # shared libraries and can-utils run in place; multidevs=remap keeps inode
  # numbers unique across the host's mounts.
  timeout --kill-after=10 "$timeout_s" "$qemu" \
    "${cpu[@]}" -smp 1 -m 512M \
    -nodefaults -nographic -no-reboot -serial stdio \
    -kernel "$kvm_cache/kernel/vmlinuz" -initrd "$kvm_cache/initramfs.cpio.gz" \
    -append "console=ttyS0 quiet panic=-1 TCPEST_VCAN_JOB=$job TCPEST_VCAN_GUEST=qemu-$accel" \
    -virtfs local,path=/,mount_tag=hostroot,security_model=passthrough,multidevs=remap,id=hostroot \
    </dev/null >"$job/console.log" 2>&1 || guest_rc=$?
  end=$(date +%s.%N)
  finish_guest "$name" "$guest_rc" "$start" "$end"
}

# The accelerator: TCPEST_VCAN_ACCEL, else KVM where it has hardware
# virtualisation, else TCG (tried after UML in auto mode: slower).
accel="${TCPEST_VCAN_ACCEL:-}"
case "$accel" in
  kvm | tcg) ;;
  "") if kvm_hardware; then accel=kvm; else accel=tcg; fi ;;
  *)
    log "TCPEST_VCAN_ACCEL=$accel: expected kvm or tcg"
    exit 2
    ;;
esac
qemu_ready=0
if [ "$mode" = "auto" ] || [ "$mode" = "kvm" ]; then
  if kvm_possible && kvm_prepare; then
    qemu_ready=1
  fi
fi
if [ "$mode" = "kvm" ]; then
  if [ "$qemu_ready" -eq 0 ]; then
    log "TCPEST_VCAN_MODE=kvm but the qemu guest cannot run here: $kvm_reason"
    exit 1
  fi
  [ "$accel" = "tcg" ] && [ -n "$accel_reason" ] && log "KVM not usable ($accel_reason): emulating the CPU (TCG)"
  run_kvm "$accel" "$@"
fi
if [ "$mode" = "auto" ] && [ "$qemu_ready" -eq 1 ] && [ "$accel" = "kvm" ]; then
  run_kvm kvm "$@"
fi
if [ "$mode" = "auto" ]; then
  if [ "$qemu_ready" -eq 0 ]; then
    not_here+=("$kvm_reason")
  elif [ -n "$accel_reason" ]; then
    not_here+=("kvm: $accel_reason")
  fi
fi

# Last resort in auto mode, when UML is missing or cannot start.
qemu_tcg_or_skip() {
  if [ "$mode" = "auto" ] && [ "$qemu_ready" -eq 1 ]; then
    log "$(printf '%s; ' "${not_here[@]}")emulating the CPU (qemu TCG) instead"
    run_kvm tcg "$@"
  fi
  log "SKIPPED: no way to a vcan driver here: $(printf '%s; ' "${not_here[@]}")see tests/vcan/README.md and toolchain/deps.sh"
  exit 77
}

# ----------------------------------------------------------------- uml ----

uml="$(command -v linux.uml || true)"
if [ -z "$uml" ]; then
  not_here+=("uml: no linux.uml (package user-mode-linux)")
  qemu_tcg_or_skip "$@"
fi
modules="/usr/lib/uml/modules"
if ! ls -d "$modules"/*/kernel/drivers/net/can >/dev/null 2>&1; then
  log "user-mode-linux has no CAN modules under $modules"
  exit 1
fi

new_job "$@"
log "booting user-mode-linux ($uml) for: $*"
start=$(date +%s.%N)
uml_rc=0
# UML maps its memory through files in TMPDIR: /dev/shm keeps them in RAM.
TMPDIR=/dev/shm timeout --kill-after=10 "$timeout_s" "$uml" mem=256M rootfstype=hostfs rootflags=/ rw \
  init="$here/guest-init.sh" TCPEST_VCAN_JOB="$job" TCPEST_VCAN_GUEST=uml con=null con0=null,fd:1 \
  </dev/null >"$job/console.log" 2>&1 || uml_rc=$?
end=$(date +%s.%N)

if [ ! -f "$job/rc" ] && grep -q "ptrace set fp regs failed" "$job/console.log"; then
  # The guest's first process dies before our init runs: Debian 12's UML
  # 6.1 cannot load the FPU state of its processes through ptrace on a host
  # whose FPU state is larger than it expects (seen on a 6.18 host kernel
  # with AMX). Nothing of ours ran: the tests are skipped, loudly.
  not_here+=("uml: cannot start processes on this host ($(uname -r)): \"$(grep -m1 'ptrace set fp regs failed' "$job/console.log")\"")
  rm -rf "$job"
  qemu_tcg_or_skip "$@"
fi
finish_guest UML "$uml_rc" "$start" "$end"
