#!/usr/bin/env bash
# Runs a command where a vcan interface exists, so that SocketCAN code meets
# the kernel's real vcan driver:
#   - on the host, when the host can have vcan0 (it exists, or we may create it);
#   - otherwise in a user-mode-linux guest (Debian's user-mode-linux package)
#     that sees the host's / and loads can, can-raw, can-dev, vcan, sch_plug.
# The guest boots once and runs the whole command. Exit status: the command's;
# 77 (CTest "skipped") when neither vcan nor user-mode-linux is available.
#
# Usage: tests/vcan/run-vcan.sh COMMAND [ARG...]
# Environment: TCPEST_VCAN_MODE=auto|host|uml (default auto),
#              TCPEST_VCAN_TIMEOUT=seconds for the whole run (default 300),
#              TCPEST_VCAN_IFACE (default vcan0),
#              TCPEST_VCAN_LOG=file to keep a copy of the command's output.
set -uo pipefail

here="$(cd "$(dirname "$0")" && pwd)"
mode="${TCPEST_VCAN_MODE:-auto}"
timeout_s="${TCPEST_VCAN_TIMEOUT:-300}"
iface="${TCPEST_VCAN_IFACE:-vcan0}"
export TCPEST_VCAN_IFACE="$iface"
PATH="/usr/sbin:/sbin:$PATH"

if [ "$#" -eq 0 ]; then
  echo "usage: $0 COMMAND [ARG...]" >&2
  exit 2
fi

log() { echo "run-vcan: $*" >&2; }

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

if [ "$mode" != "uml" ] && host_has_vcan; then
  log "host has $iface: running directly"
  if [ -n "${TCPEST_VCAN_LOG:-}" ]; then
    timeout --kill-after=10 "$timeout_s" "$@" 2>&1 | tee "$TCPEST_VCAN_LOG"
    rc=${PIPESTATUS[0]}
  else
    timeout --kill-after=10 "$timeout_s" "$@"
    rc=$?
  fi
  [ "$created" -eq 1 ] && ip link delete "$iface" >/dev/null 2>&1
  [ "$rc" -eq 124 ] && log "timed out after ${timeout_s}s"
  exit "$rc"
fi
if [ "$mode" = "host" ]; then
  log "TCPEST_VCAN_MODE=host but $iface is not available on this host"
  exit 1
fi

uml="$(command -v linux.uml || true)"
if [ -z "$uml" ]; then
  log "SKIPPED: no vcan on this host and no user-mode-linux (install the packages of toolchain/deps.sh)"
  exit 77
fi
modules="/usr/lib/uml/modules"
if ! ls -d "$modules"/*/kernel/drivers/net/can >/dev/null 2>&1; then
  log "user-mode-linux has no CAN modules under $modules"
  exit 1
fi

job="$(mktemp -d /tmp/tcpest-vcan.XXXXXX)"
printf '%q ' "$@" >"$job/cmd"
pwd >"$job/cwd"
# The guest reports before the host gives up on it.
echo $((timeout_s > 40 ? timeout_s - 20 : timeout_s * 2 / 3)) >"$job/timeout"
echo "$iface" >"$job/iface"

log "booting user-mode-linux ($uml) for: $*"
start=$(date +%s.%N)
# UML maps its memory through files in TMPDIR: /dev/shm keeps them in RAM.
TMPDIR=/dev/shm timeout --kill-after=10 "$timeout_s" "$uml" mem=256M rootfstype=hostfs rootflags=/ rw \
  init="$here/guest-init.sh" TCPEST_VCAN_JOB="$job" con=null con0=null,fd:1 \
  </dev/null >"$job/console.log" 2>&1
uml_rc=$?
end=$(date +%s.%N)

[ -f "$job/setup.log" ] && [ -s "$job/setup.log" ] && { log "guest setup:"; cat "$job/setup.log" >&2; }
if [ -f "$job/output.log" ]; then
  cat "$job/output.log"
  [ -n "${TCPEST_VCAN_LOG:-}" ] && cp "$job/output.log" "$TCPEST_VCAN_LOG"
fi
if [ ! -f "$job/rc" ] && grep -q "ptrace set fp regs failed" "$job/console.log"; then
  # The guest's first process dies before our init runs: Debian 12's UML
  # 6.1 cannot load the FPU state of its processes through ptrace on a host
  # whose FPU state is larger than it expects (seen on a 6.18 host kernel
  # with AMX). Nothing of ours ran: the tests are skipped, loudly.
  log "SKIPPED: user-mode-linux cannot start processes on this host ($(uname -r)): \"$(grep -m1 'ptrace set fp regs failed' "$job/console.log")\" (tests/vcan/README.md, Limits)"
  rm -rf "$job"
  exit 77
fi
if [ ! -f "$job/rc" ]; then
  if [ "$uml_rc" -eq 124 ] || [ "$uml_rc" -eq 137 ]; then
    log "FAILED: the guest was stopped after ${timeout_s}s (TCPEST_VCAN_TIMEOUT)"
  else
    log "FAILED: the guest ended (status $uml_rc) without reporting a result"
  fi
  log "last lines of the guest console ($job/console.log):"
  tail -n 30 "$job/console.log" >&2
  exit 1
fi
rc="$(cat "$job/rc")"
log "guest finished: status $rc, $(awk -v a="$start" -v b="$end" 'BEGIN{printf "%.1f", b-a}')s including boot"
if [ "$rc" -eq 0 ]; then
  rm -rf "$job"
else
  log "kept $job for inspection (console.log, setup.log, output.log)"
fi
exit "$rc"
