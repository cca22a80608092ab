#!/usr/bin/env bash
# The results page: the shipped configuration (the estimator's built-in
# defaults, the same `tcpest run` uses) scored on both data sources side by
# side -- our renderer's sets at fixed seeds (with its default look and with
# randomised looks) and the independent frames in ../shared/data/independent
# -- the loop's cycle times on a sequence of each, and the model-guided readers at
# each annotated frame's true pose (vision_reading_eval). Writes OUT/results.md (default build/results); with --docs also
# docs/results.md, the committed page. A few minutes on two cores.
#
#   toolchain/results.sh --docs      (regenerates docs/results.md)
#   toolchain/results.sh [OUT]
#   CONFIG=candidate.yaml toolchain/results.sh OUT   (a candidate configuration: its loop: section, for both commands)
#   TCPEST=path/to/tcpest EVALUATE_ARGS="--guided-rounds 0" toolchain/results.sh OUT   (another build or setting)
set -euo pipefail
cd "$(dirname "$0")/.."
docs=0
if [ "${1:-}" = "--docs" ]; then
  docs=1
  shift
fi
out="${1:-build/results}"
tcpest="${TCPEST:-build/default/firmware_like/tcpest}"
independent="${INDEPENDENT_DIR:-../shared/data/independent}"
read -r -a extra <<<"${EVALUATE_ARGS:-}"
config_args=()
[ -n "${CONFIG:-}" ] && config_args=(--config "$CONFIG")
if [ ! -x "$tcpest" ]; then
  echo "results: no tcpest at $tcpest (build first: cmake --preset default && cmake --build build/default)" >&2
  exit 1
fi
if [ ! -d "$independent" ]; then
  echo "results: the independent frames are not at $independent (set INDEPENDENT_DIR)" >&2
  exit 1
fi
mkdir -p "$out"

# Our renderer's sets: the documented seeds (lab 77, hard 78, sequence 79,
# lab with the independent set's HD camera 82).
frames="${OWN_FRAMES:-294}"
[ -d "$out/own_lab" ] || "$tcpest" render --set lab --n "$frames" --seed 77 --out "$out/own_lab" --quiet
[ -d "$out/own_hard" ] || "$tcpest" render --set hard --n "$frames" --seed 78 --out "$out/own_hard" --quiet
[ -d "$out/own_seq" ] || "$tcpest" render --set seq --n 100 --seed 79 --out "$out/own_seq" --quiet

pal="$independent/cams/pal.yaml"
hd="$independent/cams/hd.yaml"
[ -d "$out/own_hd" ] || "$tcpest" render --set lab --n 60 --seed 82 --calib "$hd" --out "$out/own_hd" --quiet
# The same poses with randomised looks (docs/rendering.md, "Randomised
# appearance"): what our renderer's one look alone rewards shows here.
[ -d "$out/rnd_lab" ] || "$tcpest" render --set lab --n "$frames" --seed 77 --randomise --out "$out/rnd_lab" --quiet
[ -d "$out/rnd_hard" ] || "$tcpest" render --set hard --n "$frames" --seed 78 --randomise --out "$out/rnd_hard" --quiet
[ -d "$out/rnd_seq" ] || "$tcpest" render --set seq --n 100 --seed 79 --randomise --out "$out/rnd_seq" --quiet
[ -d "$out/rnd_hd" ] || "$tcpest" render --set lab --n 60 --seed 82 --randomise --calib "$hd" --out "$out/rnd_hd" --quiet
# Every scored set, once: NAME CALIB DIR [EVALUATE ARGS] (the sequences run
# without encoders). Both evaluate and the readers' tool go through it.
sets=(
  "own_lab||$out/own_lab"
  "own_hard||$out/own_hard"
  "own_seq||$out/own_seq|--no-prior"
  "ind_lab|$pal|$independent/pal_lab"
  "ind_hard|$pal|$independent/pal_hard"
  "ind_real|$pal|$independent/pal_real"
  "ind_seq|$pal|$independent/pal_seq|--no-prior"
  "rnd_lab||$out/rnd_lab"
  "rnd_hard||$out/rnd_hard"
  "rnd_seq||$out/rnd_seq|--no-prior"
  "own_hd|$hd|$out/own_hd"
  "rnd_hd|$hd|$out/rnd_hd"
  "ind_hd|$hd|$independent/hd_lab"
)
# calib_args: the --calib option for a camera file, none for the built-in camera.
calib_option() {  # CALIB
  calib_args=()
  if [ -n "$1" ]; then calib_args=(--calib "$1"); fi
}
# One entry of `sets` into name, dir, set_args and calib_args.
read_set() {  # ENTRY
  local calib
  IFS='|' read -r name calib dir set_args <<<"$1"
  calib_option "$calib"
}
for entry in "${sets[@]}"; do
  read_set "$entry"
  read -r -a set_extra <<<"$set_args"
  "$tcpest" evaluate "${calib_args[@]}" "${config_args[@]}" "${extra[@]}" "${set_extra[@]}" "$dir" >"$out/eval_$name.txt"
done

# The floor of eq. 8: its solve from each frame's exact visible corners
# (toolchain/eq8_from_truth.py), what no reading of the image can beat.
for entry in "${sets[@]}"; do
  read_set "$entry"
  python3 toolchain/eq8_from_truth.py "$tcpest" "$dir" "${calib_args[@]}" "${config_args[@]}" >"$out/truth_solve_$name.txt"
done

# The loop itself on a sequence of each source (no encoders, as fast as it goes).
run() {  # NAME CALIB DIR
  calib_option "$2"
  "$tcpest" run "${calib_args[@]}" "${config_args[@]}" --source "$3" --bus "log:$out/run_$1.log" --no-pacing --start-operational --quiet >"$out/run_$1.txt"
}
run own_seq "" "$out/own_seq"
run rnd_seq "" "$out/rnd_seq"
run ind_seq "$pal" "$independent/pal_seq"

# The model-guided readers at each annotated frame's true pose
# (vision_reading_eval, docs/vision.md "Reading accuracy at the true pose").
reading_eval="${READING_EVAL:-$(dirname "$tcpest")/../vision/test/vision_reading_eval}"
rm -f "$out"/reading_*.txt
if [ -x "$reading_eval" ]; then
  for entry in "${sets[@]}"; do
    read_set "$entry"
    "$reading_eval" "${calib_args[@]}" "$dir" >"$out/reading_$name.txt"
  done
else
  echo "results: no vision_reading_eval at $reading_eval: the readers' table is left out" >&2
fi

python3 toolchain/results_table.py "$out" >"$out/results.md"
echo "results: $out/results.md"
if [ "$docs" -eq 1 ]; then
  cp "$out/results.md" docs/results.md
  echo "results: docs/results.md"
fi
