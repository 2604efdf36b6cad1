#!/usr/bin/env python3
"""tools/as-study --check, on the CPU on the bundled bunny at a tiny image.

    check_study_check.py TOOL_DIR SOURCE_DIR WORK_DIR

A study of three variants, seen from a camera file, is the committed run.
--check on the same scene runs those variants again with the settings the
run recorded (image size, rays verified, device, camera) and must find every
deterministic figure equal (the structures, steps, tests, mismatches) and
say so in check.md, exit 0. Times on a shared CPU vary by any factor, so
the tolerances are inf here; they are judged, and a tolerance of zero makes
the check fail on them. A committed figure changed by hand (a SAH cost, a step
count) must be found and named, exit 3. --check must refuse another scene,
a variant the committed run did not measure, and a results.json from
before as-study recorded its settings, exit 1. Prints one line per check;
exits 0 when all pass, 1 otherwise.
"""
import json
import os
import shutil
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from check_study_merge import FAILS, check, run, setup  # noqa: E402  (the same checks and tool runner)


def main():
    tool_dir, src, work, study, bunny = setup(sys.argv)
    cams = os.path.join(work, "cams")
    os.makedirs(cams)
    with open(os.path.join(cams, "bunny.cam"), "w") as f:
        f.write("eye 0.02 0.12 0.3\ntarget -0.01 0.1 0\nfov 40\n")
    variants = "BVH (SAH),KD Ropes (SAH),BVH (SAH), own bounds"
    code, _, err = run(study + [bunny, "--bin", tool_dir, "--device", "cpu", "--width", "80", "--height", "44",
                                "--verify", "800", "--cameras", cams, "--variants", variants,
                                "--out", os.path.join(work, "committed")])
    check(code == 0, "the committed study runs" + ("" if code == 0 else ": " + err[-400:]))
    committed = os.path.join(work, "committed", "bunny")

    # --check gets nothing but the folder: size, rays, camera come from it.
    # Times of milliseconds on a shared CPU can move by any factor: inf
    # leaves them out of the verdict (the zero-tolerance run below shows
    # they are judged when asked).
    wide = ["--tolerance", "inf", "--host-tolerance", "inf"]
    code, _, err = run(study + [bunny, "--bin", tool_dir, "--check", committed, "--out", os.path.join(work, "fresh")]
                       + wide)
    check(code == 0, "--check of an unchanged study exits 0" + ("" if code == 0 else ": " + err[-600:]))
    fresh = os.path.join(work, "fresh", "bunny")
    data = json.load(open(os.path.join(fresh, "results.json")))
    s = data["settings"]
    check((s["width"], s["height"], s["verify"], s["device"]) == (80, 44, 800, "cpu"),
          "the fresh run takes the committed run's image size, rays verified and device")
    check(s["camera"].get("eye") == [0.02, 0.12, 0.3] and s["camera"].get("fov") == 40.0,
          "the fresh run looks through the committed run's camera")
    check(sorted(r["variant"] for r in data["variants"]) == sorted(["BVH (SAH)", "KD Ropes (SAH)",
                                                                     "BVH (SAH), own bounds"]),
          "the fresh run measures the committed run's variants, and only those")
    text = open(os.path.join(fresh, "check.md")).read()
    lines = [l for l in text.splitlines() if l.startswith("| BVH (SAH) |") or l.startswith("| KD Ropes (SAH) |")]
    check("Result: every figure agrees." in text and any("| SAH cost |" in l and l.endswith("| same |") for l in lines)
          and any("| AO steps avg |" in l and l.endswith("| same |") for l in lines)
          and any("| Whitted ms |" in l and l.endswith("| within |") for l in lines),
          "check.md lists each figure with its verdict: exact ones the same, times within the tolerance")

    # Times are judged: with no room at all, a time that moved by a hair differs.
    code, _, err = run(study + [bunny, "--bin", tool_dir, "--check", committed, "--out", os.path.join(work, "tight"),
                                "--variants", "BVH (SAH)", "--tolerance", "0", "--host-tolerance", "0"])
    check(code == 3 and "ms: committed" in err, "with a tolerance of zero the moved times differ, exit 3")

    # A table that does not hold: a figure changed in the committed record.
    tampered = os.path.join(work, "tampered", "bunny")
    shutil.copytree(committed, tampered)
    rec = json.load(open(os.path.join(tampered, "results.json")))
    for r in rec["variants"]:
        if r["variant"] == "KD Ropes (SAH)":
            r["sah_cost"] *= 1.01
        if r["variant"] == "BVH (SAH)":
            r["ao"]["steps_avg"] += 0.5
    json.dump(rec, open(os.path.join(tampered, "results.json"), "w"))
    code, _, err = run(study + [bunny, "--bin", tool_dir, "--check", tampered, "--out", os.path.join(work, "t2")]
                       + wide)
    text = open(os.path.join(work, "t2", "bunny", "check.md")).read() if code == 3 else ""
    check(code == 3 and "KD Ropes (SAH), SAH cost" in err and "BVH (SAH), AO steps avg" in err
          and "2 figure(s) differ" in text,
          "a changed SAH cost and step count are found and named, exit 3")

    # Refusals.
    other = os.path.join(work, "other.obj")
    with open(other, "w") as f:
        f.write("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    code, _, err = run(study + [other, "--bin", tool_dir, "--check", committed, "--out", os.path.join(work, "x")])
    check(code == 1 and "is not the scene of the committed run" in err, "--check refuses another scene, exit 1")
    code, _, err = run(study + [bunny, "--bin", tool_dir, "--check", committed, "--variants", "BIH",
                                "--out", os.path.join(work, "x")])
    check(code == 1 and "no figures for BIH" in err, "--check refuses a variant the committed run did not measure")
    old = os.path.join(work, "old", "bunny")
    os.makedirs(old)
    rec = json.load(open(os.path.join(committed, "results.json")))
    del rec["settings"]
    json.dump(rec, open(os.path.join(old, "results.json"), "w"))
    code, _, err = run(study + [bunny, "--bin", tool_dir, "--check", old, "--out", os.path.join(work, "x")])
    check(code == 1 and "did not record its settings" in err, "--check refuses a record without its settings")
    return 1 if FAILS else 0


if __name__ == "__main__":
    sys.exit(main())
