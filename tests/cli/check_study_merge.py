#!/usr/bin/env python3
"""Runs tools/as-study on the CPU on the bundled bunny at a tiny image, in two
parts and in one, and checks that --merge of the parts gives the one run.

    check_study_merge.py TOOL_DIR SOURCE_DIR WORK_DIR

Part one studies BVH (SAH), part two BIH and BVH (SAH), own bounds (the
row name with a comma in it, which --variants must not cut in two); the
single run studies all three. The merged folder must have every output,
each variant's row once, in the table (markdown and CSV) the same cells as
the single run in every column that is not a time (times differ from run to
run, and so does the rank, which follows them), the images of the single
run, and a results.json that names its parts. --merge must refuse parts of
different scenes, cameras or image sizes, a variant measured twice, an
--out that is one of its parts, and a folder without results.json. A scene
is seen from NAME.cam in --cameras when no --camera is given. Prints one line
per check; exits 0 when all pass, 1 otherwise.
"""
import csv
import json
import os
import shutil
import subprocess
import sys

FAILS = []
# The columns that hold times or follow them; every other column is a count,
# a size or a ratio that the same build and rays must give again.
TIMED = {"rank", "build ms", "Whitted ms", "Whitted Mrays/s", "Whitted perf.", "AO ms", "AO Mrays/s", "AO perf.",
         "load ms"}


def check(ok, what):
    print(("ok - " if ok else "FAIL - ") + what)
    if not ok:
        FAILS.append(what)
    return ok


def run(cmd):
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    return p.returncode, p.stdout, p.stderr


def table(folder):
    """{variant: {column: cell}} from table.csv."""
    with open(os.path.join(folder, "table.csv"), newline="") as f:
        rows = list(csv.DictReader(f))
    return {r["variant"]: r for r in rows}, len(rows)


def md_variants(folder):
    names = []
    with open(os.path.join(folder, "table.md")) as f:
        for line in f.read().splitlines()[2:]:
            if line.startswith("| "):
                names.append(line.split(" | ")[1])
    return names


def setup(argv):
    """(TOOL_DIR, SOURCE_DIR, a fresh WORK_DIR, the as-study command, the
    bundled bunny) from the arguments every as-study check takes."""
    tool_dir, src, work = argv[1:4]
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    return (tool_dir, src, work, [sys.executable, os.path.join(src, "tools", "as-study")],
            os.path.join(src, "scenes", "bunny.drc"))


def main():
    tool_dir, src, work, study, bunny = setup(sys.argv)
    no_cameras = os.path.join(work, "no-cameras")

    def small(width=64, cameras=no_cameras):
        return ["--bin", tool_dir, "--device", "cpu", "--width", str(width), "--height", "48", "--verify", "500",
                "--cameras", cameras]
    both = ["BVH (SAH)", "BIH", "BVH (SAH), own bounds"]

    parts = {"one": "bvh-sah-bvh2-child-bounds", "two": "BIH,BVH (SAH), own bounds",
             "all": "BVH (SAH),BIH,BVH (SAH), own bounds"}
    for name, variants in parts.items():
        code, _, err = run(study + [bunny, "--out", os.path.join(work, name), "--variants", variants] + small())
        check(code == 0, "as-study --variants '%s' exits 0%s" % (variants, "" if code == 0 else ": " + err[-400:]))
    one, two, single = (os.path.join(work, n, "bunny") for n in ("one", "two", "all"))
    check(sorted(md_variants(two)) == ["BIH", "BVH (SAH), own bounds"],
          "a row name with a comma in it is one variant in --variants")
    part = json.load(open(os.path.join(one, "results.json")))
    raw = part["variants"][0].get("raw", {})
    check(all(k in raw for k in ("build", "inspect", "whitted", "ao")) and "workloads" in raw["whitted"],
          "a partial run's results.json keeps as-build's, as-inspect's and as-trace's own output")
    check(all(k in part.get("settings", {}) for k in ("scene_sha256", "camera", "device", "width", "verify")),
          "a partial run's results.json records what --merge compares")

    merged_out = os.path.join(work, "merged")
    # One part given as its scene folder, the other as its --out folder.
    code, _, err = run(study + ["--merge", one, os.path.join(work, "two"), "--out", merged_out])
    check(code == 0, "as-study --merge exits 0" + ("" if code == 0 else ": " + err[-400:]))
    merged = os.path.join(merged_out, "bunny")
    for f in ("table.md", "table.csv", "results.json", "report.md", "mrays.svg", "memory.svg", "error.svg",
              "shaded.png", "ao.png"):
        check(os.path.isfile(os.path.join(merged, f)), "the merge wrote %s" % f)
    check(os.path.isfile(merged_out + "/bunny.tar.gz"), "the merge wrote the archive")
    m, m_count = table(merged)
    s, _ = table(single)
    check(sorted(m) == sorted(both) and m_count == 3, "the merged table has each part's rows, once each")
    check(sorted(md_variants(merged)) == sorted(both), "the merged markdown table has each part's rows")
    for v in both:
        if v in m and v in s:
            differ = [c for c in s[v] if c not in TIMED and s[v][c] != m[v].get(c)]
            check(not differ, "%s: the merged row equals the single run's in the untimed columns%s"
                  % (v, "" if not differ else " (differ: %s)" % ", ".join(differ)))
    for png in ("shaded.png", "ao.png"):
        with open(os.path.join(merged, png), "rb") as a, open(os.path.join(single, png), "rb") as b:
            check(a.read() == b.read(), "the merged %s is the single run's" % png)
    data = json.load(open(os.path.join(merged, "results.json")))
    check([p["variants"] for p in data.get("merged_from", [])] == [["BVH (SAH)"], ["BIH", "BVH (SAH), own bounds"]],
          "the merged results.json names its parts and what each measured")
    check(data.get("images", {}).get("variant") == "BVH (SAH)", "the images are those of the first variant that traced")

    # What --merge must refuse, each with a message naming why.
    wide = os.path.join(work, "wide")
    cam_dir = os.path.join(work, "cams")
    os.makedirs(cam_dir)
    with open(os.path.join(cam_dir, "bunny.cam"), "w") as f:
        f.write("eye 0 0.1 0.3\ntarget 0 0.1 0\nfov 30\n")
    run(study + [bunny, "--out", wide, "--variants", "Octree"] + small(width=32))
    code, _, _ = run(study + [bunny, "--out", os.path.join(work, "cam"), "--variants", "Octree"] +
                     small(cameras=cam_dir))
    cam = json.load(open(os.path.join(work, "cam", "bunny", "results.json")))
    check(code == 0 and cam.get("camera_source") == os.path.join(cam_dir, "bunny.cam") and
          cam["settings"]["camera"].get("eye") == [0.0, 0.1, 0.3],
          "with no --camera, the scene's NAME.cam in --cameras is used")
    other = os.path.join(work, "other.obj")
    with open(other, "w") as f:
        f.write("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    run(study + [other, "--out", os.path.join(work, "tri"), "--variants", "Octree"] + small())
    refused = os.path.join(work, "refused")
    for what, dirs, out, words in (("image sizes", [one, wide], refused, "\n  width:"),
                                   ("cameras", [one, os.path.join(work, "cam")], refused, "\n  camera:"),
                                   ("scenes", [one, os.path.join(work, "tri")], refused, "\n  scene:"),
                                   ("a variant measured twice", [one, single], refused, "both"),
                                   ("an --out that is one of the parts", [one, two], os.path.join(work, "two"),
                                    "one of the runs")):
        code, _, err = run(study + ["--merge"] + dirs + ["--out", out])
        check(code == 1 and words in err, "--merge refuses %s" % what + ("" if code == 1 and words in err else
                                                                         " (exit %d: %s)" % (code, err.strip())))
    # --replace: a variant measured in two parts comes from the later one, and
    # results.json says which row was replaced by which part's.
    for order, winner in (([one, single], single), ([single, one], one)):
        rep_out = os.path.join(work, "replaced-%d" % len(FAILS))
        shutil.rmtree(rep_out, ignore_errors=True)
        code, _, err = run(study + ["--merge"] + order + ["--replace", "--out", rep_out])
        check(code == 0, "--merge --replace of parts that share a variant exits 0" +
              ("" if code == 0 else ": " + err[-400:]))
        if code:
            continue
        got = json.load(open(os.path.join(rep_out, "bunny", "results.json")))
        want = json.load(open(os.path.join(winner, "results.json")))
        row = lambda d: next(v for v in d["variants"] if v["variant"] == "BVH (SAH)")
        check(row(got).get("whitted") == row(want).get("whitted") and row(got).get("ao") == row(want).get("ao"),
              "--replace takes BVH (SAH) from the later part, %s" % os.path.basename(os.path.dirname(winner)))
        check(sorted(v["variant"] for v in got["variants"]) == sorted(both), "--replace keeps one row per variant")
        check(got.get("replaced") == [{"variant": "BVH (SAH)", "from": order[0], "by": order[1]}],
              "results.json names the replaced row and both parts")
        # Merged again with a newer part: the first merge's history stays.
        again = rep_out + "-again"
        shutil.rmtree(again, ignore_errors=True)
        code, _, err = run(study + ["--merge", os.path.join(rep_out, "bunny"), single, "--replace", "--out", again])
        later = json.load(open(os.path.join(again, "bunny", "results.json"))) if code == 0 else {}
        newer = [r for r in later.get("replaced", [])[1:] if r.get("by") == single]
        check(code == 0 and later["replaced"][:1] == got["replaced"] and len(newer) == len(both) and
              len(later["replaced"]) == 1 + len(both) and later["merged_from"][0].get("merged_from") == got["merged_from"],
              "a merge of a merged folder keeps its replaced rows and its merged_from" +
              ("" if code == 0 else ": " + err[-400:]))
    code, _, err = run(study + ["--replace", bunny] + small())
    check(code == 1 and "--replace goes with --merge" in err, "--replace without --merge is a usage error")
    code, _, err = run(study + ["--merge", os.path.join(work, "nothing"), "--out", refused])
    check(code == 2, "--merge of a folder that is not there exits 2")
    code, _, err = run(study + [bunny, "--merge", one, "--out", refused])
    check(code == 1, "scenes and --merge together are a usage error")
    code, _, err = run(study + [bunny, "--variants", "BVH (SAH,BIH"] + small())
    check(code == 1 and "unknown variant" in err, "an unknown variant name is a usage error")
    return 1 if FAILS else 0


if __name__ == "__main__":
    sys.exit(main())
