#!/usr/bin/env python3
"""Runs tools/as-accuracy on the CPU on the bundled bunny at a tiny image and
checks what it wrote.

    check_accuracy_outputs.py accuracy|build-sweep TOOL_DIR SOURCE_DIR WORK_DIR

accuracy: two variants, every intersector this as-trace knows, the four
workloads, 5,000 rays verified per workload (more than the 3,072 primary
rays of a 64 x 48 image, so the table must say the primary rays fell
short), then part of it again with --merge. build-sweep: two builders'
series, 500 rays verified, the camera from a file (SCENE@FILE), then one
builder again with --merge. Then, for the mode run: the JSON has every
field, the counts add up (no mismatch count above the rays checked, no more
checked than traced or asked for, ppm and 95% bounds from the counts,
Mrays/s positive), the CSV has the JSON's rows, the markdown table names
every row, and the SVG is well-formed XML. Also the usage errors that must
not start a run. Prints one line per check; exits 0 when all pass, 1
otherwise.
"""
import csv
import json
import math
import os
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET

FAILS = []


def check(ok, what):
    print(("ok - " if ok else "FAIL - ") + what)
    if not ok:
        FAILS.append(what)
    return ok


def close(a, b):
    return a is not None and b is not None and math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-9)


def run(cmd):
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    return p.returncode, p.stdout, p.stderr


def well_formed_svg(path):
    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError) as e:
        return False, str(e)
    if root.tag != "{http://www.w3.org/2000/svg}svg":
        return False, "root element is %s" % root.tag
    marks = [e for e in root.iter() if e.tag.split("}")[1] in ("circle", "polygon")]
    return bool(marks), "%d markers" % len(marks)


def check_accuracy(out, requested, variants, workloads):
    data = json.load(open(os.path.join(out, "accuracy.json")))
    for key in ("tool", "version", "mode", "scene", "device", "device_name", "width", "height", "requested_verify",
                "intersectors", "intersectors_missing", "workloads", "rows", "command", "complete"):
        check(key in data, "accuracy.json has '%s'" % key)
    check(data.get("complete") is True and data.get("variants_done") == data.get("variants_planned"),
          "accuracy.json says it is complete")
    inters = data.get("intersectors", [])
    check("watertight" in inters and "watertight-double" in inters,
          "both watertight intersectors measured (%s)" % ", ".join(inters))
    check(sorted(inters + data.get("intersectors_missing", [])) ==
          sorted(["watertight", "watertight-double", "moller-trumbore"]),
          "measured and missing intersectors make up the default list")
    rows = data.get("rows", [])
    check(not [r for r in rows if "error" in r], "no failed row (%s)" % "; ".join(r["error"] for r in rows if "error" in r))
    want = {(v, i, w) for v in variants for i in inters for w in workloads}
    got = {(r["variant"], r["intersector"], r["workload"]) for r in rows}
    check(got == want, "one row per variant, intersector and workload (%d rows)" % len(rows))
    fields = ("rays", "verified", "requested_verify", "short_of_request", "mrays_per_s", "trace_ms", "wrong_primitive",
              "false_misses", "false_hits", "mismatches", "wrong_primitive_ppm", "false_misses_ppm", "false_hits_ppm",
              "mismatch_ppm", "wrong_primitive_ppm_upper95", "false_misses_ppm_upper95", "false_hits_ppm_upper95",
              "mismatch_ppm_upper95", "max_t_error", "max_t_error_diagonal", "plot_ppm", "query")
    bad = []
    for r in rows:
        name = "%s/%s/%s" % (r.get("variant"), r.get("intersector"), r.get("workload"))
        missing = [f for f in fields if f not in r]
        if missing:
            bad.append("%s lacks %s" % (name, ", ".join(missing)))
            continue
        n = r["verified"]
        counts = {k: r[k] for k in ("wrong_primitive", "false_misses", "false_hits")}
        if r["mismatches"] != sum(counts.values()):
            bad.append("%s: mismatches %d is not the sum of its parts" % (name, r["mismatches"]))
        if any(c < 0 or c > n for c in counts.values()) or r["mismatches"] > n:
            bad.append("%s: a count above the %d rays checked" % (name, n))
        if not 0 < n <= r["rays"] or n != min(r["rays"], requested) or r["requested_verify"] != requested:
            bad.append("%s: %d checked of %d rays, %d asked" % (name, n, r["rays"], requested))
        if r["short_of_request"] != (n < requested):
            bad.append("%s: short_of_request is %s with %d of %d checked" % (name, r["short_of_request"], n, requested))
        if not r["mrays_per_s"] > 0 or not r["trace_ms"] > 0:
            bad.append("%s: Mrays/s %s, trace ms %s" % (name, r["mrays_per_s"], r["trace_ms"]))
        for k, c in list(counts.items()) + [("mismatch", r["mismatches"])]:
            if not close(r[k + "_ppm"], 1e6 * c / n):
                bad.append("%s: %s_ppm %s for %d of %d" % (name, k, r[k + "_ppm"], c, n))
            bound = r[k + "_ppm_upper95"]
            if (c == 0 and not close(bound, 3e6 / n)) or (c and bound is not None):
                bad.append("%s: %s_ppm_upper95 %s for %d of %d" % (name, k, bound, c, n))
        if not close(r["plot_ppm"], 1e6 * r["mismatches"] / n if r["mismatches"] else 3e6 / n):
            bad.append("%s: plotted at %s ppm" % (name, r["plot_ppm"]))
        if r["max_t_error"] < 0 or r["max_t_error_diagonal"] < 0:
            bad.append("%s: negative t error" % name)
    check(not bad, "every row's counts are consistent" + ("" if not bad else ": " + "; ".join(bad[:5])))
    check(any(r["short_of_request"] for r in rows if r["workload"] == "primary") and
          not any(r["short_of_request"] for r in rows if r["workload"] == "ao"),
          "the primary rays fall short of the request, the AO rays do not")

    with open(os.path.join(out, "accuracy.csv"), newline="") as f:
        table = list(csv.DictReader(f))
    check(len(table) == len(rows), "accuracy.csv has the JSON's %d rows" % len(rows))
    check(all(t["mismatches"] == str(r["mismatches"]) and t["verified"] == str(r["verified"])
              for t, r in zip(table, rows)), "accuracy.csv's counts are the JSON's")
    md = open(os.path.join(out, "accuracy.md")).read()
    check(all("## %s (" % w in md for w in workloads), "accuracy.md has a section per workload")
    check(all(v in md for v in variants), "accuracy.md names every variant")
    check("(all; short)" in md and "Fewer rays than the 5,000 asked for" in md,
          "accuracy.md says where fewer rays than asked could be checked")
    zero = [r for r in rows if r["mismatches"] == 0]
    check(not zero or "< %s" % ("{:,.0f}".format(3e6 / zero[0]["verified"])) in md,
          "accuracy.md gives zero counts as their 95% bound")
    ok, why = well_formed_svg(os.path.join(out, "accuracy.svg"))
    check(ok, "accuracy.svg is well-formed SVG with markers (%s)" % why)


def check_sweep(out, builders, verify):
    data = json.load(open(os.path.join(out, "build-sweep.json")))
    for key in ("tool", "version", "mode", "scene", "device", "device_name", "width", "height", "rows", "command", "complete"):
        check(key in data, "build-sweep.json has '%s'" % key)
    check(data.get("complete") is True, "build-sweep.json says it is complete")
    check(str(data.get("camera")).endswith("bunny.cam"), "build-sweep.json names the camera file")
    rows = data.get("rows", [])
    check(not [r for r in rows if "error" in r], "no failed build or trace (%s)"
          % "; ".join(r["error"] for r in rows if "error" in r))
    check(sorted(set(r["sweep"] for r in rows)) == sorted(builders), "rows for exactly the builders asked for")
    settings = [(r["sweep"], r["setting"]) for r in rows]
    check(len(settings) == len(set(settings)), "each setting built once (%d rows)" % len(rows))
    bad = []
    for r in rows:
        name = "%s %s" % (r.get("builder_label"), r.get("setting"))
        for f in ("build_ms", "sah_cost", "primary_mrays", "ao_mrays", "primary_rays", "ao_rays", "megabytes",
                  "leaves", "build_threads"):
            if not isinstance(r.get(f), (int, float)) or not r[f] > 0:
                bad.append("%s: %s is %s" % (name, f, r.get(f)))
        for w in ("primary", "ao"):
            n = r.get(w + "_verified")
            if n != min(verify, r.get(w + "_rays", 0)) or not 0 <= r.get(w + "_mismatches", -1) <= n:
                bad.append("%s: %s verified %s, mismatches %s" % (name, w, n, r.get(w + "_mismatches")))
    check(not bad, "every row has positive build ms, SAH cost and Mrays/s and consistent counts"
          + ("" if not bad else ": " + "; ".join(bad[:5])))
    defaults = [r for r in rows if not r["params"]]
    check(len(defaults) == len(builders), "one default build per builder")
    with open(os.path.join(out, "build-sweep.csv"), newline="") as f:
        table = list(csv.DictReader(f))
    check(len(table) == len(rows) and all(t["setting"] == r["setting"] for t, r in zip(table, rows)),
          "build-sweep.csv has the JSON's %d rows" % len(rows))
    md = open(os.path.join(out, "build-sweep.md")).read()
    check(all("| %s | %s |" % (r["builder_label"], r["setting"]) in md for r in rows),
          "build-sweep.md has a line per setting")
    ok, why = well_formed_svg(os.path.join(out, "build-sweep.svg"))
    check(ok, "build-sweep.svg is well-formed SVG with markers (%s)" % why)


def check_merge(common, scene, path, args, measured_again):
    """A second run into the same folder with --merge measures part of the
    first run again: the rows it does not measure are kept as they were,
    those it does are new, and a run with another image is refused."""
    before = json.load(open(path))["rows"]
    code, _, err = run(common + [scene, "--merge"] + args)
    if not check(code == 0, "a --merge run of part of it exits 0 (%s)" % (err.strip().splitlines() or [""])[-1]):
        return
    after = json.load(open(path))
    key = lambda r: json.dumps(r, sort_keys=True)
    kept = [r for r in before if not measured_again(r)]
    check(len(after["rows"]) == len(before) and after["merged_rows"] == len(kept) and
          all(r in after["rows"] for r in kept),
          "--merge keeps the %d rows it did not measure and replaces the %d it did"
          % (len(kept), len(before) - len(kept)))
    check(sorted(map(key, after["rows"])) != sorted(map(key, before)), "--merge wrote the rows it measured anew")
    wider = [a if a != "64" else "80" for a in common]
    code, _, err = run(wider + [scene, "--merge"] + args)
    check(code == 1 and "--merge" in err, "--merge into a folder measured at another image size is refused (exit %d)"
          % code)


def main():
    if len(sys.argv) != 5 or sys.argv[1] not in ("accuracy", "build-sweep"):
        sys.stderr.write(__doc__)
        return 1
    mode, tool_dir, src, work = sys.argv[1:]
    tool = os.path.join(src, "tools", "as-accuracy")
    scene = os.path.join(src, "scenes", "bunny.drc")
    out = os.path.join(work, mode)
    shutil.rmtree(out, ignore_errors=True)
    # Each mode writes only under WORK_DIR/MODE, so the two may run at once;
    # WORK_DIR itself may not exist yet in a fresh build tree.
    os.makedirs(work, exist_ok=True)
    common = [tool, "--bin", tool_dir, "--device", "cpu", "--width", "64", "--height", "48", "--out", out]

    code, _, err = run(common + [scene, "--intersectors", "watertight,no-such-test"])
    check(code == 1 and "no-such-test" in err, "an intersector as-trace does not know is a usage error (exit %d)" % code)
    code, _, err = run(common + [scene, "--variants", "BVH (SAH),no such variant"])
    check(code == 1 and "no such variant" in err, "an unknown variant is a usage error (exit %d)" % code)
    code, _, err = run(common + [os.path.join(work, "no-such-scene.obj")])
    check(code == 2, "a missing scene is an I/O error (exit %d)" % code)
    check(not os.path.exists(os.path.join(out, "bunny")), "no run started for a usage or I/O error")

    if mode == "accuracy":
        variants = ["BVH (SAH)", "Uniform Grid", "CWBVH (SBVH)"]
        workloads = ["primary", "shadow", "ao", "diffuse"]
        code, _, err = run(common + [scene, "--verify", "5000", "--variants", ",".join(variants)])
        if check(code == 0, "as-accuracy exits 0 (%s)" % (err.strip().splitlines() or [""])[-1]):
            check_accuracy(os.path.join(out, "bunny"), 5000, variants, workloads)
            check_merge(common, scene, os.path.join(out, "bunny", "accuracy.json"),
                        ["--verify", "5000", "--variants", variants[0], "--intersectors", "watertight"],
                        lambda r: r["variant"] == variants[0] and r["intersector"] == "watertight")
            check_accuracy(os.path.join(out, "bunny"), 5000, variants, workloads)
    else:
        builders = ["bvh-sah", "grid"]
        # The sweep also takes the camera from a file, as SCENE@FILE.
        cam = os.path.join(work, "build-sweep-bunny.cam")
        with open(cam, "w") as f:
            f.write("eye -0.0168405 0.110152 0.325428\ntarget -0.0168405 0.110152 -0.00153505\nup 0 1 0\nfov 45\n")
        scene = scene + "@" + cam
        code, _, err = run(common + ["--build-sweep", scene, "--verify", "500", "--builders", ",".join(builders)])
        if check(code == 0, "as-accuracy --build-sweep exits 0 (%s)" % (err.strip().splitlines() or [""])[-1]):
            check_sweep(os.path.join(out, "bunny"), builders, 500)
            check_merge(common, scene, os.path.join(out, "bunny", "build-sweep.json"),
                        ["--build-sweep", "--verify", "500", "--builders", builders[1]],
                        lambda r: r["sweep"] == builders[1])
            check_sweep(os.path.join(out, "bunny"), builders, 500)
    print("%d checks failed" % len(FAILS) if FAILS else "all checks passed")
    return 1 if FAILS else 0


if __name__ == "__main__":
    sys.exit(main())
