#!/usr/bin/env python3
"""ctest driver for scripts/recompute_errors.py (tests/accuracy_tests.cmake).

    check_recompute.py match TOOLS_DIR SOURCE_DIR WORK_DIR STRUCTURE INTERSECTOR
    check_recompute.py damaged TOOLS_DIR SOURCE_DIR WORK_DIR
    check_recompute.py published TOOLS_DIR SOURCE_DIR WORK_DIR

match: builds the bundled bunny, writes three ray files with the script
(camera rays, rays aimed at vertices and edge midpoints, shadow rays from
the camera hits: an any-hit query), traces each on the CPU with every ray
verified by as-trace, and requires the recomputed counts to equal
as-trace's exactly; a sampled recomputation must agree within sampling
error.

damaged: breaks a known number of records of a correct hit file in known
ways and requires the recomputation to count exactly those and to report
disagreement (exit 6); bad files must be refused (exit 3).

published: runs scripts/recompute_published.sh on the bunny (CPU, small
image) against the bunny's published H100 accuracy rows: every check must
agree and the summary must say so; against a copy of those rows in which
the checked row claims 50% false misses it must disagree (exit 6).
"""
import json
import os
import struct
import subprocess
import sys

NO_HIT = 0xFFFFFFFF


def die(msg):
    sys.stderr.write("check_recompute: FAIL: %s\n" % msg)
    sys.exit(1)


def run(cmd, expect=0, stdout=None):
    sys.stderr.write("+ %s\n" % " ".join(cmd))
    p = subprocess.run(cmd, stdout=stdout or subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    sys.stderr.write(p.stderr)
    if expect is not None and p.returncode != expect:
        die("%s exited %d, expected %d\n%s" % (os.path.basename(cmd[0]), p.returncode, expect, p.stdout or ""))
    return p


class Setup:
    def __init__(self, tools, src, work):
        self.tools, self.src, self.work = tools, src, work
        self.script = [sys.executable, os.path.join(src, "scripts", "recompute_errors.py")]
        os.makedirs(work, exist_ok=True)

    def path(self, name):
        return os.path.join(self.work, name)

    def build(self, structure):
        asf = self.path("bunny-%s.asf" % structure)
        run([os.path.join(self.tools, "as-build"), os.path.join(self.src, "scenes", "bunny.drc"), "-o", asf,
             "--structure", structure, "--threads", "1", "-q"])
        return asf

    def rays(self, asf, name, *opts):
        out = self.path(name + ".rays")
        run(self.script + ["rays", asf, "-o", out] + list(opts))
        return out

    def trace(self, asf, rays, intersector, name, any_hit=False):
        hits, js = self.path(name + ".hits"), self.path(name + ".trace.json")
        with open(js, "w") as f:
            run([os.path.join(self.tools, "as-trace"), asf, "--rays", rays, "--device", "cpu", "--threads", "1",
                 "--intersector", intersector, "--hits-out", hits, "--verify=100000000", "--format", "json"]
                + (["--any-hit"] if any_hit else []), stdout=f)
        return hits, js

    def check(self, asf, rays, hits, name, compare=None, any_hit=False, samples=100000000, expect=0):
        out = self.path(name + ".recomputed.json")
        cmd = self.script + ["check", asf, rays, hits, "--samples", str(samples), "--json", out, "-q"]
        if compare:
            cmd += ["--compare", compare]
        if any_hit:
            cmd.append("--any-hit")
        run(cmd, expect=expect)
        with open(out) as f:
            return json.load(f)


def counts(r):
    return (r["false_misses"], r["false_hits"], r["wrong_primitive"])


def match(s, structure, intersector):
    asf = s.build(structure)
    tag = "%s-%s" % (structure, intersector)
    cam = s.rays(asf, "camera-" + tag, "-W", "64", "-H", "48")
    vert = s.rays(asf, "vertices-" + tag, "--toward-vertices", "2000")
    cam_hits, cam_json = s.trace(asf, cam, intersector, "camera-" + tag)
    shadow = s.rays(asf, "shadow-" + tag, "--shadow-from", cam, cam_hits)
    vert_hits, vert_json = s.trace(asf, vert, intersector, "vertices-" + tag)
    sh_hits, sh_json = s.trace(asf, shadow, intersector, "shadow-" + tag, any_hit=True)
    total = 0
    for name, rays, hits, js, any_hit in (("camera", cam, cam_hits, cam_json, False),
                                          ("vertices", vert, vert_hits, vert_json, False),
                                          ("shadow", shadow, sh_hits, sh_json, True)):
        r = s.check(asf, rays, hits, "%s-%s" % (name, tag), compare=js, any_hit=any_hit)
        c = r["compare"]
        if not c["exact"] or not c["agree"]:
            die("%s: recomputed %s, as-trace %s" % (name, counts(r),
                tuple(c["metrics"][m]["other"] for m in ("false_misses", "false_hits", "wrong_primitive"))))
        with open(js) as f:
            other = json.load(f)["workloads"][0]
        if not any_hit and abs(r["max_t_error"] - other["max_t_error"]) > 0.01 * other["max_t_error"] + 1e-12:
            die("%s: max relative t error %.4g recomputed, %.4g from as-trace" % (name, r["max_t_error"],
                                                                              other["max_t_error"]))
        total += sum(counts(r))
        print("%-8s %-9s %-16s %5d rays: false misses %d, false hits %d, wrong primitives %d (as-trace the same)"
              % (name, structure, intersector, r["sampled"], *counts(r)))
    # A sample of the vertex rays against as-trace's full count: the binomial comparison.
    r = s.check(asf, vert, vert_hits, "vertices-sampled-" + tag, compare=vert_json, samples=500)
    if r["compare"]["exact"] or not r["compare"]["agree"]:
        die("sampled vertex rays: %s" % json.dumps(r["compare"]))
    if intersector == "moller-trumbore" and total == 0:
        die("Moller-Trumbore on rays aimed at vertices made no error at all: the rays test nothing")


def damaged(s):
    asf = s.build("bvh")
    rays = s.rays(asf, "camera-damaged", "-W", "64", "-H", "48")
    hits, js = s.trace(asf, rays, "watertight", "camera-damaged")
    clean = s.check(asf, rays, hits, "camera-clean", compare=js)
    if counts(clean) != (0, 0, 0):
        die("the undamaged camera hits already disagree: %s" % (counts(clean),))
    with open(hits, "rb") as f:
        data = bytearray(f.read())
    n = struct.unpack_from("<Q", data, 16)[0]
    rec = lambda i: 32 + 16 * i
    hit = [i for i in range(n) if struct.unpack_from("<I", data, rec(i) + 4)[0] != NO_HIT]
    miss = [i for i in range(n) if struct.unpack_from("<I", data, rec(i) + 4)[0] == NO_HIT]
    if len(hit) < 20 or len(miss) < 5:
        die("too few hits (%d) or misses (%d) to damage" % (len(hit), len(miss)))
    tri_count = clean["triangles"]
    for i in hit[0:3]:  # three false misses
        struct.pack_into("<fI", data, rec(i), float("inf"), NO_HIT)
    for i in miss[0:2]:  # two false hits
        struct.pack_into("<fI", data, rec(i), 1.0, 0)
    for i in hit[5:9]:  # four wrong primitives: another triangle, nowhere near the hit
        t, p = struct.unpack_from("<fI", data, rec(i))
        struct.pack_into("<fI", data, rec(i), 2 * t, (p + tri_count // 2) % tri_count)
    t, p = struct.unpack_from("<fI", data, rec(hit[12]))
    struct.pack_into("<f", data, rec(hit[12]), t * 1.001)  # the right triangle, t off by 1e-3
    bad = s.path("camera-damaged-broken.hits")
    with open(bad, "wb") as f:
        f.write(data)
    r = s.check(asf, rays, bad, "camera-damaged", compare=js, expect=6)
    if counts(r) != (3, 2, 4):
        die("damaged hits: recomputed (false misses, false hits, wrong primitives) %s, expected (3, 2, 4)"
            % (counts(r),))
    if not 0.9e-3 < r["max_t_error"] < 1.1e-3:
        die("damaged hits: max relative t error %.4g, expected 1e-3" % r["max_t_error"])
    if r["compare"]["agree"]:
        die("damaged hits: --compare said they agree")
    print("damaged hit file: recomputed false misses 3, false hits 2, wrong primitives 4, max t error %.3g; "
          "disagreement reported" % r["max_t_error"])
    # Files that are not what they claim are refused, naming the problem.
    short = s.path("truncated.hits")
    with open(short, "wb") as f:
        f.write(data[:-7])
    p = run(s.script + ["check", asf, rays, short, "-q"], expect=3)
    if "truncated.hits" not in p.stderr:
        die("the refusal of a truncated hit file does not name it")
    run(s.script + ["check", asf, hits, rays, "-q"], expect=3)
    print("truncated and swapped files refused")


def published(s):
    script = os.path.join(s.src, "scripts", "recompute_published.sh")
    acc = os.path.join(s.src, "docs", "results", "accuracy-h100", "bunny", "accuracy.json")
    env = dict(os.environ, BIN=s.tools, DEVICE="cpu", W="320", H="240", VERIFY="20000", SAMPLES="400",
               INTERSECTORS="watertight-double")
    variant = "bvh sah bvh2-child-bounds BVH (SAH)"

    def go(out, accuracy, expect):
        cmd = ["sh", script, s.path(out), os.path.join(s.src, "scenes", "bunny.drc"), "-", accuracy, variant]
        sys.stderr.write("+ %s\n" % " ".join(cmd))
        p = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        sys.stderr.write(p.stderr[-4000:])
        if p.returncode != expect:
            die("recompute_published.sh exited %d, expected %d\n%s" % (p.returncode, expect, p.stdout))
        with open(s.path(out + "/summary.md")) as f:
            return f.read()

    text = go("published-ok", acc, 0)
    if "4 checks, 4 agree, 0 disagree." not in text:
        die("the summary does not report 4 agreeing checks:\n" + text)
    with open(acc) as f:
        data = json.load(f)
    hit = 0
    for row in data["rows"]:
        if row["variant"] == "BVH (SAH)" and row["intersector"] == "watertight-double" and row["workload"] == "primary":
            row["false_misses"] = row["verified"] // 2
            hit += 1
    if hit != 1:
        die("the bunny's published rows have %d BVH (SAH) watertight-double primary rows, not 1" % hit)
    wrong = s.path("published-wrong.json")
    with open(wrong, "w") as f:
        json.dump(data, f)
    text = go("published-wrong", wrong, 6)
    if "| NO |" not in text or "1 disagree." not in text:
        die("a published row with 50% false misses was not reported as disagreeing:\n" + text)
    print("published rows: 4 checks agree; a false row is reported")


def main():
    if len(sys.argv) < 5 or sys.argv[1] not in ("match", "damaged", "published"):
        die(__doc__)
    s = Setup(sys.argv[2], sys.argv[3], sys.argv[4])
    if sys.argv[1] == "match":
        if len(sys.argv) != 7:
            die(__doc__)
        match(s, sys.argv[5], sys.argv[6])
    elif sys.argv[1] == "published":
        published(s)
    else:
        damaged(s)
    print("check_recompute: OK")


if __name__ == "__main__":
    main()
