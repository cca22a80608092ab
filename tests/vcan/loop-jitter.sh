#!/bin/sh
# Receiver-side period jitter of the real loop on vcan, against the timer
# floor measured in the same run. To be run where vcan0 exists, normally in
# one of run-vcan.sh's guests (it skips itself in the emulated-CPU one):
#
#   TCPEST_VCAN_TIMEOUT=1500 tests/vcan/run-vcan.sh tests/vcan/loop-jitter.sh --seconds 600
#
# One `candump -L` records the interface for the whole run; three phases,
# one after the other (the guest has one CPU: running them side by side would
# measure each one's effect on the other):
#   1. floor: tcpest_period_floor, a bare clock_nanosleep(TIMER_ABSTIME) loop
#      sending one frame (ID 0x7F0) per 40 ms deadline, for half of --floor-seconds;
#   2. loop: `tcpest run` with loop.trigger: period, 40 ms, the simulated
#      camera, --bus IFACE, for --seconds (its TCP PDO, 0x190, is measured);
#   3. floor again, the other half (so that slow drifts of the machine's
#      conditions weigh on both sides alike).
# Then tests/vcan/candump-jitter.sh computes, from candump's time stamps
# only, |actual - nominal| and |interval - period| of 0x190 and of 0x7F0,
# and the ratio of the p99.9s.
#
# --check (the CTest `vcan_loop_jitter`): a short run that fails unless every
# TCP PDO the loop published reached candump, in order (alive counter), and
# the floor's frames too; the jitter is only reported.
#
# Options: --build DIR (default build/default), --seconds S (loop phase,
# default 120), --floor-seconds F (default = S), --period-us P (default 40000),
# --out DIR (default DIR/vcan-jitter), --rt (rt.fifo_priority 50 and
# rt.lock_memory for the loop, the same for the floor), --check.
set -eu

build=build/default
seconds=120
floor_seconds=
period_us=40000
out=
rt=0
check=0
while [ "$#" -gt 0 ]; do
  case "$1" in
    --build) build="$2"; shift 2 ;;
    --seconds) seconds="$2"; shift 2 ;;
    --floor-seconds) floor_seconds="$2"; shift 2 ;;
    --period-us) period_us="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    --rt) rt=1; shift ;;
    --check) check=1; shift ;;
    *) echo "loop-jitter: unknown argument $1" >&2; exit 2 ;;
  esac
done
[ -n "$floor_seconds" ] || floor_seconds="$seconds"
# In run-vcan.sh's qemu guest without KVM (TCG: the CPU is emulated, the
# last resort when neither KVM nor user-mode-linux can run) the loop's
# rendering and vision run many times slower than on any real machine (the
# --check run did not finish in 180 s there, against about 45 s under UML):
# its period jitter would be the emulator's. Skipped, with the reason; the
# SocketCAN tests (tcpest_vcan_test) do run there.
if [ "${TCPEST_VCAN_GUEST:-}" = "qemu-tcg" ]; then
  echo "loop-jitter: SKIPPED: the guest's CPU is emulated (qemu TCG, no usable KVM here): the loop's timing would be the emulator's" >&2
  exit 77
fi
[ -n "$out" ] || out="$build/vcan-jitter"
iface="${TCPEST_VCAN_IFACE:-vcan0}"
here="$(cd "$(dirname "$0")" && pwd)"
tcpest="$build/firmware_like/tcpest"
floor="$build/tests/vcan/tcpest_period_floor"
for program in "$tcpest" "$floor"; do
  if [ ! -x "$program" ]; then
    echo "loop-jitter: $program not built (cmake --build $build --target tcpest tcpest_period_floor)" >&2
    exit 1
  fi
done
if ! ip link show "$iface" >/dev/null 2>&1; then
  echo "loop-jitter: no $iface here: run it through tests/vcan/run-vcan.sh" >&2
  exit 1
fi
mkdir -p "$out"

# In the guest the host's file system is hostfs: each write is a host
# syscall that stalls the guest's only CPU. candump writes to a tmpfs instead.
scratch="$(mktemp -d /tmp/loop-jitter.XXXXXX)"
if [ "${TCPEST_VCAN_IN_GUEST:-0}" = 1 ]; then
  mount -t tmpfs -o size=64m tmpfs "$scratch"
fi
cleanup() {
  if [ -n "${candump_pid:-}" ]; then kill "$candump_pid" 2>/dev/null || true; fi
  if [ "${TCPEST_VCAN_IN_GUEST:-0}" = 1 ]; then umount "$scratch" 2>/dev/null || true; fi
  rm -rf "$scratch"
}
trap cleanup EXIT

frames=$((seconds * 1000000 / period_us))
half_floor=$(awk -v f="$floor_seconds" 'BEGIN { printf "%g", f / 2 }')
fifo=""
cfg="$out/loop-jitter.yaml"
{
  echo "# written by tests/vcan/loop-jitter.sh"
  echo "loop:"
  echo "  trigger: period"
  echo "  period_us: $period_us"
  echo "  source: sim"
  echo "can:"
  echo "  start_operational: true  # no NMT master on this bus"
  if [ "$rt" = 1 ]; then
    echo "rt:"
    echo "  lock_memory: true"
    echo "  fifo_priority: 50"
  fi
} >"$cfg"
if [ "$rt" = 1 ]; then
  fifo="--fifo 50 --lock"
fi

# candump is listening once /proc/net/can/rcvlist_all has one more line for
# the interface (its "(vcan0: no entry)" line does not count).
receivers() { grep -c "^ *$iface " /proc/net/can/rcvlist_all 2>/dev/null || true; }
before="$(receivers)"
candump -L "$iface" >"$scratch/candump.log" &
candump_pid=$!
tries=0
while [ "$(receivers)" -le "$before" ]; do
  tries=$((tries + 1))
  if [ "$tries" -gt 100 ]; then
    echo "loop-jitter: candump did not start listening on $iface" >&2
    exit 1
  fi
  sleep 0.1
done

echo "== $(uname -r) on $iface; loop ${seconds}s ($frames cycles), floor ${floor_seconds}s, period ${period_us}us, rt $rt"
echo "-- floor, first half (${half_floor}s)"
# shellcheck disable=SC2086 # $fifo is empty or two options
"$floor" --iface "$iface" --id 7F0 --period-us "$period_us" --seconds "$half_floor" $fifo | tee "$out/floor-1.txt"
echo "-- loop: tcpest run --config $cfg --bus $iface --frames $frames --quiet"
status=0
"$tcpest" run --config "$cfg" --bus "$iface" --frames "$frames" --quiet >"$out/run.txt" 2>&1 || status=$?
cat "$out/run.txt"
if [ "$status" -ne 0 ]; then
  echo "loop-jitter: tcpest run failed (status $status)" >&2
  exit 1
fi
echo "-- floor, second half (${half_floor}s)"
# shellcheck disable=SC2086
"$floor" --iface "$iface" --id 7F0 --period-us "$period_us" --seconds "$half_floor" $fifo | tee "$out/floor-2.txt"
sleep 0.5  # the last frames reach candump
kill "$candump_pid"
wait "$candump_pid" 2>/dev/null || true
candump_pid=
cp "$scratch/candump.log" "$out/candump.log"

echo "== receiver side (candump time stamps), $out/candump.log"
"$here/candump-jitter.sh" "$out/candump.log" 190 "$period_us" loop-tcp alive | tee "$out/analysis.txt"
"$here/candump-jitter.sh" "$out/candump.log" 7F0 "$period_us" floor seq32 | tee -a "$out/analysis.txt"
loop_p999=$(awk '$1 == "RESULT" && $2 == "loop-tcp" { print $8 }' "$out/analysis.txt")
floor_p999=$(awk '$1 == "RESULT" && $2 == "floor" { print $8 }' "$out/analysis.txt")
awk -v l="$loop_p999" -v f="$floor_p999" 'BEGIN {
  printf "ratio p99.9 |actual - nominal| loop / floor: %.2f (target <= 1.2)\n", (f > 0 ? l / f : 0) }' | tee -a "$out/analysis.txt"

if [ "$check" = 1 ]; then
  published=$(awk '/^published / { print $2 }' "$out/run.txt")
  received=$(awk '$1 == "RESULT" && $2 == "loop-tcp" { print $3 }' "$out/analysis.txt")
  order=$(awk '$1 == "RESULT" && $2 == "loop-tcp" { print $5 }' "$out/analysis.txt")
  floor_order=$(awk '$1 == "RESULT" && $2 == "floor" { print $5 }' "$out/analysis.txt")
  floor_sent=$(awk '/^bare clock_nanosleep/ { n += $4 } END { print n + 0 }' "$out/floor-1.txt" "$out/floor-2.txt")
  floor_received=$(awk '$1 == "RESULT" && $2 == "floor" { print $3 }' "$out/analysis.txt")
  echo "check: TCP PDOs published $published, received $received, counter errors $order;" \
       "floor frames sent $floor_sent, received $floor_received, sequence errors $floor_order"
  if [ "$published" != "$received" ] || [ "$order" != 0 ] || [ "$floor_sent" != "$floor_received" ] || [ "$floor_order" != 0 ]; then
    echo "loop-jitter: FAILED: frames lost or out of order" >&2
    exit 1
  fi
  echo "loop-jitter: every TCP PDO and every floor frame arrived, in order"
fi
