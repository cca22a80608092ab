#!/usr/bin/env python3
"""Traceability between docs/requirements.md and the tests.

A requirement is a line `- **REQ-<UNIT>-<NNN>** text` of docs/requirements.md.
A test verifies requirements when a comment in the comment block directly
above its TEST / TEST_F / TEST_P / TYPED_TEST line says so:

    // Verifies: REQ-CAN-004, REQ-CAN-005
    TEST(Crc8, CatalogueCheckValue) {

Test sources are every .cpp/.hpp/.h/.cc file in a `test` folder or under
`tests/` (build folders and .git left out).

Fails (exit 1), naming them, on: a requirement no test verifies, a test
naming an unknown requirement, a malformed or duplicated requirement id, a
marker that is not directly above a test, a design note (docs/*.md)
naming an unknown requirement.

    toolchain/trace.py                       check
    toolchain/trace.py --matrix              check, then print the trace matrix (Markdown)
    toolchain/trace.py --check-matrix FILE   check, and that FILE is the matrix as printed now

Python 3 standard library only.
"""

import argparse
import os
import re
import sys
from collections import OrderedDict

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
REQUIREMENTS = os.path.join("docs", "requirements.md")
UNITS = ("MODEL", "SOLVER", "VISION", "LOOP", "CAN", "HAL", "ERR")
UNIT_TITLES = {
    "MODEL": "camera and instrument model",
    "SOLVER": "pose solver and the estimate's status",
    "VISION": "feature extraction and the frame estimator",
    "LOOP": "the cyclic executive",
    "CAN": "the protocol node",
    "HAL": "camera, CAN and clock backends",
    "ERR": "reading outside input, reporting errors",
}
SOURCE_SUFFIXES = (".cpp", ".hpp", ".h", ".cc")

REQ_LINE = re.compile(r"^- \*\*(REQ-[A-Z]+-[0-9]+)\*\*\s+(.*)$")
REQ_ID = re.compile(r"^REQ-(" + "|".join(UNITS) + r")-([0-9]{3})$")
TEST_LINE = re.compile(r"^\s*(TEST|TEST_F|TEST_P|TYPED_TEST|TYPED_TEST_P)\(\s*(\w+)\s*,\s*(\w+)\s*\)")
MARKER = re.compile(r"^\s*//\s*Verifies:\s*(.*?)\s*$")
COMMENT = re.compile(r"^\s*//")
DOC_REFERENCE = re.compile(r"\bREQ-[A-Z]+-[0-9]+\b")


class Requirement:
    def __init__(self, req_id, text, line):
        self.req_id = req_id
        self.text = text
        self.line = line
        self.tests = []  # (test name, file), in source order


def sort_key(req_id):
    match = REQ_ID.match(req_id)
    return (UNITS.index(match.group(1)), int(match.group(2)))


def read_requirements(errors):
    path = os.path.join(ROOT, REQUIREMENTS)
    requirements = OrderedDict()
    try:
        with open(path, encoding="utf-8") as handle:
            lines = handle.read().splitlines()
    except OSError as error:
        errors.append("%s: cannot read: %s" % (REQUIREMENTS, error.strerror))
        return requirements
    for number, line in enumerate(lines, start=1):
        match = REQ_LINE.match(line)
        if not match:
            if line.startswith("- **REQ"):
                errors.append("%s:%d: malformed requirement line" % (REQUIREMENTS, number))
            continue
        req_id, text = match.group(1), match.group(2)
        if not REQ_ID.match(req_id):
            errors.append("%s:%d: %s: not REQ-<UNIT>-<NNN> with UNIT one of %s"
                          % (REQUIREMENTS, number, req_id, ", ".join(UNITS)))
            continue
        if req_id in requirements:
            errors.append("%s:%d: %s defined again (first at line %d)"
                          % (REQUIREMENTS, number, req_id, requirements[req_id].line))
            continue
        requirements[req_id] = Requirement(req_id, text, number)
    if not requirements and not errors:
        errors.append("%s: no requirement found" % REQUIREMENTS)
    return requirements


def test_sources():
    found = []
    for directory, subdirectories, files in os.walk(ROOT):
        subdirectories[:] = sorted(d for d in subdirectories
                                   if not d.startswith("build") and not d.startswith("."))
        relative = os.path.relpath(directory, ROOT)
        parts = [] if relative == "." else relative.split(os.sep)
        if "test" not in parts and (not parts or parts[0] != "tests"):
            continue
        for name in sorted(files):
            if name.endswith(SOURCE_SUFFIXES):
                found.append(os.path.join(relative, name))
    return found


def read_markers(path, errors):
    """(test name, [requirement ids], line) of every test with a marker."""
    try:
        with open(os.path.join(ROOT, path), encoding="utf-8", errors="replace") as handle:
            lines = handle.read().splitlines()
    except OSError as error:
        errors.append("%s: cannot read: %s" % (path, error.strerror))
        return []
    traced = []
    pending = []  # ids of the markers in the current comment block
    pending_line = 0
    for number, line in enumerate(lines, start=1):
        marker = MARKER.match(line)
        if marker:
            if not pending:
                pending_line = number
            for token in (t.strip() for t in marker.group(1).split(",")):
                if not REQ_ID.match(token):
                    errors.append("%s:%d: '%s' is not a requirement id" % (path, number, token))
                else:
                    pending.append(token)
            continue
        if COMMENT.match(line):
            continue
        test = TEST_LINE.match(line)
        if test and pending:
            traced.append(("%s.%s" % (test.group(2), test.group(3)), pending, pending_line))
        elif pending:
            errors.append("%s:%d: Verifies marker not directly above a TEST" % (path, pending_line))
        pending = []
    if pending:
        errors.append("%s:%d: Verifies marker not directly above a TEST" % (path, pending_line))
    return traced


def check_doc_references(requirements, errors):
    """Every requirement id another design note names (safety.md, ...) exists."""
    docs = os.path.join(ROOT, "docs")
    for name in sorted(os.listdir(docs)):
        if not name.endswith(".md") or name in ("requirements.md", "trace.md"):
            continue
        with open(os.path.join(docs, name), encoding="utf-8") as handle:
            for number, line in enumerate(handle, start=1):
                for req_id in DOC_REFERENCE.findall(line):
                    if req_id not in requirements:
                        errors.append("docs/%s:%d: names unknown requirement %s" % (name, number, req_id))


def trace(errors):
    requirements = read_requirements(errors)
    for path in test_sources():
        for test, ids, line in read_markers(path, errors):
            for req_id in ids:
                if req_id not in requirements:
                    errors.append("%s:%d: %s names unknown requirement %s" % (path, line, test, req_id))
                elif (test, path) not in requirements[req_id].tests:
                    requirements[req_id].tests.append((test, path))
    check_doc_references(requirements, errors)
    for requirement in requirements.values():
        if not requirement.tests:
            errors.append("%s:%d: %s has no verifying test"
                          % (REQUIREMENTS, requirement.line, requirement.req_id))
    return requirements


def matrix(requirements):
    out = ["# Trace matrix", "",
           "Generated by `toolchain/trace.py --matrix > docs/trace.md`; do not edit by hand.",
           "Requirements: [requirements.md](requirements.md). A test verifies a requirement",
           "when a `// Verifies: REQ-...` comment stands directly above it. CI runs",
           "`toolchain/trace.py --check-matrix docs/trace.md` (toolchain/run-tests.sh).", ""]
    tests = {t for r in requirements.values() for t in r.tests}
    out.append("%d requirements, %d tests verifying them." % (len(requirements), len(tests)))
    for unit in UNITS:
        rows = [r for r in requirements.values() if r.req_id.startswith("REQ-%s-" % unit)]
        if not rows:
            continue
        out += ["", "## %s: %s" % (unit, UNIT_TITLES[unit]), "",
                "| requirement | verified by |", "|---|---|"]
        for r in sorted(rows, key=lambda x: sort_key(x.req_id)):
            cells = "<br>".join("`%s` (%s)" % (t, p.replace(os.sep, "/"))
                                for t, p in sorted(r.tests, key=lambda tp: (tp[1], tp[0])))
            out.append("| %s | %s |" % (r.req_id, cells))
    return "\n".join(out) + "\n"


def main():
    parser = argparse.ArgumentParser(description="Requirements-to-tests traceability check.")
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--matrix", action="store_true", help="print the trace matrix as Markdown")
    group.add_argument("--check-matrix", metavar="FILE",
                       help="fail unless FILE holds the matrix --matrix prints")
    args = parser.parse_args()
    errors = []
    requirements = trace(errors)
    if errors:
        for error in errors:
            print("trace: " + error, file=sys.stderr)
        print("trace: %d problem(s)" % len(errors), file=sys.stderr)
        return 1
    text = matrix(requirements)
    if args.matrix:
        sys.stdout.write(text)
        return 0
    if args.check_matrix:
        try:
            with open(args.check_matrix, encoding="utf-8") as handle:
                committed = handle.read()
        except OSError as error:
            print("trace: %s: cannot read: %s" % (args.check_matrix, error.strerror), file=sys.stderr)
            return 1
        if committed != text:
            print("trace: %s is not the current matrix; regenerate it: "
                  "toolchain/trace.py --matrix > %s" % (args.check_matrix, args.check_matrix), file=sys.stderr)
            return 1
    tests = {t for r in requirements.values() for t in r.tests}
    print("trace: %d requirements, each verified; %d tests name them" % (len(requirements), len(tests)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
