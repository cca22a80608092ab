#!/usr/bin/env bash
# Builds the libFuzzer targets of fuzz/ (preset PRESET, default `fuzz`:
# clang, ASan + UBSan, the targets only) and runs each for SECONDS (default 60) over a copy of its
# seed corpus, so that the checked-in corpus never grows. Fails when a target
# reports a crash, a leak, a timeout or running out of memory; the input that
# did it is kept in build/PRESET/findings/. Prints the executions of each
# target.
# Usage: toolchain/fuzz.sh [SECONDS [PRESET]]    (docs/fuzzing.md)
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-60}"
preset="${2:-fuzz}"
if ! [[ "$seconds" =~ ^[0-9]+$ ]] || [ "$seconds" -lt 1 ] || ! [[ "$preset" =~ ^[a-z0-9-]+$ ]]; then
  echo "usage: toolchain/fuzz.sh [SECONDS [PRESET]]" >&2
  exit 2
fi
build="build/$preset"
source toolchain/deps.sh
tcpest_install_deps "${TCPEST_BUILD_PACKAGES[@]}" clang libclang-rt-14-dev

cmake --preset "$preset" >/dev/null
if ! grep -q '^TCPEST_FUZZ:BOOL=ON' "$build/CMakeCache.txt"; then
  echo "fuzz.sh: preset $preset does not build the fuzz targets (TCPEST_FUZZ)" >&2
  exit 2
fi
nice cmake --build "$build" -j"$(nproc)" --target tcpest_fuzz_all

# Target and its largest input: a few times the seeds' size, so that the
# mutations stay close to real files. No input that small may make a reader
# take more than 256 MB at once (-malloc_limit_mb).
targets=(fuzz_json:16384 fuzz_yaml:16384 fuzz_jpeg:32768 fuzz_y4m:16384 fuzz_can:2048)

work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
findings="$build/findings"
mkdir -p "$findings"
failed=()
for entry in "${targets[@]}"; do
  name="${entry%%:*}"
  max_len="${entry##*:}"
  cp -r "fuzz/corpus/$name" "$work/$name"
  log="$work/$name.log"
  status=0
  nice "$build/fuzz/$name" -max_total_time="$seconds" -timeout=5 -rss_limit_mb=2048 -malloc_limit_mb=256 -max_len="$max_len" \
       -dict="fuzz/$name.dict" -artifact_prefix="$findings/$name-" -print_final_stats=1 \
       "$work/$name" >"$log" 2>&1 || status=$?
  runs="$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -n 1)"
  coverage="$(grep -o 'cov: [0-9]*' "$log" | tail -n 1 || true)"
  printf '%-10s %8s s  %10s executions  %s\n' "$name" "$seconds" "${runs:-?}" "${coverage:-}"
  if [ "$status" -ne 0 ]; then
    failed+=("$name")
    echo "--- $name failed (exit $status); its input is in $findings/:" >&2
    grep -E '^(==[0-9]+==ERROR|SUMMARY|.*runtime error|artifact_prefix|Test unit written)' "$log" >&2 || tail -n 30 "$log" >&2
  fi
done

if [ "${#failed[@]}" -ne 0 ]; then
  echo "fuzzing found faults in: ${failed[*]}" >&2
  exit 1
fi
echo "fuzzing: ${#targets[@]} targets, ${seconds} s each, no finding"
