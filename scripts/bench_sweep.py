#!/usr/bin/env python3
"""The performance protocol of issue 9 against the other tracer, a ray-count
sweep and a scene-size sweep.

Three parts, one per run (each fits a time limit on the GPU host):

    scripts/bench_sweep.py protocol SCENE[@CAMERA]... --bin DIR --out FILE.md
    scripts/bench_sweep.py rays SCENE[@CAMERA] --bin DIR --out FILE.md [--ray-counts N,...]
    scripts/bench_sweep.py sizes SCENE[@CAMERA]... --bin DIR --out FILE.md
        [--variants NAME,...] [--runs N] [--cap SECONDS] [--device gpu|cpu]
        [--width W --height H] [--commit TEXT]

Each scene is built with as-build for each variant (on every core of the
machine it runs on), inspected with as-inspect (bytes per triangle) and
traced with as-trace on the four workloads of the protocol: primary (closest
hit), AO (16 cosine rays per primary hit within 0.1 of the scene diagonal,
any hit), diffuse (4 cosine rays per primary hit, unbounded, closest hit)
and the same diffuse rays in random order (as-trace --shuffle). Mrays/s is
as-trace's: on the GPU the median of --runs launches timed with device
events, rays already on the device; on the CPU the wall clock of the trace.

- protocol: a table per scene and variant, each cell beside the other
  tracer's figure measured on the H100 (issue 9's tables, held in this
  script), the ratio ours/theirs and whether the goal (1.00x) and the
  moonshot (1.25x) are met; bytes per triangle against its 117. Default
  variants: bvh-sbvh and bvh-sbvh-cwbvh.
- rays: for one scene, the first N rays of each workload (as-trace
  --ray-limit) for N in --ray-counts (default 65,536 to 33,554,432 in powers
  of 4 and 2), where the workload has more than N rays, and the whole
  workload. Default variant: bvh-sbvh.
- sizes: the four workloads over scenes, rows ordered by triangle count.
  Default variant: bvh-sbvh.

CAMERA is an as-trace camera file; without it, scenes/cameras/NAME.cam of
this repository (NAME: the scene's file name without its extensions) when
there is one, else as-trace's default camera. The markdown table and the
same data as JSON (FILE.json beside FILE.md) are rewritten after every
variant, with the date, the device's name (as-trace's), the commit (--commit,
else git's) and the rays of every cell. A variant or scene whose build or
trace fails or exceeds --cap (seconds per tool run) is reported in the table
and the others go on.

Exit codes: 0 done (failed variants are in the table), 1 usage, 2 I/O (a
tool, a scene or a camera file is missing).
"""
import argparse
import datetime
import json
import os
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.dont_write_bytecode = True
sys.path.insert(0, HERE)
from bench_scene import VARIANTS, run, first_line, fmt  # noqa: E402  (the same variants, tool runner, cells)

WORKLOADS = ["primary", "ao", "diffuse", "diffuse random"]
LABELS = {"primary": "primary", "ao": "AO", "diffuse": "diffuse", "diffuse random": "random order"}
# The as-trace runs that give the four workloads: (options, workloads taken from its output).
TRACE_RUNS = [(["-w", "ao"], ["primary", "ao"]),
              (["-w", "diffuse"], ["diffuse"]),
              (["-w", "diffuse", "--shuffle"], ["diffuse random"])]
DEFAULT_RAY_COUNTS = [65536, 262144, 1048576, 4194304, 16777216, 33554432]

# The other tracer on the H100 with the protocol, as measured and given in
# issue 9 ("What the other tracer does on the H100 with this protocol"):
# Mrays/s for primary, AO, diffuse and diffuse in random order, the camera of
# each scene (eye; target; up; vertical field of view) at 1920x1080, and the
# rays of San Miguel's workloads. Not measured by this script.
REFERENCE_SOURCE = "issue 9, the other tracer measured on the H100"
REFERENCE_BYTES_PER_TRIANGLE = 117
REFERENCE_WIDTH, REFERENCE_HEIGHT = 1920, 1080
REFERENCE = {
    "sanmiguel": {"camera": ((27.6255, -2.42353, 1.49616), (26.6582, -2.17012, 1.48803), (0, 0, 1), 57.2),
                  "mrays_per_s": {"primary": 1324, "ao": 951, "diffuse": 653, "diffuse random": 542},
                  "rays": {"primary": 2073600, "ao": 33040240, "diffuse": 8260060, "diffuse random": 8260060}},
    "staircase": {"camera": ((0.0324, 1.5267, 4.8820), (0.0248, 1.5718, 3.8830), (0, 1, 0), 35),
                  "mrays_per_s": {"primary": 3168, "ao": 4054, "diffuse": 1723, "diffuse random": 1206}},
    "bathroom": {"camera": ((0.0072, 0.9124, -0.2276), (-0.7446, 0.9279, -0.8867), (0, 1, 0), 55),
                 "mrays_per_s": {"primary": 2029, "ao": 2648, "diffuse": 1174, "diffuse random": 881}},
    "bmw-m6": {"camera": ((-11, 0.8, 5), (-2, -0.5, 0), (0, 1, 0), 30),
               "mrays_per_s": {"primary": 2444, "ao": 2344, "diffuse": 1572, "diffuse random": 1183}},
    "chopper-titan": {"camera": ((-3, 1.5, -10), (2, 1, 20), (0, 1, 0), 60),
                      "mrays_per_s": {"primary": 3420, "ao": 2457, "diffuse": 1913, "diffuse random": 1473}},
}
# Triangles of the decoded scenes (../shared/scenes/README.md; San Miguel's
# also in issue 9): a scene of the same name with another count is not the
# one the other tracer was measured on.
REFERENCE_TRIANGLES = {"sanmiguel": 9384746, "staircase": 262663, "bathroom": 591924, "bmw-m6": 792582,
                       "chopper-titan": 2542918}
GOAL, MOONSHOT = 1.0, 1.25


def progress(msg):
    sys.stderr.write("bench_sweep: " + msg + "\n")
    sys.stderr.flush()


def scene_name(path):
    """sanmiguel.drc -> sanmiguel; staircase.ply.zst -> staircase."""
    name = os.path.basename(path)
    if name.endswith(".zst"):
        name = name[:-4]
    return os.path.splitext(name)[0]


def read_camera(path):
    """(eye, target, up, fov) of a camera file; up and fov as as-trace defaults them."""
    cam = {"up": (0.0, 1.0, 0.0), "fov": (45.0,)}
    with open(path) as f:
        for line in f:
            words = line.split("#", 1)[0].split()
            if words and words[0] in ("eye", "target", "up", "fov"):
                cam[words[0]] = tuple(float(w) for w in words[1:])
    return cam.get("eye"), cam.get("target"), cam["up"], cam["fov"][0]


def same_camera(path, ref):
    try:
        eye, target, up, fov = read_camera(path)
    except (OSError, ValueError):
        return False
    if eye is None or target is None:
        return False
    mine = list(eye) + list(target) + list(up) + [fov]
    theirs = list(ref[0]) + list(ref[1]) + list(ref[2]) + [ref[3]]
    return len(mine) == len(theirs) and all(abs(a - b) <= 1e-6 * max(1.0, abs(b)) for a, b in zip(mine, theirs))


class Bench:
    """Builds each (scene, variant) once per run and keeps its measurements."""

    def __init__(self, args, work):
        self.args = args
        self.work = work
        self.built = {}      # (scene, variant) -> (asf path or None, row facts or error)
        self.device_name = None

    def tool(self, name):
        return os.path.join(self.args.bin, name)

    def build(self, scene, variant):
        key = (scene, variant)
        if key in self.built:
            return self.built[key]
        asf = os.path.join(self.work, "%d-%s.asf" % (len(self.built), variant))
        rc, _, err, secs = run([self.tool("as-build"), scene, "-o", asf, "-q"] + dict(VARIANTS)[variant],
                               self.args.cap)
        if rc != 0:
            self.built[key] = (None, {"error": "build: exit %d: %s" % (rc, first_line(err))})
            return self.built[key]
        rc, out, err, _ = run([self.tool("as-inspect"), asf, "--format", "json"], self.args.cap)
        if rc != 0:
            self.built[key] = (None, {"error": "inspect: exit %d: %s" % (rc, first_line(err))})
            return self.built[key]
        info = json.loads(out)
        facts = {"triangles": info["triangles"], "bytes": info["bytes"], "megabytes": info["megabytes"],
                 "bytes_per_triangle": info["bytes_per_triangle"],
                 "build_ms": info.get("build", {}).get("build_ms"),
                 "build_threads": info.get("build", {}).get("threads"), "as_build_s": round(secs, 2)}
        self.built[key] = (asf, facts)
        return self.built[key]

    def drop(self, scene):
        """Removes the scene's files once its variants are measured (San Miguel's are ~1 GB each)."""
        for key in [k for k in self.built if k[0] == scene]:
            asf = self.built.pop(key)[0]
            if asf:
                try:
                    os.remove(asf)
                except OSError:
                    pass

    def trace(self, asf, camera, limit=None, runs=TRACE_RUNS):
        """{workload: {rays, workload_rays, mrays_per_s, trace_ms}} for the runs asked for,
        and an error text or None."""
        cmd = [self.tool("as-trace"), asf, "--device", self.args.device, "--runs", str(self.args.runs),
               "-W", str(self.args.width), "-H", str(self.args.height), "--format", "json"]
        if camera:
            cmd += ["--camera", camera]
        if limit:
            cmd += ["--ray-limit", str(limit)]
        result = {}
        for extra, wanted in runs:
            rc, out, err, _ = run(cmd + extra, self.args.cap)
            if rc != 0:
                return result, "trace %s%s: exit %d: %s" % (" ".join(extra), " --ray-limit %d" % limit if limit else "",
                                                             rc, first_line(err))
            res = json.loads(out)
            self.device_name = self.device_name or res.get("device_name")
            for w in res["workloads"]:
                if w["workload"] in wanted:
                    result[w["workload"]] = {"rays": w["rays"], "workload_rays": w.get("workload_rays", w["rays"]),
                                             "mrays_per_s": w["mrays_per_s"], "trace_ms": w["trace_ms"]}
        return result, None


def measure_scene(bench, scene, camera, variant):
    """One row: the structure's facts and the four workloads, whole."""
    row = {"scene": scene, "name": scene_name(scene), "camera": camera, "variant": variant}
    asf, facts = bench.build(scene, variant)
    row.update(facts)
    if asf:
        row["workloads"], error = bench.trace(asf, camera)
        if error:
            row["error"] = error
    return row


def add_ratios(row):
    """The other tracer's figure and ours/theirs beside each workload of a scene of issue 9."""
    ref = REFERENCE.get(row["name"])
    if not ref:
        return
    for w, v in row.get("workloads", {}).items():
        v["reference_mrays_per_s"] = ref["mrays_per_s"][w]
        ratio = v["mrays_per_s"] / ref["mrays_per_s"][w]
        v["ratio"] = round(ratio, 6)
        v["goal"] = ratio >= GOAL
        v["moonshot"] = ratio >= MOONSHOT
    if "bytes_per_triangle" in row:
        row["reference_bytes_per_triangle"] = REFERENCE_BYTES_PER_TRIANGLE
        row["bytes_goal"] = row["bytes_per_triangle"] <= REFERENCE_BYTES_PER_TRIANGLE


def fmt_mrays(v):
    """Three significant figures below 100 (the CPU's and small runs'), whole numbers above."""
    return "-" if v is None else format(v, ",.0f" if v >= 100 else ".1f" if v >= 10 else ".2f")


def fmt_ratio(ratio):
    return format(ratio, ".2f" if ratio >= 0.1 else ".2g") + "x"


def verdict(ratio):
    return "moonshot" if ratio >= MOONSHOT else "goal" if ratio >= GOAL else "missed"


def header(args, state, title):
    cams = "cameras: " + ", ".join(sorted(set(os.path.basename(c) if c else "default" for c in state["cameras"])))
    return ["# %s" % title, "",
            "Date %s; device %s; commit %s; %dx%d; %s; %s; builds on %d host cores." % (
                state["date"], state["device_name"] or "?", state["commit"] or "?", args.width, args.height, cams,
                "%d timed launches per workload (median, device events)" % args.runs if args.device == "gpu"
                else "CPU wall clock", os.cpu_count() or 0), ""]


def camera_text(row):
    return os.path.basename(row["camera"]) if row["camera"] else "default"


def rays_text(row):
    w = row.get("workloads", {})
    return " / ".join(fmt(w.get(k, {}).get("rays"), ",") for k in ("primary", "ao", "diffuse"))


def protocol_markdown(args, state):
    rows = state["rows"]
    lines = header(args, state, "Issue 9's protocol: this toolkit against the other tracer")
    lines += ["Each cell: our Mrays/s (the ratio to the other tracer's figure: goal at 1.00x, moonshot at 1.25x). "
              "B/tri against its %d bytes per triangle. Rays: primary / AO / diffuse (random order: as diffuse)."
              % REFERENCE_BYTES_PER_TRIANGLE, "",
              "| scene | variant | triangles | B/tri | " + " | ".join(LABELS[w] for w in WORKLOADS) + " | rays |",
              "|---|---|---:|---:|" + "---:|" * len(WORKLOADS) + "---:|"]
    for r in rows:
        ref = REFERENCE.get(r["name"])
        if "workloads" not in r:
            lines.append("| %s | %s | %s |" % (r["name"], r["variant"], r["error"]) + " |" * (3 + len(WORKLOADS)))
            continue
        cells = []
        for w in WORKLOADS:
            m = r["workloads"].get(w, {}).get("mrays_per_s")
            if m is None:
                cells.append("-")
            elif ref:
                ratio = m / ref["mrays_per_s"][w]
                cells.append("%s (%s %s)" % (fmt_mrays(m), fmt_ratio(ratio), verdict(ratio)))
            else:
                cells.append(fmt_mrays(m))
        bpt = r["bytes_per_triangle"]
        lines.append("| %s | %s | %s | %.0f (%s) | %s | %s |" % (
            r["name"], r["variant"], format(r["triangles"], ","), bpt,
            "goal" if bpt <= REFERENCE_BYTES_PER_TRIANGLE else "over %d" % REFERENCE_BYTES_PER_TRIANGLE,
            " | ".join(cells), rays_text(r)))
        if "error" in r:
            lines.append("| | | %s |" % r["error"] + " |" * (3 + len(WORKLOADS)))
    lines += ["", "## The other tracer (%s)" % REFERENCE_SOURCE, "",
              "Not measured here: the figures of issue 9, on the H100 at %dx%d with each scene's protocol camera; "
              "its structure takes %d bytes per triangle on the device."
              % (REFERENCE_WIDTH, REFERENCE_HEIGHT, REFERENCE_BYTES_PER_TRIANGLE), "",
              "| scene | " + " | ".join(LABELS[w] for w in WORKLOADS) + " |",
              "|---|" + "---:|" * len(WORKLOADS)]
    for name in REFERENCE:
        lines.append("| %s | %s |" % (name, " | ".join(format(REFERENCE[name]["mrays_per_s"][w], ",")
                                                      for w in WORKLOADS)))
    lines += ["", "## Goals", ""] + [s for s in protocol_summary(rows)]
    notes = comparability_notes(args, state, rows)
    if notes:
        lines += ["", "## Not comparable as measured", ""] + ["- " + n for n in notes]
    return "\n".join(lines) + "\n"


def protocol_summary(rows):
    """One line per variant and one for the best variant of each cell."""
    out = []
    compared = [r for r in rows if r["name"] in REFERENCE and "workloads" in r]
    best = {}
    for variant in dict.fromkeys(r["variant"] for r in compared):
        n = goal = moon = 0
        mem = [r for r in compared if r["variant"] == variant]
        for r in mem:
            for w in WORKLOADS:
                m = r["workloads"].get(w, {}).get("mrays_per_s")
                if m is None:
                    continue
                ratio = m / REFERENCE[r["name"]]["mrays_per_s"][w]
                n += 1
                goal += ratio >= GOAL
                moon += ratio >= MOONSHOT
                key = (r["name"], w)
                best[key] = max(best.get(key, 0.0), ratio)
        small = sum(r["bytes_per_triangle"] <= REFERENCE_BYTES_PER_TRIANGLE for r in mem)
        out.append("- %s: goal met in %d of %d cells, moonshot in %d; at most %d bytes per triangle in %d of %d "
                   "scenes." % (variant, goal, n, moon, REFERENCE_BYTES_PER_TRIANGLE, small, len(mem)))
    if best:
        ratios = list(best.values())
        out.append("- Best variant of each cell: goal met in %d of %d cells, moonshot in %d; lowest ratio %s "
                   "(%s %s)." % (sum(x >= GOAL for x in ratios), len(ratios), sum(x >= MOONSHOT for x in ratios),
                                 fmt_ratio(min(ratios)), *min(best, key=best.get)))
    return out or ["- No scene of issue 9 was measured."]


def comparability_notes(args, state, rows):
    notes = []
    if (args.width, args.height) != (REFERENCE_WIDTH, REFERENCE_HEIGHT):
        notes.append("image %dx%d, not the protocol's %dx%d." % (args.width, args.height, REFERENCE_WIDTH,
                                                                 REFERENCE_HEIGHT))
    if args.device != "gpu" or "H100" not in (state["device_name"] or ""):
        notes.append("device %s: the other tracer's figures are the H100's." % (state["device_name"] or args.device))
    for name in dict.fromkeys(r["name"] for r in rows):
        r = next(x for x in rows if x["name"] == name)
        if name not in REFERENCE:
            notes.append("%s: not a scene of issue 9 (no figures to compare with)." % name)
            continue
        if not r["camera"] or not same_camera(r["camera"], REFERENCE[name]["camera"]):
            notes.append("%s: camera %s is not the protocol's." % (name, r["camera"] or "(as-trace's default)"))
        if r.get("triangles") is not None and r["triangles"] != REFERENCE_TRIANGLES[name]:
            notes.append("%s: %s triangles, not the %s of the scene measured." % (
                name, format(r["triangles"], ","), format(REFERENCE_TRIANGLES[name], ",")))
        theirs = REFERENCE[name].get("rays")
        if theirs and "workloads" in r:
            differ = ["%s %s against %s" % (LABELS[w], format(r["workloads"][w]["rays"], ","), format(theirs[w], ","))
                      for w in WORKLOADS if w in r["workloads"] and r["workloads"][w]["rays"] != theirs[w]]
            if differ:
                notes.append("%s: rays differ from the other tracer's: %s." % (name, "; ".join(differ)))
    return notes


def rays_markdown(args, state):
    lines = header(args, state, "Ray-count sweep: %s" % ", ".join(sorted({scene_name(r["scene"])
                                                                           for r in state["rows"]})))
    lines += ["Mrays/s of the first N rays of each workload in its own order (as-trace --ray-limit N: primary "
              "rays in 16x32 Morton tiles, AO and diffuse rays grouped by the primary hit they start from; random "
              "order: a random sample of the diffuse rays); \"-\" where the workload has no more than N rays. "
              "The last row of each table is the whole workload.", ""]
    for r in state["rows"]:
        lines += ["## %s, %s" % (r["name"], r["variant"]), ""]
        if r.get("triangles") is not None:
            lines += ["%s triangles, %.0f bytes per triangle." % (format(r["triangles"], ","),
                                                                  r["bytes_per_triangle"]), ""]
        lines += ["| rays | " + " | ".join(LABELS[w] for w in WORKLOADS) + " |", "|---:|" + "---:|" * len(WORKLOADS)]
        for p in r.get("points", []):
            cells = [fmt_mrays(p["workloads"].get(w, {}).get("mrays_per_s")) for w in WORKLOADS]
            lines.append("| %s | %s |" % (format(p["ray_limit"], ","), " | ".join(cells)))
        whole = r.get("workloads")
        if whole:
            lines.append("| all | %s |" % " | ".join(
                "%s (%s)" % (fmt_mrays(whole[w]["mrays_per_s"]), format(whole[w]["rays"], ",")) if w in whole
                else "-" for w in WORKLOADS))
        if "error" in r:
            lines += ["", "Failed: %s" % r["error"]]
        lines.append("")
    return "\n".join(lines)


def sizes_markdown(args, state):
    rows = sorted(state["rows"], key=lambda r: (r.get("triangles") is None, r.get("triangles") or 0))
    lines = header(args, state, "Scene-size sweep: %s" % ", ".join(dict.fromkeys(r["variant"] for r in rows)))
    lines += ["Mrays/s per workload, scenes by triangle count. Rays: primary / AO / diffuse (random order: as "
              "diffuse).", "",
              "| scene | variant | camera | triangles | MB | B/tri | " + " | ".join(LABELS[w] for w in WORKLOADS) +
              " | rays |",
              "|---|---|---|---:|---:|---:|" + "---:|" * len(WORKLOADS) + "---:|"]
    for r in rows:
        if "workloads" not in r:
            lines.append("| %s | %s | %s | %s |" % (r["name"], r["variant"], camera_text(r), r["error"]) +
                         " |" * (4 + len(WORKLOADS)))
            continue
        cells = [fmt_mrays(r["workloads"].get(w, {}).get("mrays_per_s")) for w in WORKLOADS]
        lines.append("| %s | %s | %s | %s | %.1f | %.0f | %s | %s |" % (
            r["name"], r["variant"], camera_text(r), format(r["triangles"], ","), r["megabytes"],
            r["bytes_per_triangle"], " | ".join(cells), rays_text(r)))
        if "error" in r:
            lines.append("| | | | %s |" % r["error"] + " |" * (4 + len(WORKLOADS)))
    return "\n".join(lines) + "\n"


def write(args, state):
    text = {"protocol": protocol_markdown, "rays": rays_markdown, "sizes": sizes_markdown}[args.part](args, state)
    with open(args.out, "w") as f:
        f.write(text)
    doc = {"part": args.part, "date": state["date"], "device": args.device, "device_name": state["device_name"],
           "commit": state["commit"], "width": args.width, "height": args.height, "runs": args.runs,
           "cap_s": args.cap, "variants": state["variants"], "rows": state["rows"]}
    if args.part == "protocol":
        doc["notes"] = comparability_notes(args, state, state["rows"])
        doc["reference"] = {"source": REFERENCE_SOURCE, "bytes_per_triangle": REFERENCE_BYTES_PER_TRIANGLE,
                            "width": REFERENCE_WIDTH, "height": REFERENCE_HEIGHT, "goal": GOAL, "moonshot": MOONSHOT,
                            "scenes": REFERENCE, "triangles": REFERENCE_TRIANGLES}
    if args.part == "rays":
        doc["ray_counts"] = args.ray_counts
    with open(os.path.splitext(args.out)[0] + ".json", "w") as f:
        json.dump(doc, f, indent=1)


def git_commit():
    try:
        p = subprocess.run(["git", "-C", HERE, "describe", "--always", "--dirty"], capture_output=True, text=True,
                           timeout=10)
        return p.stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        return None


class Parser(argparse.ArgumentParser):
    """argparse with the tools' exit code for a usage error (1, not 2)."""

    def error(self, message):
        self.print_usage(sys.stderr)
        self.exit(1, "%s: error: %s\n" % (self.prog, message))


def parse_args():
    common = Parser(add_help=False)
    common.add_argument("--bin", required=True, help="directory of as-build, as-inspect, as-trace")
    common.add_argument("--out", required=True, help="markdown to write (and FILE.json beside it)")
    common.add_argument("--variants", help="comma-separated variant names of scripts/bench_scene.py "
                                           "(default: bvh-sbvh,bvh-sbvh-cwbvh for protocol, bvh-sbvh otherwise)")
    common.add_argument("--runs", type=int, default=10, help="GPU: timed launches per workload (median)")
    common.add_argument("--cap", type=int, default=240, help="seconds a build, inspection or trace may take")
    common.add_argument("--device", default="gpu", choices=["gpu", "cpu"])
    common.add_argument("--width", type=int, default=REFERENCE_WIDTH)
    common.add_argument("--height", type=int, default=REFERENCE_HEIGHT)
    common.add_argument("--commit", help="recorded in the table (default: git describe of this checkout)")
    ap = Parser(description=__doc__.split("\n\n")[0], epilog="Each part's options: bench_sweep.py PART --help. "
                "Exit codes: 0 done (failed variants are in the table), 1 usage, 2 I/O (a tool, a scene or a "
                "camera file is missing).")
    parts = ap.add_subparsers(dest="part", required=True)
    parts.add_parser("protocol", parents=[common], help="issue 9's table against the other tracer").add_argument(
        "scenes", nargs="+", metavar="SCENE[@CAMERA]")
    p = parts.add_parser("rays", parents=[common], help="ray-count sweep on one scene")
    p.add_argument("scenes", nargs=1, metavar="SCENE[@CAMERA]")
    p.add_argument("--ray-counts", default=",".join(str(n) for n in DEFAULT_RAY_COUNTS),
                   help="comma-separated ray counts (default %(default)s)")
    parts.add_parser("sizes", parents=[common], help="scene-size sweep").add_argument(
        "scenes", nargs="+", metavar="SCENE[@CAMERA]")
    return ap, ap.parse_args()


def main():
    ap, args = parse_args()
    if args.runs < 1 or args.cap < 1 or args.width < 1 or args.height < 1:
        ap.error("--runs, --cap, --width and --height need positive values")
    if args.part == "rays":
        try:
            args.ray_counts = sorted({int(n) for n in args.ray_counts.split(",")})
        except ValueError:
            ap.error("--ray-counts needs comma-separated integers, got '%s'" % args.ray_counts)
        if args.ray_counts[0] < 1:
            ap.error("--ray-counts needs positive counts")
    names = (args.variants.split(",") if args.variants else
             ["bvh-sbvh", "bvh-sbvh-cwbvh"] if args.part == "protocol" else ["bvh-sbvh"])
    unknown = [n for n in names if n not in dict(VARIANTS)]
    if unknown:
        progress("unknown variant(s) %s (known: %s)" % (", ".join(unknown), ", ".join(n for n, _ in VARIANTS)))
        return 1
    for tool in ("as-build", "as-inspect", "as-trace"):
        if not os.access(os.path.join(args.bin, tool), os.X_OK):
            progress("%s not found in %s" % (tool, args.bin))
            return 2
    scenes = []
    for spec in args.scenes:
        scene, _, camera = spec.partition("@")
        if not camera:
            own = os.path.join(HERE, "..", "scenes", "cameras", scene_name(scene) + ".cam")
            camera = os.path.normpath(own) if os.path.isfile(own) else None
        for path in (scene, camera):
            if path and not os.path.isfile(path):
                progress("no such file: %s" % path)
                return 2
        scenes.append((scene, camera))

    state = {"date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
             "commit": args.commit or git_commit(), "device_name": None, "variants": names,
             "cameras": [c for _, c in scenes], "rows": []}
    jobs = [(s, c, v) for s, c in scenes for v in names]
    with tempfile.TemporaryDirectory(prefix="bench_sweep.") as work:
        bench = Bench(args, work)
        for i, (scene, camera, variant) in enumerate(jobs):
            t0 = time.monotonic()
            row = measure_scene(bench, scene, camera, variant)
            if args.part == "protocol":
                add_ratios(row)
            if args.part == "rays" and "workloads" in row and "error" not in row:
                sweep_rays(bench, row, args.ray_counts)
            state["rows"].append(row)
            state["device_name"] = bench.device_name
            progress("[%d/%d] %s %s: %s (%.0f s)" % (i + 1, len(jobs), scene_name(scene), variant,
                                                    row.get("error", "ok"), time.monotonic() - t0))
            if i + 1 == len(jobs) or jobs[i + 1][0] != scene:
                bench.drop(scene)
            # Rewritten after every variant: a run cut short keeps what it measured.
            write(args, state)
    return 0


def sweep_rays(bench, row, counts):
    """The first N rays of each workload, for each N below the workload's ray count; an as-trace run only
    where one of its workloads has more than N rays."""
    asf, _ = bench.build(row["scene"], row["variant"])
    total = {w: v["rays"] for w, v in row["workloads"].items()}
    row["points"] = []
    for n in counts:
        runs = [(extra, [w for w in wanted if total.get(w, 0) > n]) for extra, wanted in TRACE_RUNS]
        runs = [(extra, wanted) for extra, wanted in runs if wanted]
        if not runs:
            continue
        t0 = time.monotonic()
        result, error = bench.trace(asf, row["camera"], limit=n, runs=runs)
        row["points"].append({"ray_limit": n, "workloads": result})
        progress("  %s rays: %s (%.0f s)" % (format(n, ","), error or "ok", time.monotonic() - t0))
        if error:
            row["error"] = error
            return


if __name__ == "__main__":
    sys.exit(main())
