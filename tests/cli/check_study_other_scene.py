#!/usr/bin/env python3
"""tools/as-study on a scene made here, not one of ../shared/scenes or the
bundled bunny: every variant, on the CPU at a small image.

    check_study_other_scene.py TOOL_DIR SOURCE_DIR WORK_DIR

The scene is written as OBJ: a height field of 7,200 triangles, a closed
icosphere floating above it, a thin slab and a fan of needles, seen from a
camera given as EYE@TARGET@UP@FOV. All thirteen variants must build, trace
both workloads and verify with 0 mismatches; every output the study promises
must be there (tables, plots, images, report, archive), the archive small;
and --check of the written study must agree. Prints one line per check;
exits 0 when all pass, 1 otherwise.
"""
import csv
import json
import math
import os
import sys
import tarfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from check_study_merge import FAILS, check, run, setup  # noqa: E402  (the same checks and tool runner)


def write_scene(path):
    v, f = [], []

    def vert(x, y, z):
        v.append((x, y, z))
        return len(v)

    n = 60  # height field: n x n quads, two triangles each
    idx = [[vert(-3 + 6 * i / n, 0.3 * math.sin(3.1 * i / n) * math.cos(4.7 * j / n), -3 + 6 * j / n)
            for j in range(n + 1)] for i in range(n + 1)]
    for i in range(n):
        for j in range(n):
            a, b, c, d = idx[i][j], idx[i + 1][j], idx[i + 1][j + 1], idx[i][j + 1]
            f += [(a, b, c), (a, c, d)]
    # An icosphere, subdivided twice, closed.
    t = (1 + 5 ** 0.5) / 2
    base = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
            (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2),
             (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11),
             (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    pts = [tuple(c / math.sqrt(sum(x * x for x in p)) for c in p) for p in base]
    for _ in range(2):
        mid, nf = {}, []

        def m(a, b):
            k = (min(a, b), max(a, b))
            if k not in mid:
                p = [(pts[a][i] + pts[b][i]) / 2 for i in range(3)]
                s = math.sqrt(sum(x * x for x in p))
                pts.append(tuple(x / s for x in p))
                mid[k] = len(pts) - 1
            return mid[k]
        for a, b, c in faces:
            ab, bc, ca = m(a, b), m(b, c), m(c, a)
            nf += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = nf
    first = len(v)
    for p in pts:
        vert(0.8 * p[0] + 0.5, 0.8 * p[1] + 1.4, 0.8 * p[2] - 0.5)
    f += [(first + a + 1, first + b + 1, first + c + 1) for a, b, c in faces]
    # A thin slab (1e-4 thick) and a fan of needles around one vertex.
    s = [vert(x, y, z) for x in (-2.5, -1.0) for y in (0.6, 0.6001) for z in (1.0, 2.5)]
    for a, b, c, d in ((0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)):
        f += [(s[a], s[b], s[c]), (s[a], s[c], s[d])]
    centre = vert(2.0, 1.0, 2.0)
    ring = [vert(2.0 + 1.5 * math.cos(k * 2 * math.pi / 64), 1.0, 2.0 + 1.5 * math.sin(k * 2 * math.pi / 64))
            for k in range(64)]
    f += [(centre, ring[k], ring[(k + 1) % 64]) for k in range(64)]
    with open(path, "w") as out:
        out.write("# a scene made by check_study_other_scene.py\n")
        out.writelines("v %.9g %.9g %.9g\n" % p for p in v)
        out.writelines("f %d %d %d\n" % t for t in f)
    return len(f)


def main():
    tool_dir, src, work, study, _ = setup(sys.argv)
    scene = os.path.join(work, "hills.obj")
    triangles = write_scene(scene)
    out = os.path.join(work, "study")
    code, _, err = run(study + [scene, "--bin", tool_dir, "--device", "cpu", "--width", "96", "--height", "54",
                                "--verify", "3000", "--camera", "0,2.5,6@0,0.5,0@0,1,0@50", "--out", out])
    check(code == 0, "as-study on a scene of its own exits 0" + ("" if code == 0 else ": " + err[-600:]))
    folder = os.path.join(out, "hills")
    for name in ("table.md", "table.csv", "results.json", "report.md", "mrays.svg", "memory.svg", "error.svg",
                 "shaded.png", "ao.png"):
        check(os.path.isfile(os.path.join(folder, name)), "the study wrote %s" % name)
    data = json.load(open(os.path.join(folder, "results.json")))
    rows = data["variants"]
    check(len(rows) == 13, "all thirteen variants have a row (%d)" % len(rows))
    failed = [(r["variant"], r["error"]) for r in rows if "error" in r]
    check(not failed, "every variant built, traced and verified%s" % ("" if not failed else ": %s" % failed))
    bad = [(r["variant"], r[w]["mismatch_ppm"]) for r in rows if "error" not in r for w in ("whitted", "ao")
           if r[w]["mismatch_ppm"] != 0]
    check(not bad, "0 mismatches in every variant and workload%s" % ("" if not bad else ": %s" % bad))
    check(all(r.get("triangles") == triangles for r in rows if "error" not in r),
          "every variant built all %d triangles" % triangles)
    with open(os.path.join(folder, "table.csv"), newline="") as f:
        table = list(csv.DictReader(f))
    check(sorted(int(r["rank"]) for r in table) == list(range(1, 14)), "the table ranks thirteen rows 1 to 13")
    report = open(os.path.join(folder, "report.md")).read()
    check("our ranking beside the paper's" in report and "bytes/ray" in report,
          "the report sets our ranking beside the paper's, with the estimated bytes per ray")
    archive = os.path.join(out, "hills.tar.gz")
    check(os.path.isfile(archive) and os.path.getsize(archive) < 5 << 20, "one archive of the scene, under 5 MB")
    with tarfile.open(archive) as tar:
        check("hills/table.md" in tar.getnames(), "the archive holds the scene's folder")
    code, _, err = run(study + [scene, "--bin", tool_dir, "--check", folder, "--out", os.path.join(work, "again"),
                                "--tolerance", "inf", "--host-tolerance", "inf"])
    check(code == 0, "--check of the written study agrees" + ("" if code == 0 else ": " + err[-600:]))
    return 1 if FAILS else 0


if __name__ == "__main__":
    sys.exit(main())
