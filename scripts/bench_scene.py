#!/usr/bin/env python3
"""Every variant of one scene, every workload: the GPU trace benchmark.

Builds each structure variant of SCENE with as-build (on every core of the
machine it runs on), then traces every workload with as-trace on the GPU
(primary, hard shadows, AO, diffuse, diffuse in random order, Whitted) and
writes one markdown table and the same data as JSON: size, build time, load
time (open to ready, with where validation ran), and Mrays/s per workload,
each the median of --runs launches timed with device events, rays already on
the device. One scene per run, so that a run stays within a time limit; a
variant whose build or trace fails or exceeds --cap is reported and the
others go on.

    scripts/bench_scene.py --bin DIR SCENE --out FILE.md [--camera FILE]
                           [--runs N] [--cap SECONDS] [--device gpu|cpu]
                           [--variants NAME,...] [--width W --height H]
                           [--commit TEXT]

Exit codes: 0 done (failed variants are in the table), 1 usage, 2 I/O (a
tool or the scene is missing).
"""
import argparse
import datetime
import json
import os
import subprocess
import sys
import tempfile
import time

# (name in the table, as-build arguments)
VARIANTS = [
    ("bvh-midcut", ["--structure", "bvh", "--builder", "midcut"]),
    ("bvh-sah", ["--structure", "bvh", "--builder", "sah"]),
    ("bvh-sbvh", ["--structure", "bvh", "--builder", "sbvh"]),
    ("bvh-sah-own", ["--structure", "bvh", "--builder", "sah", "--layout", "bvh2-own-bounds"]),
    ("bvh-sah-cwbvh", ["--structure", "bvh", "--builder", "sah", "--layout", "cwbvh"]),
    ("bvh-sbvh-cwbvh", ["--structure", "bvh", "--builder", "sbvh", "--layout", "cwbvh"]),
    ("kd-midcut", ["--structure", "kd", "--builder", "midcut"]),
    ("kd-sah", ["--structure", "kd", "--builder", "sah"]),
    ("kd-ropes-midcut", ["--structure", "kd", "--builder", "midcut", "--layout", "kd-ropes"]),
    ("kd-ropes-sah", ["--structure", "kd", "--builder", "sah", "--layout", "kd-ropes"]),
    ("bih", ["--structure", "bih"]),
    ("octree", ["--structure", "octree"]),
    ("grid", ["--structure", "grid"]),
]
WORKLOADS = ["primary", "shadow", "ao", "diffuse", "diffuse random", "whitted total"]


def progress(msg):
    sys.stderr.write("bench_scene: " + msg + "\n")
    sys.stderr.flush()


def run(cmd, cap):
    """(exit code, stdout, stderr, seconds); 124 when it ran past `cap`."""
    t0 = time.monotonic()
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=cap)
        return p.returncode, p.stdout, p.stderr, time.monotonic() - t0
    except subprocess.TimeoutExpired:
        return 124, "", "ran past the cap of %d s" % cap, time.monotonic() - t0


def first_line(text):
    return (text.strip().splitlines() or [""])[-1][:160]


def bench_variant(args, name, build_args, work):
    row = {"variant": name}
    asf = os.path.join(work, name + ".asf")
    rc, _, err, _ = run([os.path.join(args.bin, "as-build"), args.scene, "-o", asf, "-q"] + build_args, args.cap)
    if rc != 0:
        row["error"] = "build: exit %d: %s" % (rc, first_line(err))
        return row
    rc, out, err, _ = run([os.path.join(args.bin, "as-inspect"), asf, "--format", "json"], args.cap)
    if rc != 0:
        row["error"] = "inspect: exit %d: %s" % (rc, first_line(err))
        return row
    info = json.loads(out)
    row.update({"megabytes": info["megabytes"], "bytes_per_triangle": info["bytes_per_triangle"],
                "triangles": info["triangles"], "build_ms": info.get("build", {}).get("build_ms"),
                "build_threads": info.get("build", {}).get("threads")})
    trace = [os.path.join(args.bin, "as-trace"), asf, "--device", args.device, "--runs", str(args.runs),
             "-W", str(args.width), "-H", str(args.height), "--format", "json"]
    if args.camera:
        trace += ["--camera", args.camera]
    mrays = {}
    for extra in (["-w", "all"], ["-w", "diffuse", "--shuffle"]):
        rc, out, err, _ = run(trace + extra, args.cap)
        if rc != 0:
            row["error"] = "trace %s: exit %d: %s" % (" ".join(extra), rc, first_line(err))
            break
        res = json.loads(out)
        if extra[1] == "all":
            row.update({"load_ms": res["load_ms"], "validate_ms": res["validate_ms"],
                        "validated_on": res.get("validated_on"), "upload_ms": res["upload_ms"],
                        "upload_gb_per_s": res["upload_gb_per_s"], "device_name": res["device_name"]})
        for w in res["workloads"]:
            key = "diffuse random" if extra[1] == "diffuse" else w["workload"]
            if key in WORKLOADS:
                mrays[key] = {"rays": w["rays"], "mrays_per_s": w["mrays_per_s"], "trace_ms": w["trace_ms"]}
    row["workloads"] = mrays
    try:
        os.remove(asf)
    except OSError:
        pass
    return row


def fmt(v, spec):
    return "-" if v is None else format(v, spec)


def markdown(args, rows, started):
    device = next((r["device_name"] for r in rows if r.get("device_name")), "?")
    lines = ["# %s: every variant, every workload" % os.path.basename(args.scene), "",
             "Date %s; device %s; commit %s; %dx%d%s; %s; builds on %d host cores." % (
                 started, device, args.commit or "?", args.width, args.height,
                 ", camera " + os.path.basename(args.camera) if args.camera else ", default camera",
                 "%d timed launches per workload (median, device events)" % args.runs if args.device == "gpu"
                 else "CPU wall clock", os.cpu_count() or 0),
             "", "Mrays/s per workload; load = open to ready (validation where noted, upload).", "",
             "| variant | MB | B/tri | build ms | load ms | validated | " + " | ".join(WORKLOADS) + " |",
             "|---|---:|---:|---:|---:|---|" + "---:|" * len(WORKLOADS)]
    for r in rows:
        if "error" in r and "workloads" not in r:
            lines.append("| %s | %s |" % (r["variant"], r["error"]) + " |" * (5 + len(WORKLOADS)))
            continue
        cells = [fmt(r["workloads"].get(w, {}).get("mrays_per_s"), ",.0f") for w in WORKLOADS]
        validated = "%s %.1f ms" % (r.get("validated_on"), r["validate_ms"]) if "validate_ms" in r else "-"
        lines.append("| %s | %s | %s | %s | %s | %s | %s |" % (
            r["variant"], fmt(r.get("megabytes"), ".1f"), fmt(r.get("bytes_per_triangle"), ".0f"),
            fmt(r.get("build_ms"), ",.0f"), fmt(r.get("load_ms"), ",.0f"), validated, " | ".join(cells)))
        if "error" in r:
            lines.append("| | %s |" % r["error"] + " |" * (5 + len(WORKLOADS)))
    rays = next((r["workloads"] for r in rows if r.get("workloads")), {})
    if rays:
        lines += ["", "Rays per workload: " + ", ".join("%s %s" % (w, format(rays[w]["rays"], ","))
                                                      for w in WORKLOADS if w in rays) + "."]
    return "\n".join(lines) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene")
    ap.add_argument("--bin", required=True, help="directory of as-build, as-inspect, as-trace")
    ap.add_argument("--out", required=True, help="markdown table to write (and FILE.json beside it)")
    ap.add_argument("--camera", help="camera file for as-trace --camera")
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--cap", type=int, default=240, help="seconds a build or a trace may take")
    ap.add_argument("--device", default="gpu", choices=["gpu", "cpu"])
    ap.add_argument("--variants", help="comma-separated names (default: all)")
    ap.add_argument("--width", type=int, default=1920)
    ap.add_argument("--height", type=int, default=1080)
    ap.add_argument("--commit", help="recorded in the table")
    args = ap.parse_args()
    for tool in ("as-build", "as-inspect", "as-trace"):
        if not os.access(os.path.join(args.bin, tool), os.X_OK):
            progress("%s not found in %s" % (tool, args.bin))
            return 2
    if not os.path.isfile(args.scene) or (args.camera and not os.path.isfile(args.camera)):
        progress("no such file: %s" % (args.scene if not os.path.isfile(args.scene) else args.camera))
        return 2
    chosen = VARIANTS
    if args.variants:
        names = args.variants.split(",")
        unknown = [n for n in names if n not in dict(VARIANTS)]
        if unknown:
            progress("unknown variant(s) %s (known: %s)" % (", ".join(unknown), ", ".join(n for n, _ in VARIANTS)))
            return 1
        chosen = [v for v in VARIANTS if v[0] in names]
    started = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench_scene.") as work:
        for i, (name, build_args) in enumerate(chosen):
            t0 = time.monotonic()
            row = bench_variant(args, name, build_args, work)
            rows.append(row)
            progress("[%d/%d] %s: %s (%.0f s)" % (i + 1, len(chosen), name, row.get("error", "ok"),
                                                  time.monotonic() - t0))
            # Rewritten after every variant: a run cut short keeps what it measured.
            write(args, rows, started)
    return 0


def write(args, rows, started):
    with open(args.out, "w") as f:
        f.write(markdown(args, rows, started))
    with open(os.path.splitext(args.out)[0] + ".json", "w") as f:
        json.dump({"scene": args.scene, "date": started, "commit": args.commit, "width": args.width,
                   "height": args.height, "runs": args.runs, "rows": rows}, f, indent=1)


if __name__ == "__main__":
    sys.exit(main())
