#!/usr/bin/env bash
# cppcheck's MISRA C:2012 addon over the flight code of the core units (the
# sources of the libraries the loop links: tcpest_common, tcpest_solver,
# tcpest_vision, tcpest_can_iface, tcpest_loop), their headers included.
# Prints the count of findings per rule, writes every finding to
# build/misra/findings.txt, and compares the counts with
# toolchain/misra-baseline.txt: exit 1 when a rule's count grew or a rule
# not in the baseline appears. Each rule of the baseline is a deviation
# justified in docs/coding-rules.md.
#   toolchain/misra.sh                    check against the baseline
#   toolchain/misra.sh --update-baseline  rewrite the baseline from this run
set -euo pipefail
cd "$(dirname "$0")/.."
update=0
[ "${1:-}" = "--update-baseline" ] && update=1
baseline=toolchain/misra-baseline.txt
out=build/misra
mkdir -p "$out"

# The sources of a library, read from its tcpest_(core_)library(...) call,
# so that a file added to a flight library is analysed without editing this
# script. Simulation and offline tools (tcpest_loop_sim, tcpest_vision_dense,
# tcpest_hal_render) are separate libraries and stay out.
library_sources() { # unit-dir target
  awk -v target="$2" '
    $0 ~ "^tcpest_(core_)?library\\(" target "[ )]" { on = 1 }
    on { for (i = 1; i <= NF; i++) if ($i ~ /\.cpp\)?$/) { f = $i; sub(/\)$/, "", f); print f } }
    on && /\)/ { on = 0 }' "$1/CMakeLists.txt" | sed "s|^|$1/|"
}
sources=()
for pair in common:tcpest_common solver:tcpest_solver vision:tcpest_vision can_iface:tcpest_can_iface \
            firmware_like/loop:tcpest_loop; do
  mapfile -t -O "${#sources[@]}" sources < <(library_sources "${pair%%:*}" "${pair#*:}")
done
for f in "${sources[@]}"; do
  [ -f "$f" ] || { echo "misra: $f (from a CMakeLists) does not exist"; exit 1; }
done
if [ "${#sources[@]}" -lt 30 ]; then
  echo "misra: only ${#sources[@]} sources read from the CMakeLists; has their layout changed?"; exit 1
fi

# The include directories of toolchain/lint.sh. Eigen and the system headers
# are not passed: they are not ours (missingIncludeSystem), and parsing Eigen
# would take most of the time.
includes=()
for dir in common/include solver/include vision/include can_iface/include hal/*/include firmware_like/loop/include \
           firmware_like/src; do
  [ -d "$dir" ] && includes+=("-I$dir")
done

echo "misra: ${#sources[@]} files"
raw="$out/raw.txt"
# The addon reports a header's findings from every file that includes it:
# sort -u keeps one of each.
nice -n 10 cppcheck --std=c++17 --language=c++ --addon=misra --quiet \
  --suppress=missingIncludeSystem --cppcheck-build-dir="$out" \
  --template='{file}:{line}:{column}: {id}: {message}' \
  "${includes[@]}" "${sources[@]}" 2>"$raw"
sort -u -t: -k1,1 -k2,2n -k3,3n -k4 "$raw" >"$out/findings.txt"

# Rule per finding: "misra-c2012-12.3" is rule 12.3; anything else cppcheck
# itself reported (a syntax error, a misra-config) keeps its id and counts
# like a rule.
counts="$out/counts.txt"
sed -E -n 's/^[^:]+:[0-9]+:[0-9]+: ([^:]+): .*/\1/p' "$out/findings.txt" | sed 's/^misra-c2012-//' |
  sort | uniq -c | awk '{ print $2, $1 }' | sort -V >"$counts"
if [ "$(wc -l <"$out/findings.txt")" -ne "$(awk '{ n += $2 } END { print n + 0 }' "$counts")" ]; then
  echo "misra: lines of $out/findings.txt not in the file:line:column: id: form:"
  grep -v -E '^[^:]+:[0-9]+:[0-9]+: [^:]+: ' "$out/findings.txt"; exit 1
fi
printf '%-8s %s\n' rule count
awk '{ printf "%-8s %s\n", $1, $2 }' "$counts"
echo "misra: $(awk '{ n += $2 } END { print n + 0 }' "$counts") findings ($out/findings.txt)"

if [ "$update" -eq 1 ]; then
  { echo "# rule count: findings of toolchain/misra.sh per MISRA C:2012 rule; every"
    echo "# rule here is a deviation of docs/coding-rules.md. The counts may fall"
    echo "# (toolchain/misra.sh --update-baseline), never grow."
    cat "$counts"; } >"$baseline"
  echo "misra: $baseline rewritten"; exit 0
fi

# Compare with the baseline: a rule's count may fall, never grow.
status=0
fell=0
declare -A allowed=()
while read -r rule count; do
  allowed["$rule"]="$count"
done < <(grep -v -E '^(#|$)' "$baseline")
while read -r rule count; do
  if [ -z "${allowed[$rule]+x}" ]; then
    echo "misra: rule $rule: $count findings, and it is not a deviation of $baseline (fix them; see $out/findings.txt)"
    status=1
  elif [ "$count" -gt "${allowed[$rule]}" ]; then
    echo "misra: rule $rule: $count findings, more than the ${allowed[$rule]} of $baseline (see $out/findings.txt)"
    status=1
  elif [ "$count" -lt "${allowed[$rule]}" ]; then
    fell=1
  fi
  unset "allowed[$rule]"
done <"$counts"
for rule in "${!allowed[@]}"; do
  [ "${allowed[$rule]}" -gt 0 ] && fell=1
done
if [ "$fell" -eq 1 ]; then
  echo "misra: counts fell below $baseline; lower it: toolchain/misra.sh --update-baseline"
  echo "       (and drop from docs/coding-rules.md the deviations that no longer have findings)"
fi
if [ "$status" -ne 0 ]; then
  exit 1
fi
echo "misra: within $baseline"
