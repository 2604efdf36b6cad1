#!/usr/bin/env python3
"""Runs tools/as-study on the CPU on the bundled bunny at a tiny image with
its two compressed wide BVH rows, CWBVH (SAH) and CWBVH (SBVH), and checks
what the study does for them.

    check_study_cwbvh.py TOOL_DIR SOURCE_DIR WORK_DIR

Each row must be built in the cwbvh layout from its own builder's tree, and
have sensible figures in every column (a positive size, leaves, depth, SAH
cost, steps and tests per ray; at least the 48 bytes of a stored triangle
per triangle; rays verified with 0 mismatches); table.md must say what the
columns mean for them, the plots name them, and the report mark them as
ours, beyond the paper's ten variants and out of the comparison with its
ranking. --merge must put a part with these rows together with a merged
folder made before them (BVH (SAH) and BIH), in the study's order, and keep
a row of a name it does not know rather than drop it; a merged folder of
the H100 study (docs/study/h100/sanmiguel, merged from its parts) must
merge again into the same table. Prints one line per check; exits 0 when
all pass, 1 otherwise.
"""
import csv
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from check_study_merge import FAILS, check, run, setup  # noqa: E402  (the same checks and tool runner)

CWBVH = ["CWBVH (SAH)", "CWBVH (SBVH)"]


def table(folder):
    """[{column: cell}] from table.csv, in its order."""
    with open(os.path.join(folder, "table.csv"), newline="") as f:
        return list(csv.DictReader(f))


def main():
    tool_dir, src, work, study, bunny = setup(sys.argv)
    small = ["--bin", tool_dir, "--device", "cpu", "--width", "64", "--height", "48", "--verify", "500",
             "--cameras", os.path.join(work, "no-cameras")]

    # One row by its name, the other by structure-builder-layout.
    code, _, err = run(study + [bunny, "--out", os.path.join(work, "cw"), "--variants", "CWBVH (SAH),bvh-sbvh-cwbvh"]
                       + small)
    check(code == 0, "as-study --variants 'CWBVH (SAH),bvh-sbvh-cwbvh' exits 0" + ("" if code == 0 else ": " + err[-400:]))
    cw = os.path.join(work, "cw", "bunny")
    rows = {r["variant"]: r for r in table(cw)}
    check(sorted(rows) == CWBVH, "the table has both CWBVH rows (has: %s)" % ", ".join(sorted(rows)))
    data = json.load(open(os.path.join(cw, "results.json")))
    by_name = {r["variant"]: r for r in data["variants"]}
    for v, builder in zip(CWBVH, ("sah", "sbvh")):
        r, j = rows.get(v), by_name.get(v, {})
        if not check(r is not None and "error" not in j, "%s traced%s" % (v, "" if "error" not in j else
                                                                           ": " + j["error"])):
            continue
        ins = j["raw"]["inspect"]
        check(ins["structure"] == "bvh" and ins["layout"] == "cwbvh" and ins["build"]["builder"] == builder,
              "%s: as-inspect sees a bvh in the cwbvh layout from the %s builder (%s, %s, %s)"
              % (v, builder, ins["structure"], ins["layout"], ins["build"]["builder"]))
        check(ins["triangles"] == 69451 and ins["references"] >= ins["triangles"],
              "%s: every triangle of the bunny is in a leaf (%d triangles, %d references)"
              % (v, ins["triangles"], ins["references"]))
        size, leaves, depth = float(r["size MB"]), float(r["leaves (k)"]), int(r["max depth"])
        check(size > 0 and leaves > 0 and depth > 0, "%s: positive size, leaves and depth (%s MB, %sk leaves, "
              "depth %s)" % (v, r["size MB"], r["leaves (k)"], r["max depth"]))
        bpt = float(r["bytes/triangle"])
        check(48 <= bpt < 200, "%s: at least the 48 bytes of a stored triangle per triangle, and not wildly more "
              "(%s)" % (v, r["bytes/triangle"]))
        check(float(r["SAH cost"]) > 0 and r["SAH cost ratio"] == "1.00/1",
              "%s: a positive SAH cost at the ratio 1.00/1 (%s, %s)" % (v, r["SAH cost"], r["SAH cost ratio"]))
        check(j.get("build_ms", 0) > 0, "%s: as-build's build time is recorded (%s ms)" % (v, j.get("build_ms")))
        for w in ("Whitted", "AO"):
            steps, tests = (float(r["%s %s avg (max)" % (w, k)].split()[0]) for k in ("steps", "tests"))
            check(steps > 0 and tests > 0, "%s: %s steps and tests per ray are positive (%s, %s)" % (v, w, steps, tests))
        verified = sum(x.get("verified", 0) for wl in ("whitted", "ao") for x in j["raw"][wl]["workloads"])
        check(r["mismatch ppm (Whitted/AO)"] == "0.0 / 0.0" and verified > 0,
              "%s: %d rays verified, 0 mismatches (%s)" % (v, verified, r["mismatch ppm (Whitted/AO)"]))
    md = open(os.path.join(cw, "table.md")).read()
    check("CWBVH rows: a step is a visit of an 8-wide node" in md, "table.md says what the columns mean for CWBVH")
    svg = open(os.path.join(cw, "mrays.svg")).read()
    check(all(v in svg for v in CWBVH), "the Mrays/s plot names both CWBVH rows")
    report = open(os.path.join(cw, "report.md")).read()
    lines = report.splitlines()
    check(all(any(l.startswith("| ") and ("| %s * |" % v) in l and "| ours |" in l for l in lines) for v in CWBVH),
          "the report marks both CWBVH rows with * and 'ours' among the paper's ranks")
    check(all(("- %s: ours, not in the paper" % v) in report for v in CWBVH),
          "the report says each CWBVH row is ours, not in the paper")
    differ = next((l for l in lines if l.startswith("Where the rankings differ")), "")
    check(differ and "CWBVH" not in differ, "the CWBVH rows are left out of the comparison with the paper's ranking")

    # A merged folder made before the CWBVH rows, merged with a part that has them.
    for part, variants in (("a", "BVH (SAH)"), ("b", "BIH")):
        run(study + [bunny, "--out", os.path.join(work, part), "--variants", variants] + small)
    old = os.path.join(work, "old-merged")
    code, _, err = run(study + ["--merge", os.path.join(work, "a"), os.path.join(work, "b"), "--out", old])
    check(code == 0, "two parts without CWBVH rows merge" + ("" if code == 0 else ": " + err[-400:]))
    new = os.path.join(work, "new-merged")
    code, _, err = run(study + ["--merge", os.path.join(old, "bunny"), cw, "--out", new])
    check(code == 0, "a merged folder without CWBVH rows merges with a part that has them"
          + ("" if code == 0 else ": " + err[-400:]))
    if code == 0:
        merged = json.load(open(os.path.join(new, "bunny", "results.json")))
        order = [r["variant"] for r in merged["variants"]]
        check(order == ["BVH (SAH)", "BIH"] + CWBVH, "the merged rows are in the study's order (%s)" % ", ".join(order))
        check(sorted(r["variant"] for r in table(os.path.join(new, "bunny"))) == sorted(order),
              "the merged table has every row")
        check(merged.get("variants_requested") == order, "the merged folder names every variant asked for")
        m = {r["variant"]: r for r in table(os.path.join(new, "bunny"))}
        check(all(m[v]["SAH cost"] == rows[v]["SAH cost"] and m[v]["size MB"] == rows[v]["size MB"]
                  for v in CWBVH if v in rows and v in m), "the merged CWBVH rows keep the part's figures")

    # A row this as-study does not know (a part from another as-study of the
    # same libas version) is kept, after the known ones.
    future = os.path.join(work, "future", "bunny")
    os.makedirs(future)
    d = json.load(open(os.path.join(cw, "results.json")))
    d["variants"] = [dict(d["variants"][0], variant="BVH (future)")]
    d["variants_requested"] = ["BVH (future)"]
    d["images"] = None
    with open(os.path.join(future, "results.json"), "w") as f:
        json.dump(d, f)
    kept = os.path.join(work, "kept")
    code, _, err = run(study + ["--merge", os.path.join(old, "bunny"), future, "--out", kept])
    order = []
    if code == 0:
        order = [r["variant"] for r in json.load(open(os.path.join(kept, "bunny", "results.json")))["variants"]]
    check(code == 0 and order == ["BVH (SAH)", "BIH", "BVH (future)"] and "not a variant of this as-study" in err,
          "--merge keeps a row it does not know, after the others, and says so (exit %d, %s)"
          % (code, ", ".join(order)))

    # The H100 study's San Miguel, merged in four parts before the CWBVH rows.
    h100 = os.path.join(src, "docs", "study", "h100", "sanmiguel")
    if os.path.isfile(os.path.join(h100, "results.json")):
        again = os.path.join(work, "h100")
        code, _, err = run(study + ["--merge", h100, "--out", again])
        same = code == 0 and open(os.path.join(again, "sanmiguel", "table.csv")).read() == \
            open(os.path.join(h100, "table.csv")).read()
        check(same, "the H100 study's merged San Miguel merges again into the same table.csv"
              + ("" if code == 0 else ": " + err[-400:]))
    return 1 if FAILS else 0


if __name__ == "__main__":
    sys.exit(main())
