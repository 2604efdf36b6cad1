#!/usr/bin/env python3
"""Every kernel of a study against the H100's node-fetch ceiling.

    scripts/ceiling.py STUDY_SCENE_DIR... [--out FILE.md]

Reads each scene's results.json (as-study's, with the tools' raw output) and
prints, for every variant, the primary and AO workloads' Mrays/s, steps per
ray (from the counting kernel) and node visits per second (Mrays/s x steps
per ray), beside the two ceilings the performance issue gives for random,
data-dependent fetches of 64-byte two-child nodes with both slab tests on
the H100: about 66 G visits/s when the nodes fit in the 50 MB L2, about 25
G/s for a 1 GB structure. The ceiling is a 64-byte node's: the fraction is
exact for the BVH2 kernel and a yardstick for the others, whose nodes are
smaller (KD, octree 8 bytes; BIH 12; grid cells 8), larger (CWBVH 80) or
whose steps test more than two boxes (CWBVH up to eight). Coherent rays
(primary) can exceed it through shared cache lines. The AO triangle tests per
ray and per second beside them show the other limit: a kernel far below the
fetch ceiling with hundreds of tests per ray is bound by its leaves.
"""
import argparse
import json
import os
import sys

IN_L2 = 66.0   # G node visits/s, nodes in the 50 MB L2
LARGE = 25.0   # G node visits/s, a 1 GB structure


def workload(row, name):
    """(Mrays/s, steps per ray, triangle tests per ray) of one workload from
    as-trace's own output."""
    for part in ("whitted", "ao"):
        for w in (row.get("raw", {}).get(part) or {}).get("workloads", []):
            if w["workload"] == name and "steps_avg" in w:
                return w["mrays_per_s"], w["steps_avg"], w["tests_avg"]
    return None


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("dirs", nargs="+", metavar="STUDY_SCENE_DIR")
    p.add_argument("--out", metavar="FILE.md")
    args = p.parse_args()
    lines = ["| scene | variant | MB | primary Mrays/s | steps | G visits/s | of 66 G | AO Mrays/s | steps | "
             "G visits/s | of 66 G | of 25 G | tests | G tests/s |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for d in args.dirs:
        path = os.path.join(d, "results.json")
        try:
            with open(path) as f:
                data = json.load(f)
        except (OSError, ValueError) as e:
            sys.stderr.write("ceiling.py: %s: %s\n" % (path, e))
            return 2
        for row in data["variants"]:
            if "error" in row:
                lines.append("| %s | %s | | %s | | | | | | | | | | |" % (data["scene"], row["variant"], row["error"]))
                continue
            cells = []
            for name in ("primary", "ao"):
                got = workload(row, name)
                if got is None:
                    cells += ["–"] * (4 if name == "primary" else 7)
                    continue
                mrays, steps, tests = got
                g = mrays * steps / 1e3
                cells += ["{:,.0f}".format(mrays), "%.1f" % steps, "%.1f" % g, "%.0f%%" % (100 * g / IN_L2)]
                if name == "ao":
                    cells += ["%.0f%%" % (100 * g / LARGE), "%.1f" % tests, "%.1f" % (mrays * tests / 1e3)]
            lines.append("| %s | %s | %.1f | %s |" % (data["scene"], row["variant"], row["size_mb"], " | ".join(cells)))
    text = "\n".join(lines) + "\n"
    if args.out:
        with open(args.out, "w") as f:
            f.write(text)
    sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
