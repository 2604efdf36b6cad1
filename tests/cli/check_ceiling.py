#!/usr/bin/env python3
"""scripts/ceiling.py on a study folder whose figures are known.

    check_ceiling.py SOURCE_DIR WORK_DIR

A results.json with one variant at 1,000 Mrays/s and 66 steps per primary ray
is at 66 G node visits/s, 100% of the in-L2 ceiling; its AO rays, 500 Mrays/s
at 100 steps and 4 tests, are at 50 G/s: 76% of 66 G, 200% of 25 G, 2.0 G
tests/s. A failed variant keeps its row with the error; a folder without
results.json is an I/O error (exit 2). Prints one line per check; exits 0
when all pass, 1 otherwise.
"""
import json
import os
import shutil
import subprocess
import sys

FAILS = []


def check(ok, what):
    print(("ok - " if ok else "FAIL - ") + what)
    if not ok:
        FAILS.append(what)


def main():
    src, work = sys.argv[1:3]
    shutil.rmtree(work, ignore_errors=True)
    scene = os.path.join(work, "known")
    os.makedirs(scene)
    w = lambda name, mrays, steps, tests: {"workload": name, "mrays_per_s": mrays, "steps_avg": steps,
                                           "tests_avg": tests}
    data = {"scene": "known", "variants": [
        {"variant": "BVH (SBVH)", "size_mb": 12.5,
         "raw": {"whitted": {"workloads": [w("primary", 1000.0, 66.0, 2.0)]},
                 "ao": {"workloads": [w("primary", 1000.0, 66.0, 2.0), w("ao", 500.0, 100.0, 4.0)]}}},
        {"variant": "Octree", "error": "whitted: timed out after 120 s"}]}
    with open(os.path.join(scene, "results.json"), "w") as f:
        json.dump(data, f)
    tool = [sys.executable, os.path.join(src, "scripts", "ceiling.py")]
    p = subprocess.run(tool + [scene, "--out", os.path.join(work, "c.md")], capture_output=True, text=True)
    check(p.returncode == 0, "ceiling.py exits 0" + ("" if p.returncode == 0 else ": " + p.stderr))
    rows = [l.split(" | ") for l in p.stdout.splitlines() if l.startswith("| known |")]
    check(len(rows) == 2, "one row per variant, the failed one too")
    if rows:
        r = rows[0]
        check(r[3:7] == ["1,000", "66.0", "66.0", "100%"], "primary: 1,000 Mrays/s x 66 steps = 66 G/s, 100%% (%s)"
              % r[3:7])
        check(r[7:13] == ["500", "100.0", "50.0", "76%", "200%", "4.0"] and r[13].startswith("2.0"),
              "AO: 50 G/s, 76%% of 66 G, 200%% of 25 G, 4 tests, 2.0 G tests/s (%s)" % r[7:])
    check(len(rows) == 2 and rows[1][1] == "Octree" and "timed out after 120 s" in " | ".join(rows[1]),
          "the failed variant's row names its error")
    check(open(os.path.join(work, "c.md")).read() == p.stdout, "--out writes what it prints")
    p = subprocess.run(tool + [os.path.join(work, "nothing")], capture_output=True, text=True)
    check(p.returncode == 2 and "results.json" in p.stderr, "a folder without results.json: exit 2, named")
    return 1 if FAILS else 0


if __name__ == "__main__":
    sys.exit(main())
