#!/usr/bin/env python3
"""Writes the results page (Markdown) from the outputs of toolchain/results.sh.

Usage: results_table.py OUT   (reads OUT/eval_*.txt and OUT/run_*.txt, prints Markdown)
"""
import re
import sys
from pathlib import Path

# The three sources, side by side: our renderer's default look, its
# randomised looks (`tcpest render --randomise`, the same poses), and the
# independent frames.
SOURCES = ["ours", "ours, randomised", "independent"]
# (column title, the evaluate outputs of each source; None: no such set)
SETS = [
    ("lab", ("own_lab", "rnd_lab", "ind_lab")),
    ("hard", ("own_hard", "rnd_hard", "ind_hard")),
    ("sequence, no encoders", ("own_seq", "rnd_seq", "ind_seq")),
    ("curved tube, miscalibrated", (None, None, "ind_real")),
    ("HD camera", ("own_hd", "rnd_hd", "ind_hd")),
]
RUNS = [("sequence, no encoders", ("own_seq", "rnd_seq", "ind_seq"))]


def header_cells(groups):
    return " | ".join(f"{title}: {source}" for title, _ in groups for source in SOURCES)


def number(pattern, text, group=1, cast=float):
    m = re.search(pattern, text)
    return cast(m.group(group)) if m else None


def read_eval(path):
    t = path.read_text()
    frames = number(r"frame success \(>= 80 % of visible corners found and labelled\): [\d.]+ % of (\d+) frames", t,
                    cast=int)
    none = number(r"frames not succeeding: \d+ \(no estimate (\d+)", t, cast=int)
    rms = re.search(r"valid estimates: (\d+); TCP error median ([\d.na]+) mm, RMS x/y/z ([\d.na]+) / ([\d.na]+) / "
                    r"([\d.na]+) mm, over 3 mm: (\d+)", t)
    scored = number(r"(\d+) images scored", t, cast=int)
    # The same valid frames, the TCP of the image fit's pose (docs/solver.md, "The image fit's pose and the TCP").
    fit = re.search(r"the image fit's pose instead \((\d+) of the valid.*?: valid TCP error median ([\d.na]+) mm, "
                    r"RMS x/y/z ([\d.na]+) / ([\d.na]+) / ([\d.na]+) mm, over 3 mm: (\d+);", t)
    return {
        "found": number(r"correctly labelled: ([\d.]+) %", t),
        "median_px": number(r"median corner error \(found ones\): ([\d.na]+) px", t),
        "off": number(r"found corners farther than [\d.]+ px from their truth: ([\d.]+) %", t),
        "mislabelled": number(r"another corner's: ([\d.]+) %", t),
        "success": number(r"frame success \(>= 80 % of visible corners found and labelled\): ([\d.]+) %", t),
        "frames": frames,
        "none": 100.0 * none / scored if none is not None and scored else None,
        "valid": int(rms.group(1)) if rms else None,
        "valid_share": 100.0 * int(rms.group(1)) / scored if rms and scored else None,
        "tcp_rms": "/".join(rms.group(i) for i in (3, 4, 5)) if rms else None,
        "valid_far": int(rms.group(6)) if rms else None,
        "tcp_median": rms.group(2) if rms else None,
        "fit_valid": int(fit.group(1)) if fit else None,
        "fit_tcp_median": fit.group(2) if fit else None,
        "fit_tcp_rms": "/".join(fit.group(i) for i in (3, 4, 5)) if fit else None,
        "fit_valid_far": int(fit.group(6)) if fit else None,
        "stages_us": number(r"stages 1-4 (\d+) us", t),
        "solve_us": number(r"solver (\d+) us", t),
    }


def read_truth_solve(path):
    """eq8_from_truth.py's line: eq. 8 solved from the exact visible corners."""
    m = re.search(r"TCP error median ([\d.]+) mm, RMS x/y/z ([\d.]+) / ([\d.]+) / ([\d.]+) mm, over 3 mm: (\d+); "
                  r"corner residual RMS median ([\d.]+) px, 90th percentile ([\d.]+) px", path.read_text())
    if not m:
        return {}
    return {"truth_tcp_median": m.group(1), "truth_tcp_rms": "/".join(m.group(i) for i in (2, 3, 4)),
            "truth_far": int(m.group(5)), "truth_residual": f"{m.group(6)} / {m.group(7)}"}


def read_reading(path):
    """vision_reading_eval's report of one dataset (the readers at the true pose)."""
    t = path.read_text()
    tube = re.search(r"silhouette, tube +\d+ sampled: read +([\d.]+) %, within [\d.]+ px +([\d.]+) %, beyond +([\d.]+) %; "
                     r"median offset ([-+\d.]+) px", t)
    shaft = re.search(r"silhouette, shaft +\d+ sampled: read +([\d.]+) %, within [\d.]+ px +([\d.]+) %", t)
    colour = re.search(r"boundaries 1-4: +\d+ visible corners, measured +([\d.]+) %; of those off along +([\d.]+) %, "
                       r"across +([\d.]+) %", t)
    tip = re.search(r"boundary 5: +\d+ visible corners, measured +([\d.]+) %", t)
    inside = re.search(r"model off by d px: .* d -2: +([\d.]+) %", t)
    outside = re.search(r"model off by d px: .* d \+2: +([\d.]+) %", t)
    along = re.findall(r"boundary \d: .*along median ([-+\d.]+) px", t)
    return {
        "tube_good": float(tube.group(2)) if tube else None,
        "tube_bad": float(tube.group(3)) if tube else None,
        "tube_offset": float(tube.group(4)) if tube else None,
        "tube_inside": float(inside.group(1)) if inside else None,
        "tube_outside": float(outside.group(1)) if outside else None,
        "shaft_good": float(shaft.group(2)) if shaft else None,
        "measured": float(colour.group(1)) if colour else None,
        "off_along": float(colour.group(2)) if colour else None,
        "off_across": float(colour.group(3)) if colour else None,
        "tip_measured": float(tip.group(1)) if tip else None,
        "along": "/".join(f"{float(a):+.2f}" for a in along) if along else None,
    }


STEPS = ["acquire", "classify", "interpret", "borders", "corners", "solve", "refine", "publish", "housekeeping"]


def read_run(path):
    t = path.read_text()
    steps = {}
    for name in STEPS:
        m = re.search(r"^" + name + r"\s+([\d.]+)\s+([\d.]+)\s+([\d.]+)\s+([\d.]+)\s+([\d.]+)\s+([\d.]+)\s+(\d+)",
                      t, re.M)
        if m:
            steps[name] = (float(m.group(1)), float(m.group(2)), float(m.group(4)), int(m.group(7)))
    total = re.search(r"^total\s+([\d.]+)\s+([\d.]+)\s+([\d.]+)\s+([\d.]+)\s+([\d.]+)\s+([\d.]+)\s+(\d+)", t, re.M)
    refine = re.search(r"^refine\s+([\d.]+)\s+([\d.]+)\s+([\d.]+)\s+([\d.]+)", t, re.M)
    return {
        "valid_share": number(r"valid share ([\d.]+) %", t),
        "cycles": number(r"^cycles (\d+)", t, cast=int) if re.search(r"^cycles", t, re.M) else None,
        "budget": float(total.group(1)) if total else None,
        "p50": float(total.group(2)) if total else None,
        "p999": float(total.group(4)) if total else None,
        "overruns": int(total.group(7)) if total else None,
        "refine_p999": float(refine.group(4)) if refine else None,
        "steps": steps,
    }


def fmt(v, spec):
    if v is None:
        return "—"
    if isinstance(v, str):
        return v
    return format(v, spec)


def print_set_table(rows, by_set, groups=SETS):
    """One row per (label, key, format) of `rows`, one column per set of `groups` and source."""
    print("| | " + header_cells(groups) + " |")
    print("|---" * (1 + len(SOURCES) * len(groups)) + "|")
    for label, key, spec in rows:
        cells = []
        for _, names in groups:
            for name in names:
                cells.append(fmt(by_set.get(name, {}).get(key) if name else None, spec))
        print(f"| {label} | " + " | ".join(cells) + " |")


def main():
    out = Path(sys.argv[1])
    evals = {p.stem[5:]: read_eval(p) for p in out.glob("eval_*.txt")}
    runs = {p.stem[4:]: read_run(p) for p in out.glob("run_*.txt")}
    readings = {p.stem[8:]: read_reading(p) for p in out.glob("reading_*.txt")}
    for p in out.glob("truth_solve_*.txt"):
        evals.setdefault(p.stem[12:], {}).update(read_truth_solve(p))
    print("# Results\n")
    print("Generated by `toolchain/results.sh` (do not edit): the configuration `tcpest run` ships (the estimator's")
    print("built-in defaults), scored by `tcpest evaluate` on our renderer's sets (lab seed 77, hard seed 78,")
    print("sequence seed 79, lab with the HD camera seed 82; 294 / 294 / 100 / 60 frames), on the same poses with")
    print("randomised looks (`tcpest render --randomise`: paint, gloss, tissue tint, white balance, exposure, noise,")
    print("blur, vignetting, JPEG quality and chroma subsampling per image, the shaft's and grasper's radii and the")
    print("lamp's place per set; docs/rendering.md) and on the independent")
    print("frames of `../shared/data/independent`")
    print("(pal_lab, pal_hard, pal_seq, pal_real, hd_lab), side by side; our renderer has no curved tube. Sets")
    print("with encoder priors use the sidecars'")
    print("(truth + up to 3 mm and 0.2 rad); the sequences run without encoders (`--no-prior`).\n")
    rows = [
        ("corners found within 1.5 px and labelled (%)", "found", ".1f"),
        ("median corner error (px)", "median_px", ".3f"),
        ("found corners > 1.5 px off (%)", "off", ".1f"),
        ("... of which another corner's label (%)", "mislabelled", ".2f"),
        ("frame success, paper's 80 % rule (%)", "success", ".1f"),
        ("frames with no estimate (%)", "none", ".1f"),
        ("valid estimates (% of frames)", "valid_share", ".1f"),
        ("valid estimates > 3 mm off (count)", "valid_far", "d"),
        ("valid TCP error median (mm)", "tcp_median", ""),
        ("valid TCP RMS x/y/z (mm)", "tcp_rms", ""),
        ("the image fit's pose on the valid frames with a fit (count)", "fit_valid", "d"),
        ("... its TCP error median (mm)", "fit_tcp_median", ""),
        ("... its TCP RMS x/y/z (mm)", "fit_tcp_rms", ""),
        ("... its TCP more than 3 mm off (count)", "fit_valid_far", "d"),
        ("eq. 8 from the exact visible corners: TCP error median (mm)", "truth_tcp_median", ""),
        ("... its TCP RMS x/y/z (mm)", "truth_tcp_rms", ""),
        ("... its TCP more than 3 mm off (count of all frames)", "truth_far", "d"),
        ("... its corner residual RMS, median / 90th percentile (px)", "truth_residual", ""),
        ("median time, stages 1-4 (us)", "stages_us", ".0f"),
        ("median time, solve and refine (us)", "solve_us", ".0f"),
        ("frames", "frames", "d"),
    ]
    print_set_table(rows, evals)
    print("\nThe TCP sent is that of the solve of eq. 8 from the corners read (model.md). The rows \"the image fit's")
    print("pose\" score, on the same valid frames, the pose the corners were read at: the change of contract")
    print("docs/solver.md proposes (\"The image fit's pose and the TCP\").")
    print("The rows \"eq. 8 from the exact visible corners\" solve eq. 8 (`tcpest solve`) from each frame's true")
    print("corners, started at its true joints (toolchain/eq8_from_truth.py), on every frame: the TCP error no reading")
    print("of the image can remove under this contract.")
    print("\n## The loop (`tcpest run --no-pacing`, no encoders)\n")
    run_rows = [
        ("valid share (%)", "valid_share", ".1f"),
        ("cycle median (ms)", "p50", ".2f"),
        ("cycle p99.9 (ms)", "p999", ".2f"),
        ("refine step p99.9 (ms)", "refine_p999", ".2f"),
        ("cycles over the budget", "overruns", "d"),
        ("cycle budget (ms)", "budget", ".2f"),
    ]
    print_set_table(run_rows, runs, RUNS)
    print("\nPer step (ms): budget, then p50 / p99.9 and the cycles over the step's budget.\n")
    print("| step | budget | " + header_cells(RUNS) + " |")
    print("|---" * (2 + len(SOURCES) * len(RUNS)) + "|")
    for name in STEPS:
        cells = []
        budget = None
        for _, names in RUNS:
            for run in names:
                step = runs.get(run, {}).get("steps", {}).get(name)
                if step:
                    budget = step[0]
                    cells.append(f"{step[1]:.3f} / {step[2]:.3f} ({step[3]})")
                else:
                    cells.append("—")
        print(f"| {name} | {fmt(budget, '.1f')} | " + " | ".join(cells) + " |")
    print("\nTimes are of the machine that ran the command; compare columns of one run, not runs of different days.")
    if readings:
        print("\n## The readers at the true pose (`vision_reading_eval`)\n")
        print("At each frame's true pose (its sidecar's r) the model lies on the image: what a reader reports there")
        print("is its own error, with no fit, solve or track in between (docs/vision.md, \"Reading accuracy at the")
        print("true pose\"). Silhouettes: the image fit's reader at its sample points, per cent of the points sampled;")
        print("with the model moved 2 px along the normal, the reading must point back to the true silhouette.")
        print("Corners: `refine_corners` at the true pose; a measured corner is off when its part along the tube or")
        print("across it exceeds 0.7 px.\n")
        reading_rows = [
            ("tube silhouette read within 1 px (%)", "tube_good", ".1f"),
            ("tube silhouette read beyond 1 px (%)", "tube_bad", ".1f"),
            ("tube silhouette, median offset (px, outwards)", "tube_offset", "+.3f"),
            ("... with the model 2 px inside: read back within 1 px (%)", "tube_inside", ".1f"),
            ("... with the model 2 px outside: read back within 1 px (%)", "tube_outside", ".1f"),
            ("shaft silhouette read within 1 px (%)", "shaft_good", ".1f"),
            ("boundaries 1-4: corners measured (%)", "measured", ".1f"),
            ("... measured, off along (%)", "off_along", ".1f"),
            ("... measured, off across (%)", "off_across", ".1f"),
            ("tip boundary: corners measured (%)", "tip_measured", ".1f"),
            ("along median, boundaries 1-5 (px, towards the tip)", "along", ""),
        ]
        print_set_table(reading_rows, readings)


if __name__ == "__main__":
    main()
