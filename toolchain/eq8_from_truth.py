#!/usr/bin/env python3
"""The floor of eq. 8 on a dataset: `tcpest solve` (the estimator's solve of eq. 8, model.md) given each
frame's exact visible corners from its sidecar, with the sidecar's true joints as the start; prints the TCP
error of the solutions against the sidecars' truth. What no corner reader can improve on: the error that
remains comes from eq. 8 itself (its channel penalty, the corners' geometry), not from the image. The
solutions' corner residual is printed too: the validity test compares the solve's with a limit
(EstimatorConfig's max_rms_valid_px), and a residual above it here is one no corner reader can lower.

Usage: eq8_from_truth.py TCPEST DIR [SOLVE OPTIONS...]   (e.g. --calib CAM.yaml --config CFG.yaml, as `tcpest solve` takes them)
"""
import json
import math
import statistics
import subprocess
import sys
from pathlib import Path


def main():
    if len(sys.argv) < 3:
        sys.exit("usage: eq8_from_truth.py TCPEST DIR [SOLVE OPTIONS...]")
    tcpest, folder = sys.argv[1], Path(sys.argv[2])
    requests, truths = [], []
    for sidecar in sorted(folder.glob("*.json")):
        try:
            s = json.loads(sidecar.read_text())
            corners = [c if visible else None for c, visible in zip(s["corners"], s["corner_visible"])]
            joints = s["r"][4:7]
            truth = [float(v) for v in s["tcp"]]
        except (OSError, ValueError, KeyError, TypeError) as error:
            sys.exit(f"eq8_from_truth: {sidecar}: not a sidecar with r, tcp, corners and corner_visible ({error!r})")
        requests.append(json.dumps({"corners": corners, "prior": joints}))
        truths.append(truth)
    if not requests:
        sys.exit(f"eq8_from_truth: no sidecar in {folder}")
    args = [tcpest, "solve", "--corners", "-"] + sys.argv[3:]
    try:
        done = subprocess.run(args, input="\n".join(requests) + "\n", capture_output=True, text=True, check=False)
    except OSError as error:
        sys.exit(f"eq8_from_truth: cannot run {tcpest}: {error}")
    errors, residuals = [], []
    for line, truth in zip(done.stdout.splitlines(), truths):
        try:
            solved = json.loads(line)
        except ValueError:
            sys.exit(f"eq8_from_truth: {tcpest} solve printed a line that is not JSON: {line[:200]}")
        if solved.get("tcp") is not None:
            errors.append([a - b for a, b in zip(solved["tcp"], truth)])
            residuals.append(solved["rms_px"])
    if not errors:
        sys.exit(f"eq8_from_truth: no solution in {folder} ({done.stderr.strip()})")
    norms = [math.sqrt(sum(e * e for e in err)) for err in errors]
    rms = [math.sqrt(sum(err[i] ** 2 for err in errors) / len(errors)) for i in range(3)]
    print(f"eq. 8 from the true corners: {len(errors)} of {len(requests)} frames solved; TCP error median "
          f"{statistics.median(norms):.2f} mm, RMS x/y/z {rms[0]:.2f} / {rms[1]:.2f} / {rms[2]:.2f} mm, "
          f"over 3 mm: {sum(n > 3.0 for n in norms)}; corner residual RMS median {statistics.median(residuals):.2f} px, "
          f"90th percentile {sorted(residuals)[int(0.9 * len(residuals))]:.2f} px")


if __name__ == "__main__":
    main()
