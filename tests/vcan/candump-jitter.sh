#!/bin/sh
# Period jitter of one CAN ID from a candump log (`candump -L` format, also
# what `tcpest run --bus log:FILE` writes): receiver-side timestamps only,
# POSIX sh + awk + sort, no other tool.
#
# Usage: tests/vcan/candump-jitter.sh LOG ID_HEX PERIOD_US LABEL [COUNTER]
#   COUNTER: none (default) | alive (byte 6 bits 0-3 step 0..14, the E2E alive
#            counter of TCP and JOINTS) | seq32 (bytes 0-3 little endian,
#            tcpest_period_floor's sequence number)
#
# The sender's deadlines are not on the bus, so "nominal" is reconstructed:
# each frame gets its period index k (k steps by round(interval / period), so a
# missing frame is a gap, not a shift), a line t = a + b k is laid on the
# lower envelope of the time stamps (through the earliest frame, relative to
# the nominal grid, of the first and of the last quarter: it absorbs the
# offset and any drift between the sender's CLOCK_MONOTONIC and the
# receiver's time stamps, and late frames cannot tilt it), and
#   lateness_k = (t_k - (a + b k)) - min over k of the same,
# i.e. |actual - nominal| with the earliest frame taken as on time. Also the
# interval deviation |(t_k - t_k-1) - period| of consecutive frames.
#
# Prints a human-readable block and one machine-readable line:
#   RESULT LABEL n missing order_errors late_p50 late_p99 late_p999 late_max iv_p50 iv_p99 iv_p999 iv_max segments
# (microseconds). A silence of more than 25 periods starts a new segment
# (another sender run: its own grid, its own counter), fitted on its own. Exit 1 when the log holds fewer than 3 frames of the ID.
set -eu

if [ "$#" -lt 4 ]; then
  echo "usage: $0 LOG ID_HEX PERIOD_US LABEL [none|alive|seq32]" >&2
  exit 2
fi
log="$1"
id="$(echo "$2" | tr 'a-f' 'A-F' | sed 's/^0X//')"
period_us="$3"
label="$4"
counter="${5:-none}"

work="$(mktemp -d "${TMPDIR:-/tmp}/candump-jitter.XXXXXX")"
trap 'rm -rf "$work"' EXIT

# Pass 1: time stamps (us from the first frame), period index, counter checks;
# the fitted line; lateness and interval deviations to two files.
awk -v want="$id" -v T="$period_us" -v mode="$counter" -v out_late="$work/late" -v out_iv="$work/iv" -v out_sum="$work/sum" '
function hexval(s,    i, c, v) {
  v = 0
  s = toupper(s)
  for (i = 1; i <= length(s); i++) {
    c = index("0123456789ABCDEF", substr(s, i, 1))
    if (c == 0) return -1
    v = v * 16 + c - 1
  }
  return v
}
function byte(data, i) { return hexval(substr(data, 2 * i + 1, 2)) }
function rnd(x) { return x < 0 ? -int(-x + 0.5) : int(x + 0.5) }
BEGIN { n = 0; missing = 0; order = 0; segs = 0; short = 0; fitted = 0; gap = 25 }  # n indexes arrays: it must be the number 0, not ""
{
  if (substr($1, 1, 1) != "(") next
  split($3, f, "#")
  if (toupper(f[1]) != want) next
  ts = substr($1, 2, length($1) - 2)
  split(ts, p, ".")
  if (n == 0) sec0 = p[1]
  us = (p[1] - sec0) * 1000000 + substr(p[2] "000000", 1, 6)
  data = f[2]
  step = 0
  if (n > 0) step = rnd((us - t[n - 1]) / T)
  if (n == 0 || step > gap) {
    # A new segment: the first frame, or a silence of more than `gap` periods
    # (another sender process, with its own grid and counter).
    segs++
    first[segs] = n
    k = 0
  } else {
    if (step < 1) step = 1
    missing += step - 1
    k = kk[n - 1] + step
    iv[n] = us - t[n - 1]
    if (mode == "alive") {
      c = byte(data, 6) % 16
      # one step per message sent: a slip of the sender is a gap in time, not in the counter
      if (c != (prevc + 1) % 15) order++
    } else if (mode == "seq32") {
      c = byte(data, 0) + 256 * (byte(data, 1) + 256 * (byte(data, 2) + 256 * byte(data, 3)))
      if (c != prevc + step) order++
    }
  }
  if (mode == "alive") prevc = byte(data, 6) % 16
  else if (mode == "seq32") prevc = byte(data, 0) + 256 * (byte(data, 1) + 256 * (byte(data, 2) + 256 * byte(data, 3)))
  t[n] = us
  kk[n] = k
  n++
}
END {
  if (n < 3) {
    printf "%d 0 0 0 0 0\n", n > out_sum
    exit
  }
  first[segs + 1] = n
  dsum = 0
  for (g = 1; g <= segs; g++) {
    lo = first[g]; hi = first[g + 1] - 1
    m = hi - lo + 1
    if (m < 3) {
      # Too short to fit a line: counted in n, left out of the statistics.
      short += m
      continue
    }
    # The grid: slope from the lower envelope (the earliest frame of the
    # first and of the last quarter), which late frames cannot tilt as
    # they would a least-squares line.
    q = int(m / 4)
    i1 = lo; i2 = hi
    for (i = lo; i < lo + q; i++) if (t[i] - T * kk[i] < t[i1] - T * kk[i1]) i1 = i
    for (i = hi - q + 1; i <= hi; i++) if (t[i] - T * kk[i] < t[i2] - T * kk[i2]) i2 = i
    b = (kk[i2] > kk[i1]) ? (t[i2] - t[i1]) / (kk[i2] - kk[i1]) : T
    a = t[i1] - b * kk[i1]
    dsum += (b - T) / T * 1e6
    fitted += 1
    for (i = lo; i <= hi; i++) { r[i] = t[i] - (a + b * kk[i]); if (i == lo || r[i] < rmin) rmin = r[i] }
    for (i = lo; i <= hi; i++) printf "%.1f\n", r[i] - rmin > out_late
    for (i = lo + 1; i <= hi; i++) {
      d = iv[i] - T * rnd(iv[i] / T)
      printf "%.1f\n", (d < 0 ? -d : d) > out_iv
    }
  }
  printf "%d %d %d %d %.1f %d\n", n, missing, order, segs, (fitted > 0 ? dsum / fitted : 0), short > out_sum
}' "$log"

read -r n missing order segments drift_ppm short <"$work/sum"
if [ "$n" -lt 3 ]; then
  echo "$label: only $n frames with ID $id in $log" >&2
  exit 1
fi

# Nearest-rank quantiles of a file of numbers.
quantiles() {
  sort -g "$1" | awk '{ v[NR] = $1 } END {
    split("0.5 0.99 0.999 1", q, " ")
    for (j = 1; j <= 4; j++) { r = int(q[j] * NR + 0.999999); if (r < 1) r = 1; if (r > NR) r = NR; printf "%s%.1f", (j > 1 ? " " : ""), v[r] }
    printf "\n"
  }'
}
late="$(quantiles "$work/late")"
iv="$(quantiles "$work/iv")"
# shellcheck disable=SC2086 # word splitting of the four numbers is intended
set -- $late
echo "$label (ID 0x$id, nominal period $period_us us): $n frames in $segments segment(s), $missing missing, $order counter errors; clock drift $drift_ppm ppm"
[ "$short" -eq 0 ] || echo "  ($short frames in segments too short to fit, left out)"
printf '  %-44s p50 %8s  p99 %8s  p99.9 %8s  max %8s\n' "|actual - nominal| (us, earliest = on time)" "$1" "$2" "$3" "$4"
# shellcheck disable=SC2086
set -- $iv
printf '  %-44s p50 %8s  p99 %8s  p99.9 %8s  max %8s\n' "|interval - period| (us)" "$1" "$2" "$3" "$4"
echo "RESULT $label $n $missing $order $late $iv $segments"
