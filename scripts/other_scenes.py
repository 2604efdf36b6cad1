#!/usr/bin/env python3
"""Scenes that are not in ../shared/scenes, traced and verified.

    other_scenes.py OUT [--bin DIR] [--device gpu|cpu] [--boxes N] [--quick]

Writes three meshes nobody tuned this toolkit on, then runs as-study on each
(all thirteen variants, every workload, rays verified against the
double-precision reference) and every workload of as-trace on the SBVH (as-trace -w all) with 1,000,000
rays verified per workload:

- hills.obj: the height field, closed icosphere, thin slab and needle fan of
  the ctest tools_as_study_other_scene;
- city.obj: N axis-aligned boxes of sizes spread over three decades on a
  ground plane, with a tilted, finely tessellated sphere on every 50th box
  (58 triangles per box on average; default N 25,000: 1.45 million
  triangles, the teapot-in-a-stadium mix of tiny and huge triangles);
- sphere1e6.obj: as-stiff's watertight sphere moved to 1e6, seen from
  as-trace's default camera (the stiff suite traces its own rays at it).

OUT/summary.md lists, per scene and variant, the mismatches of every
workload. Exit status 0 when every verified ray agreed, 3 when one did not,
2 when a tool failed.
"""
import argparse
import json
import math
import os
import random
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
SRC = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(SRC, "tests", "cli"))
from check_study_other_scene import write_scene as write_hills  # noqa: E402


def write_city(path, boxes, seed=7):
    rnd = random.Random(seed)
    lines, nv, nf = [], 0, 0

    def quad(a, b, c, d):
        nonlocal nf
        lines.append("f %d %d %d\nf %d %d %d\n" % (a, b, c, a, c, d))
        nf += 2

    def vert(x, y, z):
        nonlocal nv
        lines.append("v %.7g %.7g %.7g\n" % (x, y, z))
        nv += 1
        return nv

    side = 1000.0
    g = [vert(x, 0.0, z) for x, z in ((-side, -side), (side, -side), (side, side), (-side, side))]
    quad(g[0], g[3], g[2], g[1])
    for i in range(boxes):
        w = 10 ** rnd.uniform(-1.5, 1.5)
        h = w * 10 ** rnd.uniform(-0.5, 1.0)
        cx, cz = rnd.uniform(-side, side), rnd.uniform(-side, side)
        x0, x1, z0, z1 = cx - w / 2, cx + w / 2, cz - w / 2, cz + w / 2
        c = [vert(x, y, z) for x in (x0, x1) for y in (0.0, h) for z in (z0, z1)]
        for a, b, cc, d in ((0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)):
            quad(c[a], c[b], c[cc], c[d])
        if i % 50 == 0:
            # A UV sphere of 24 x 48 quads resting on the box, tilted.
            r, tilt = w / 2, rnd.uniform(0, math.pi)
            rows = []
            for a in range(25):
                th = math.pi * a / 24
                row = []
                for b in range(48):
                    ph = 2 * math.pi * b / 48
                    x, y, z = r * math.sin(th) * math.cos(ph), r * math.cos(th), r * math.sin(th) * math.sin(ph)
                    y, z = y * math.cos(tilt) - z * math.sin(tilt), y * math.sin(tilt) + z * math.cos(tilt)
                    row.append(vert(cx + x, h + r + y, cz + z))
                rows.append(row)
            for a in range(24):
                for b in range(48):
                    quad(rows[a][b], rows[a][(b + 1) % 48], rows[a + 1][(b + 1) % 48], rows[a + 1][b])
    with open(path + ".tmp", "w") as f:
        f.write("# city: %d boxes, made by scripts/other_scenes.py with seed %d\n" % (boxes, seed))
        f.writelines(lines)
    os.replace(path + ".tmp", path)
    return nf


def run(cmd, **kw):
    sys.stderr.write("+ %s\n" % " ".join(cmd))
    return subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kw)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("out")
    p.add_argument("--bin", default=os.path.join(SRC, "build", "tools"))
    p.add_argument("--device", default="gpu", choices=("gpu", "cpu"))
    p.add_argument("--boxes", type=int, default=25000)
    p.add_argument("--quick", action="store_true",
                   help="a small image, 2,000 verified rays and four variants (for a check on the CPU)")
    a = p.parse_args()
    os.makedirs(a.out, exist_ok=True)
    scenes = []
    hills = os.path.join(a.out, "hills.obj")
    n = write_hills(hills)
    scenes.append((hills, n, None))
    city = os.path.join(a.out, "city.obj")
    n = write_city(city, a.boxes)
    scenes.append((city, n, "-900,60,-900@0,0,0@0,1,0@50"))
    sph = os.path.join(a.out, "sphere1e6")
    r = run([os.path.join(a.bin, "as-stiff"), "watertight-sphere", "--offset", "1e6", "-o", sph])
    if r.returncode:
        sys.stderr.write(r.stderr)
        return 2
    scenes.append((sph + ".obj", None, None))
    size = ["--width", "160", "--height", "90", "--verify", "2000"] if a.quick else []
    variants = ["--variants", "BVH (SAH),BVH (SBVH),KD Ropes (SAH),Octree"] if a.quick else []
    rows, bad = [], 0
    for mesh, tris, cam in scenes:
        name = os.path.basename(mesh).split(".")[0]
        cmd = [sys.executable, os.path.join(SRC, "tools", "as-study"), mesh, "--bin", a.bin, "--device", a.device,
               "--out", os.path.join(a.out, "study"), "--camera=" + (cam or "default")] + size + variants
        r = run(cmd)
        res = os.path.join(a.out, "study", name, "results.json")
        if r.returncode or not os.path.exists(res):
            sys.stderr.write(r.stderr[-2000:])
            return 2
        for v in json.load(open(res))["variants"]:
            if "error" in v:
                rows.append((name, v["variant"], "failed: " + v["error"], "", ""))
                bad += 1
                continue
            ppm = [v[w]["mismatch_ppm"] for w in ("whitted", "ao")]
            bad += any(x for x in ppm)
            rows.append((name, v["variant"], "%d" % v["triangles"], "%g / %g" % tuple(ppm),
                         "%.1f / %.1f" % (v["whitted"]["mrays"], v["ao"]["mrays"])))
        # The protocol workloads on the SBVH, every one verified.
        asf = os.path.join(a.out, name + "-sbvh.asf")
        if run([os.path.join(a.bin, "as-build"), mesh, "-o", asf, "--builder", "sbvh", "-q"]).returncode:
            return 2
        tr = [os.path.join(a.bin, "as-trace"), asf, "--device", a.device, "-w", "all",
              "--verify=%d" % (2000 if a.quick else 1000000), "--format", "json"] + \
             (["--width", "160", "--height", "90"] if a.quick else [])
        if cam:
            e, t, u, f = cam.split("@")
            tr += ["--eye=" + e, "--target=" + t, "--up=" + u, "--fov=" + f]
        r = run(tr)
        if r.returncode:
            sys.stderr.write(r.stderr[-2000:])
            return 2
        with open(os.path.join(a.out, name + "-protocol.json"), "w") as f:
            f.write(r.stdout)
        for w in json.loads(r.stdout)["workloads"]:
            if "verified" not in w:
                continue  # a total over other rows (the Whitted bounces), verified in those
            m = w["wrong_primitive"] + w["false_misses"] + w["false_hits"]
            bad += bool(m)
            rows.append((name, "SBVH, as-trace -w all: " + w["workload"], "",
                         "%d in %d verified" % (m, w["verified"]), "%.1f" % w["mrays_per_s"]))
    text = ("| scene | variant or workload | triangles | mismatch ppm (Whitted / AO), or mismatches | Mrays/s |\n"
            "|---|---|---:|---|---:|\n" + "".join("| %s |\n" % " | ".join(r) for r in rows) +
            "\n%s\n" % ("every verified ray agreed" if not bad else "%d rows with mismatches or failures" % bad))
    with open(os.path.join(a.out, "summary.md"), "w") as f:
        f.write(text)
    sys.stdout.write(text)
    return 3 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
