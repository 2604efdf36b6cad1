#!/usr/bin/env python3
"""Recompute the error figures of a traced hit file independently of libas.

    recompute_errors.py check SCENE.asf RAYS HITS [--any-hit] [--samples N]
                        [--seed S] [--json OUT] [--compare FILE [--select K=V]...]
    recompute_errors.py table CHECK.json...
    recompute_errors.py rays SCENE.asf -o OUT.rays [camera options]
    recompute_errors.py rays SCENE.asf -o OUT.rays --toward-vertices N [camera options]
    recompute_errors.py rays SCENE.asf -o OUT.rays --shadow-from RAYS HITS [--light X,Y,Z]...

`check` reads the three files by formats/SPEC.md alone (no libas code, no
libas build), samples rays with a fixed seed, finds each sampled ray's true
answer by brute force against every triangle in double precision, and
counts false misses, false hits and wrong primitives with the project's tie
rule (docs/accuracy.md). With --compare it says whether figures written by
`as-trace --format json --verify` or by tools/as-accuracy agree with these
within sampling error.

`table` prints the JSON files that `check --compare` wrote as one markdown
table: per file, the recomputed counts beside the compared ones and whether
they agree.

`rays` writes ray files for `as-trace --rays`: pinhole primary rays through
the pixel centres, or shadow rays from the hits of a hit file toward point
lights (an any-hit workload).

Exit codes: 0 success (and agreement), 1 usage error, 2 I/O error,
3 invalid input file, 5 unsupported input, 6 the compared figures disagree.
"""
import argparse
import json
import math
import os
import shutil
import struct
import subprocess
import sys
import time

try:
    import numpy as np
except ImportError:
    # pyenv and venv interpreters do not see Debian's python3-numpy; the
    # system interpreter does.
    if os.path.exists("/usr/bin/python3") and os.path.realpath(sys.executable) != os.path.realpath("/usr/bin/python3") \
            and not os.environ.get("RECOMPUTE_NO_REEXEC"):
        os.environ["RECOMPUTE_NO_REEXEC"] = "1"
        os.execv("/usr/bin/python3", ["/usr/bin/python3", os.path.abspath(__file__)] + sys.argv[1:])
    sys.stderr.write("recompute_errors: error: numpy is missing (Debian: apt-get install python3-numpy, "
                     "which scripts/setup-debian.sh does)\n")
    sys.exit(4)

EXIT_USAGE, EXIT_IO, EXIT_INVALID, EXIT_UNSUPPORTED, EXIT_DISAGREE = 1, 2, 3, 5, 6
NO_HIT = 0xFFFFFFFF
TOOL = "recompute_errors"


class InputError(Exception):
    def __init__(self, code, msg):
        super().__init__(msg)
        self.code = code


def fail(code, msg):
    raise InputError(code, msg)


def tag_value(s):
    return struct.unpack("<I", s.encode("ascii"))[0]


TAG_META, TAG_TRI4, TAG_TRIS = tag_value("META"), tag_value("TRI4"), tag_value("TRIS")
ASF_MAGIC = b"\x89ASF\r\n\x1a\n"
FLAG_REQUIRED, FLAG_ZSTD = 0x1, 0x2


# ---- formats/SPEC.md, section 2: the .asf container --------------------------

def read_file(path):
    try:
        with open(path, "rb") as f:
            return f.read()
    except OSError as e:
        fail(EXIT_IO, "%s: %s" % (path, e.strerror or e))


def zstd_decompress(path, tag, data, raw_size):
    try:
        import zstandard
        try:
            out = zstandard.ZstdDecompressor().decompress(data, max_output_size=raw_size)
        except zstandard.ZstdError as e:
            fail(EXIT_INVALID, "%s: section %s: bad zstd frame: %s" % (path, tag, e))
    except ImportError:
        if not shutil.which("zstd"):
            fail(EXIT_UNSUPPORTED, "%s: section %s is zstd-compressed and neither the Python module zstandard "
                 "(Debian python3-zstandard) nor the zstd command is installed; rebuild the file without "
                 "--compress or install one" % (path, tag))
        p = subprocess.run(["zstd", "-d", "-c", "-q"], input=data, capture_output=True)
        if p.returncode != 0:
            fail(EXIT_INVALID, "%s: section %s: bad zstd frame: %s" % (path, tag, p.stderr.decode().strip()))
        out = p.stdout
    if len(out) != raw_size:
        fail(EXIT_INVALID, "%s: section %s decompresses to %d bytes, raw_size says %d" % (path, tag, len(out), raw_size))
    return out


def read_asf(path):
    """The META fields used here and the triangle sections, as bytes.

    Checksums (XXH3, not in Python's standard library) are not verified:
    a damaged triangle would show up as disagreement, not pass unseen."""
    b = read_file(path)
    if len(b) < 64:
        fail(EXIT_INVALID, "%s: %d bytes, shorter than the 64-byte header" % (path, len(b)))
    if b[:8] != ASF_MAGIC:
        fail(EXIT_INVALID, "%s: not an .asf file (magic at offset 0)" % path)
    major, minor, header_size, count, entry_size, table_off, file_size = struct.unpack_from("<HHIIIQQ", b, 8)
    if major == 0 or major > 1:
        fail(EXIT_UNSUPPORTED, "%s: container version %d.%d, this reader knows 1.x" % (path, major, minor))
    for name, v in (("header_size", header_size), ("section_entry_size", entry_size)):
        if v < 64 or v > 4096 or v % 8:
            fail(EXIT_INVALID, "%s: %s %d out of range" % (path, name, v))
    if any(b[48:64]):
        fail(EXIT_INVALID, "%s: header reserved bytes (offset 48) are not zero" % path)
    if file_size != len(b):
        fail(EXIT_INVALID, "%s: %s: header says %d bytes, the file has %d"
             % (path, "truncated" if file_size > len(b) else "size mismatch", file_size, len(b)))
    if count > 1024 or table_off < header_size or table_off % 8 or table_off + count * entry_size > len(b):
        fail(EXIT_INVALID, "%s: section table (offset %d, %d entries) does not fit the file" % (path, table_off, count))
    sections = {}
    for i in range(count):
        e = table_off + i * entry_size
        tag, flags, off, stored, raw, elems, stride, res0, _csum, res1 = struct.unpack_from("<IIQQQQIIQQ", b, e)
        name = struct.pack("<I", tag).decode("ascii", "replace")
        where = "%s: section %d (%s, entry at offset %d)" % (path, i, name, e)
        if flags & ~(FLAG_REQUIRED | FLAG_ZSTD) or res0 or res1:
            fail(EXIT_INVALID, where + ": unknown flags or reserved fields set")
        if off % 64 or off + stored > len(b) or stride == 0 or elems * stride != raw:
            fail(EXIT_INVALID, where + ": offset, sizes or stride inconsistent")
        if not flags & FLAG_ZSTD and stored != raw:
            fail(EXIT_INVALID, where + ": stored_size %d != raw_size %d without compression" % (stored, raw))
        if tag in sections or tag not in (TAG_META, TAG_TRI4, TAG_TRIS):
            continue  # first of a tag wins; the tree sections are not needed
        data = b[off:off + stored]
        if flags & FLAG_ZSTD:
            data = zstd_decompress(path, name, data, raw)
        sections[tag] = (data, elems, stride)
    if TAG_META not in sections:
        fail(EXIT_INVALID, "%s: no META section" % path)
    meta, _, stride = sections[TAG_META]
    if stride != 256 or len(meta) < 256:
        fail(EXIT_INVALID, "%s: META is not one 256-byte element" % path)
    info = {
        "structure_kind": struct.unpack_from("<I", meta, 36)[0],
        "layout": struct.unpack_from("<I", meta, 40)[0],
        "triangle_count": struct.unpack_from("<I", meta, 68)[0],
        "bounds_lo": struct.unpack_from("<3f", meta, 80),
        "bounds_hi": struct.unpack_from("<3f", meta, 92),
    }
    return info, sections


def triangles_of(path, info, sections):
    """Source triangles as float64 (n, 3, 3) in source order, and which of
    them a ray can meet at all (zero-area ones never)."""
    n = info["triangle_count"]
    tris = np.zeros((n, 3, 3), dtype=np.float64)
    present = np.zeros(n, dtype=bool)
    if TAG_TRIS in sections:
        data, elems, stride = sections[TAG_TRIS]
        if stride != 48 or elems != n:
            fail(EXIT_INVALID, "%s: TRIS holds %d elements of %d bytes, META says %d triangles" % (path, elems, stride, n))
        rec = np.frombuffer(data, dtype="<f4").reshape(n, 12)
        idx = rec[:, 3].view("<u4")
        if n and np.any(idx != np.arange(n, dtype=np.uint32)):
            fail(EXIT_INVALID, "%s: TRIS element %d does not name itself" % (path, int(np.argmax(idx != np.arange(n)))))
        tris[:] = rec[:, [0, 1, 2, 4, 5, 6, 8, 9, 10]].astype(np.float64).reshape(n, 3, 3)
        present[:] = True
    elif TAG_TRI4 in sections:
        data, elems, stride = sections[TAG_TRI4]
        if stride != 48:
            fail(EXIT_INVALID, "%s: TRI4 stride %d, not 48" % (path, stride))
        rec = np.frombuffer(data, dtype="<f4").reshape(elems, 12)
        idx = rec[:, 3].view("<u4").astype(np.int64)
        if elems and idx.max() >= n:
            fail(EXIT_INVALID, "%s: a TRI4 entry names triangle %d of %d" % (path, int(idx.max()), n))
        verts = rec[:, [0, 1, 2, 4, 5, 6, 8, 9, 10]].astype(np.float64).reshape(elems, 3, 3)
        # An SBVH repeats a triangle in several leaves; the copies must be one triangle.
        first = np.full(n, -1, dtype=np.int64)
        order = np.arange(elems)[::-1]
        first[idx[order]] = order
        keep = first[first >= 0]
        tris[idx[keep]] = verts[keep]
        present[idx[keep]] = True
        if elems and np.any(verts != tris[idx]):
            fail(EXIT_INVALID, "%s: TRI4 holds two different triangles under one source index" % path)
    else:
        fail(EXIT_UNSUPPORTED, "%s: neither TRIS nor TRI4 present (layout 0x%04x)" % (path, info["layout"]))
    e1, e2 = tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    present &= np.any(np.cross(e1, e2) != 0, axis=1)
    return tris, present


# ---- formats/SPEC.md, section 4: ray and hit files ---------------------------

def read_records(path, kind):
    magic = {"rays": b"ASRAYS\0\0", "hits": b"ASHITS\0\0"}[kind]
    other = {"rays": b"ASHITS\0\0", "hits": b"ASRAYS\0\0"}[kind]
    size = {"rays": 32, "hits": 16}[kind]
    b = read_file(path)
    if len(b) < 32:
        fail(EXIT_INVALID, "%s: %d bytes, shorter than the 32-byte header" % (path, len(b)))
    if b[:8] != magic:
        fail(EXIT_INVALID, "%s: %s" % (path, "a %s file given for a %s file" % ("hit" if kind == "rays" else "ray", kind[:-1])
                                       if b[:8] == other else "not a %s file (magic)" % kind[:-1]))
    major, minor, record_size, count, reserved = struct.unpack_from("<HHIQQ", b, 8)
    if major == 0 or major > 1:
        fail(EXIT_UNSUPPORTED, "%s: version %d.%d, this reader knows 1.x" % (path, major, minor))
    if record_size != size:
        fail(EXIT_INVALID, "%s: record_size %d, expected %d" % (path, record_size, size))
    if reserved:
        fail(EXIT_INVALID, "%s: reserved header field is not zero" % path)
    if 32 + count * size != len(b):
        fail(EXIT_INVALID, "%s: %d records need %d bytes, the file has %d" % (path, count, 32 + count * size, len(b)))
    return np.frombuffer(b, dtype="<f4", offset=32).reshape(count, size // 4)


def write_rays(path, org, tmin, dirs, tmax):
    n = len(org)
    rec = np.empty((n, 8), dtype="<f4")
    rec[:, 0:3], rec[:, 3], rec[:, 4:7], rec[:, 7] = org, tmin, dirs, tmax
    tmp = path + ".tmp.%d" % os.getpid()
    try:
        with open(tmp, "wb") as f:
            f.write(b"ASRAYS\0\0" + struct.pack("<HHIQQ", 1, 0, 32, n, 0))
            f.write(rec.tobytes())
        os.replace(tmp, path)
    except OSError as e:
        if os.path.exists(tmp):
            os.unlink(tmp)
        fail(EXIT_IO, "%s: %s" % (path, e.strerror or e))


# ---- the reference: brute force in double ------------------------------------

class Scene:
    """Triangles laid out per coordinate, so that one ray is tested against
    a chunk of them with whole-array operations."""

    CHUNK = 1 << 15  # keeps each temporary array within a core's L2 cache

    def __init__(self, tris, present):
        self.n = len(tris)
        self.present = present
        live = np.nonzero(present)[0]
        self.ids = live
        # p[v][k]: coordinate k of vertex v of every triangle that can be hit.
        self.p = [[np.ascontiguousarray(tris[live, v, k]) for k in range(3)] for v in range(3)]
        self.tris = tris

    def closest(self, o, d, tmin, tmax, any_hit=False):
        """The reference answer for one ray: (t, triangle) of the nearest
        intersection in [tmin, tmax], lowest index among equal t; any_hit
        stops at the first chunk with a hit. (inf, NO_HIT) on a miss."""
        if not (tmin <= tmax) or not all(math.isfinite(x) for x in o + d) or d == (0.0, 0.0, 0.0):
            return math.inf, NO_HIT
        # Woop, Benthin & Wald: shear so the ray runs along the z axis; with every
        # vertex transformed once per ray, a shared edge gets the same edge
        # function (negated) from both triangles, so no ray passes between.
        kz = max(range(3), key=lambda k: abs(d[k]))
        kx, ky = (kz + 1) % 3, (kz + 2) % 3
        sx, sy, sz = d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]
        best_t, best_i = math.inf, NO_HIT
        for s in range(0, len(self.ids), self.CHUNK):
            sl = slice(s, s + self.CHUNK)
            ax, ay, az = (self.p[0][k][sl] - o[k] for k in (kx, ky, kz))
            bx, by, bz = (self.p[1][k][sl] - o[k] for k in (kx, ky, kz))
            cx, cy, cz = (self.p[2][k][sl] - o[k] for k in (kx, ky, kz))
            ax -= sx * az; ay -= sy * az
            bx -= sx * bz; by -= sy * bz
            cx -= sx * cz; cy -= sy * cz
            u = cx * by - cy * bx
            v = ax * cy - ay * cx
            w = bx * ay - by * ax
            inside = ((u >= 0) & (v >= 0) & (w >= 0)) | ((u <= 0) & (v <= 0) & (w <= 0))
            cand = np.nonzero(inside)[0]
            if not len(cand):
                continue
            u, v, w = u[cand], v[cand], w[cand]
            det = u + v + w
            t = sz * (u * az[cand] + v * bz[cand] + w * cz[cand])
            with np.errstate(divide="ignore", invalid="ignore"):
                t = t / det
            ok = (det != 0) & (t >= tmin) & (t <= tmax)
            if not ok.any():
                continue
            t, ids = t[ok], self.ids[s + cand[ok]]
            m = t.min()
            i = int(ids[t == m].min())
            if m < best_t or (m == best_t and i < best_i):
                best_t, best_i = float(m), i
            if any_hit:
                break
        return best_t, best_i

    def distance(self, i, o, d, tmin, tmax):
        """Where the ray meets triangle i in [tmin, tmax] by the same test, or inf."""
        if not self.present[i]:
            return math.inf
        kz = max(range(3), key=lambda k: abs(d[k]))
        kx, ky = (kz + 1) % 3, (kz + 2) % 3
        sx, sy, sz = d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]
        a, b, c = ([vv[k] - o[k] for k in range(3)] for vv in self.tris[i].tolist())
        ax, ay = a[kx] - sx * a[kz], a[ky] - sy * a[kz]
        bx, by = b[kx] - sx * b[kz], b[ky] - sy * b[kz]
        cx, cy = c[kx] - sx * c[kz], c[ky] - sy * c[kz]
        u, v, w = cx * by - cy * bx, ax * cy - ay * cx, bx * ay - by * ax
        if (u < 0 or v < 0 or w < 0) and (u > 0 or v > 0 or w > 0):
            return math.inf
        det = u + v + w
        if det == 0:
            return math.inf
        t = sz * (u * a[kz] + v * b[kz] + w * c[kz]) / det
        return t if tmin <= t <= tmax else math.inf


# ---- counting -----------------------------------------------------------------

def ppm(k, n):
    return 1e6 * k / n if n else None


COUNTS = ("false_misses", "false_hits", "wrong_primitive", "wrong_primitive_strict", "reference_hits", "reported_hits")
MAX_EXAMPLES = 20
_job = None  # (scene, diag, rays, hits, any_hit): inherited by forked workers, not pickled


def recompute_block(sample):
    scene, diag, rays, hits, any_hit = _job
    tol = 1e-6 * diag
    c = dict.fromkeys(COUNTS, 0)
    rel, absd, examples = [], [], []
    for i in sample.tolist():
        r = rays[i]
        o, d = (float(r[0]), float(r[1]), float(r[2])), (float(r[4]), float(r[5]), float(r[6]))
        tmin, tmax = float(r[3]), float(r[7])
        got_t = float(hits[i, 0])
        got_p = int(hits[i, 1:2].view("<u4")[0])
        ref_t, ref_p = scene.closest(o, d, tmin, tmax, any_hit)
        got_hit = got_p != NO_HIT
        c["reference_hits"] += ref_p != NO_HIT
        c["reported_hits"] += got_hit
        kind = None
        if ref_p == NO_HIT:
            if got_hit:
                kind = "false_hit"
        elif not got_hit:
            kind = "false_miss"
        elif got_p >= scene.n or not scene.present[got_p]:
            kind = "wrong_primitive"  # no such triangle, or one of zero area
        else:
            own = scene.distance(got_p, o, d, tmin, tmax)
            if not math.isfinite(own):
                c["wrong_primitive_strict"] += 1
            if any_hit:
                # A float test may hit an edge the double test misses: such a
                # hit counts when its reported t lies within the ray.
                if not math.isfinite(own) and not (tmin <= got_t <= tmax):
                    kind = "wrong_primitive"
            else:
                if got_p != ref_p and abs((own if math.isfinite(own) else got_t) - ref_t) > tol:
                    kind = "wrong_primitive"
                else:
                    err = abs(got_t - ref_t)
                    # Near the origin t is all coordinate rounding, not t's.
                    if ref_t > 1e3 * tol:
                        rel.append(err / ref_t)
                    absd.append(err / diag if diag > 0 else 0.0)
        if kind:
            c[{"false_hit": "false_hits", "false_miss": "false_misses"}.get(kind, kind)] += 1
            if len(examples) < MAX_EXAMPLES:
                examples.append({"ray": i, "kind": kind, "reported_prim": None if got_p == NO_HIT else got_p,
                                 "reported_t": got_t if got_hit else None,
                                 "reference_prim": None if ref_p == NO_HIT else ref_p,
                                 "reference_t": ref_t if ref_p != NO_HIT else None})
    return len(sample), c, rel, absd, examples


def recompute(scene, diag, rays, hits, sample, any_hit, jobs, progress):
    global _job
    _job = (scene, diag, rays, hits, any_hit)
    blocks = [sample[k:k + 256] for k in range(0, len(sample), 256)]
    c = dict.fromkeys(COUNTS, 0)
    rel, absd, examples = [], [], []
    t0 = last = time.time()
    done = 0
    pool = None
    if jobs > 1 and len(blocks) > 1:
        import multiprocessing
        pool = multiprocessing.get_context("fork").Pool(min(jobs, len(blocks)))
        results = pool.imap_unordered(recompute_block, blocks)
    else:
        results = map(recompute_block, blocks)
    try:
        for n, bc, brel, babsd, bex in results:
            for k in COUNTS:
                c[k] += bc[k]
            rel += brel
            absd += babsd
            examples += bex
            done += n
            if progress and time.time() - last > 10:
                last = time.time()
                rate = done / (last - t0)
                sys.stderr.write("%s: %d of %d rays (%.0f rays/s, about %.0f s left)\n"
                                 % (TOOL, done, len(sample), rate, (len(sample) - done) / rate))
    finally:
        if pool:
            pool.close()
            pool.join()
    examples.sort(key=lambda e: e["ray"])
    return c, rel, absd, examples[:MAX_EXAMPLES]


# ---- comparing with as-trace or as-accuracy JSON ------------------------------

def log_binom_pmf(k, n, p):
    if p <= 0:
        return 0.0 if k == 0 else -math.inf
    if p >= 1:
        return 0.0 if k == n else -math.inf
    return (math.lgamma(n + 1) - math.lgamma(k + 1) - math.lgamma(n - k + 1)
            + k * math.log(p) + (n - k) * math.log1p(-p))


def two_rate_pvalue(k1, n1, k2, n2):
    """Two-sided p-value that k1/n1 and k2/n2 are one rate: given the k1 + k2
    events, k1 is binomial with p = n1 / (n1 + n2) when they are (the exact
    conditional test for rare events)."""
    k = k1 + k2
    if k == 0:
        return 1.0
    p = n1 / (n1 + n2)
    logs = [log_binom_pmf(i, k, p) for i in range(k + 1)]
    ref = logs[k1]
    return min(1.0, sum(math.exp(x) for x in logs if x <= ref + 1e-9))


def wilson(k, n, z=1.959964):
    if not n:
        return None
    p = k / n
    den = 1 + z * z / n
    mid = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return [round(1e6 * max(0.0, mid - half), 3), round(1e6 * min(1.0, mid + half), 3)]


def load_compare(path, selects):
    try:
        with open(path) as f:
            doc = json.load(f)
    except OSError as e:
        fail(EXIT_IO, "%s: %s" % (path, e.strerror or e))
    except ValueError as e:
        fail(EXIT_INVALID, "%s: not JSON: %s" % (path, e))
    if isinstance(doc, dict) and "rows" in doc:  # tools/as-accuracy
        rows, source = doc["rows"], "as-accuracy"
    elif isinstance(doc, dict) and "workloads" in doc:  # as-trace --format json
        rows, source = [w for w in doc["workloads"] if "verified" in w], "as-trace"
    elif isinstance(doc, dict) and "false_misses" in doc:  # this script
        rows, source = [doc], TOOL
    else:
        fail(EXIT_INVALID, "%s: neither as-trace, as-accuracy nor %s JSON" % (path, TOOL))
    for sel in selects:
        key, _, val = sel.partition("=")
        rows = [r for r in rows if str(r.get(key)) == val]
    if len(rows) != 1:
        what = ["%s/%s/%s" % (r.get("variant", "-"), r.get("intersector", "-"), r.get("workload", "-")) for r in rows[:12]]
        fail(EXIT_USAGE, "%s: %d rows match %s, need one (narrow with --select KEY=VALUE): %s"
             % (path, len(rows), selects or "no --select", ", ".join(what)))
    row = rows[0]
    n = row.get("verified", row.get("sampled"))
    if not n:
        fail(EXIT_INVALID, "%s: the selected row has no verified rays" % path)
    return row, source, n


def compare(mine, row, source, n_other, alpha, ray_count):
    n1 = mine["sampled"]
    # Both sides checked every ray of one file: the counts must be equal.
    exact = n1 == ray_count and n_other == ray_count and mine["all_rays"]
    out = {"source": source, "other_verified": n_other, "alpha": alpha, "exact": exact, "metrics": {}}
    agree = True
    for m in ("false_misses", "false_hits", "wrong_primitive"):
        k1, k2 = mine[m], int(row[m])
        if exact:
            ok, pv = k1 == k2, None
        else:
            pv = two_rate_pvalue(k1, n1, k2, n_other)
            ok = pv >= alpha
        agree &= ok
        out["metrics"][m] = {"recomputed": k1, "other": k2, "recomputed_ppm_95": wilson(k1, n1),
                             "other_ppm_95": wilson(k2, n_other), "p_value": pv, "agree": ok}
    mt = row.get("max_t_error")
    if mt is not None and mine["max_t_error"] is not None:
        out["max_t_error"] = {"recomputed": mine["max_t_error"], "other": mt}
    out["agree"] = agree
    return out


# ---- ray generation -----------------------------------------------------------

def parse_vec(s, name):
    try:
        v = tuple(float(x) for x in s.split(","))
    except ValueError:
        v = ()
    if len(v) != 3 or not all(math.isfinite(x) for x in v):
        fail(EXIT_USAGE, "%s needs X,Y,Z, got '%s'" % (name, s))
    return v


def read_camera(path):
    cam = {}
    try:
        with open(path) as f:
            lines = f.readlines()
    except OSError as e:
        fail(EXIT_IO, "%s: %s" % (path, e.strerror or e))
    for no, line in enumerate(lines, 1):
        w = line.split("#", 1)[0].split()
        if not w:
            continue
        try:
            if w[0] in ("eye", "target", "up") and len(w) == 4:
                cam[w[0]] = tuple(float(x) for x in w[1:])
            elif w[0] == "fov" and len(w) == 2:
                cam["fov"] = float(w[1])
            else:
                raise ValueError
        except ValueError:
            fail(EXIT_INVALID, "%s:%d: expected 'eye|target|up X Y Z' or 'fov DEGREES'" % (path, no))
    return cam


def primary_rays(args, info, eye_only=False):
    lo, hi = np.array(info["bounds_lo"], dtype=np.float64), np.array(info["bounds_hi"], dtype=np.float64)
    centre, radius = 0.5 * (lo + hi), 0.5 * float(np.linalg.norm(hi - lo))
    fov = 45.0
    # as-trace's default view: down -z at the box centre, its bounding sphere filling the height.
    cam = {"eye": tuple(centre + [0, 0, radius / math.sin(math.radians(fov / 2)) if radius > 0 else 1.0]),
           "target": tuple(centre), "up": (0.0, 1.0, 0.0), "fov": fov}
    if args.camera:
        cam.update(read_camera(args.camera))
    for k in ("eye", "target", "up"):
        if getattr(args, k):
            cam[k] = parse_vec(getattr(args, k), "--" + k)
    if args.fov:
        cam["fov"] = args.fov
    eye, target, up = (np.array(cam[k]) for k in ("eye", "target", "up"))
    if eye_only:
        return eye.astype(np.float32).astype(np.float64)
    f = target - eye
    r = np.cross(f, up)
    if not np.linalg.norm(f) or not np.linalg.norm(r):
        fail(EXIT_USAGE, "the camera needs eye != target and an up not along the view")
    f, r = f / np.linalg.norm(f), r / np.linalg.norm(r)
    u = np.cross(r, f)
    w, h = args.width, args.height
    th = math.tan(math.radians(cam["fov"]) / 2)
    px = (2 * (np.arange(w) + 0.5) / w - 1) * th * w / h
    py = (1 - 2 * (np.arange(h) + 0.5) / h) * th
    X, Y = np.meshgrid(px, py)
    d = f + X.reshape(-1, 1) * r + Y.reshape(-1, 1) * u
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    n = w * h
    return np.tile(eye, (n, 1)), np.zeros(n), d, np.full(n, np.inf)


def vertex_rays(args, info, tris, present):
    """Rays from the eye aimed exactly at mesh vertices and edge midpoints,
    where a test that is not watertight lets rays through."""
    eye = primary_rays(args, info, eye_only=True)
    live = np.nonzero(present)[0]
    rng = np.random.default_rng(args.seed)
    pick = rng.choice(len(live), size=min(args.toward_vertices, len(live)), replace=False)
    t = tris[live[pick]].astype(np.float32).astype(np.float64)
    corner = rng.integers(0, 3, size=len(pick))
    a = t[np.arange(len(pick)), corner]
    b = t[np.arange(len(pick)), (corner + 1) % 3]
    # Half at a vertex, half at an edge's midpoint (rounded to float, as a ray file holds it).
    aim = np.where((np.arange(len(pick)) % 2 == 0)[:, None], a, (0.5 * (a + b)).astype(np.float32))
    dirs = aim - eye
    n = len(aim)
    return np.tile(eye, (n, 1)), np.zeros(n), dirs, np.full(n, np.inf)


def shadow_rays(args, info, tris, present):
    prays = read_records(args.shadow_from[0], "rays")
    phits = read_records(args.shadow_from[1], "hits")
    if len(prays) != len(phits):
        fail(EXIT_INVALID, "%s has %d rays, %s %d hits" % (args.shadow_from[0], len(prays), args.shadow_from[1], len(phits)))
    lo, hi = np.array(info["bounds_lo"], dtype=np.float64), np.array(info["bounds_hi"], dtype=np.float64)
    diag = float(np.linalg.norm(hi - lo))
    if args.light:
        lights = [parse_vec(s, "--light") for s in args.light]
    else:
        # Four lights high in the box, over its quarter points.
        lights = [tuple(lo + np.array([fx, 0.9, fz]) * (hi - lo)) for fz in (0.25, 0.75) for fx in (0.25, 0.75)]
    prim = phits[:, 1].view("<u4").astype(np.int64)
    ok = (prim != NO_HIT) & (prim < len(tris))
    ok[ok] &= present[prim[ok]]
    idx = np.nonzero(ok)[0]
    o, d = prays[idx, 0:3].astype(np.float64), prays[idx, 4:7].astype(np.float64)
    tri = tris[prim[idx]]
    p = o + phits[idx, 0:1].astype(np.float64) * d
    nrm = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    # The normal on the side the ray came from, so the offset leaves the surface toward the viewer.
    nrm *= np.where(np.sum(nrm * d, axis=1, keepdims=True) > 0, -1.0, 1.0)
    # At least 4 float spacings of the hit point's largest coordinate, as
    # as-trace does: far from the origin a fraction of the diagonal can be
    # smaller than the rounding of the origin to float.
    off = np.maximum(args.offset * diag, 4 * np.finfo(np.float32).eps * np.max(np.abs(p), axis=1, keepdims=True))
    start = p + off * nrm
    orgs, dirs = [], []
    for L in lights:
        orgs.append(start)
        dirs.append(np.array(L) - start)
    org, dirs = np.concatenate(orgs), np.concatenate(dirs)
    n = len(org)
    # The light is at t = 1; stopping short of it keeps a light that lies on
    # a surface from shadowing itself.
    return org, np.zeros(n), dirs, np.full(n, 1 - 1e-4)


# ---- commands -----------------------------------------------------------------

def cmd_rays(args):
    info, sections = read_asf(args.asf)
    if args.shadow_from:
        tris, present = triangles_of(args.asf, info, sections)
        org, tmin, dirs, tmax = shadow_rays(args, info, tris, present)
        what = "shadow rays (any hit)"
    elif args.toward_vertices:
        tris, present = triangles_of(args.asf, info, sections)
        org, tmin, dirs, tmax = vertex_rays(args, info, tris, present)
        what = "rays toward vertices and edge midpoints"
    else:
        org, tmin, dirs, tmax = primary_rays(args, info)
        what = "primary rays %dx%d" % (args.width, args.height)
    write_rays(args.output, org, tmin, dirs, tmax)
    sys.stderr.write("%s: wrote %d %s to %s\n" % (TOOL, len(org), what, args.output))
    return 0


def cmd_check(args):
    t_start = time.time()
    info, sections = read_asf(args.asf)
    tris, present = triangles_of(args.asf, info, sections)
    rays = read_records(args.rays, "rays")
    hits = read_records(args.hits, "hits")
    if len(rays) != len(hits):
        fail(EXIT_INVALID, "%s has %d rays but %s has %d hits" % (args.rays, len(rays), args.hits, len(hits)))
    lo, hi = np.array(info["bounds_lo"], dtype=np.float64), np.array(info["bounds_hi"], dtype=np.float64)
    diag = float(np.linalg.norm(hi - lo))
    count = len(rays)
    all_rays = args.samples >= count
    if all_rays:
        sample = np.arange(count)
    else:
        sample = np.sort(np.random.default_rng(args.seed).choice(count, size=args.samples, replace=False))
    n = len(sample)
    row = None
    if args.compare:
        row, source, n_other = load_compare(args.compare, args.select)
        # The hit file does not say which query it answers; the JSON does.
        q = row.get("query")
        row_any = {"any": True, "any hit": True, "closest": False, "closest hit": False}.get(q)
        if args.any_hit is None:
            args.any_hit = bool(row_any)
        elif row_any is not None and row_any != args.any_hit:
            fail(EXIT_USAGE, "%s: the selected row answers the %s query, but %s was given"
                 % (args.compare, "any-hit" if row_any else "closest-hit", "--any-hit" if args.any_hit else "--closest-hit"))
    args.any_hit = bool(args.any_hit)
    scene = Scene(tris, present)
    c, rel, absd, examples = recompute(scene, diag, rays, hits, sample, args.any_hit, args.jobs, not args.quiet)
    res = {
        "tool": TOOL, "asf": args.asf, "rays": args.rays, "hits": args.hits,
        "query": "any" if args.any_hit else "closest", "reference": "watertight test in float64, brute force",
        "triangles": int(info["triangle_count"]), "triangles_hittable": int(present.sum()),
        "scene_diagonal": diag, "tie_tolerance": 1e-6 * diag,
        "ray_count": count, "sampled": n, "all_rays": bool(all_rays), "seed": args.seed,
    }
    res.update({k: int(v) for k, v in c.items()})
    mism = c["false_misses"] + c["false_hits"] + c["wrong_primitive"]
    res["mismatches"] = mism
    for k in ("false_misses", "false_hits", "wrong_primitive"):
        res[k + "_ppm"] = ppm(c[k], n)
        res[k + "_ppm_upper95"] = ppm(3, n) if c[k] == 0 and n else None
    res["mismatch_ppm"] = ppm(mism, n)
    res["mismatch_ppm_upper95"] = ppm(3, n) if mism == 0 and n else None
    res["t_error_rays"] = len(rel)
    res["max_t_error"] = max(rel) if rel else (None if args.any_hit else 0.0)
    res["median_t_error"] = float(np.median(rel)) if rel else (None if args.any_hit else 0.0)
    res["max_t_error_diagonal"] = max(absd) if absd else (None if args.any_hit else 0.0)
    res["examples"] = examples
    code = 0
    if row is not None:
        res["compare"] = compare(res, row, source, n_other, args.alpha, count)
        res["compare"]["file"] = args.compare
        if not res["compare"]["agree"]:
            code = EXIT_DISAGREE
    res["elapsed_s"] = round(time.time() - t_start, 2)
    text = json.dumps(res, indent=2)
    if args.json:
        try:
            with open(args.json, "w") as f:
                f.write(text + "\n")
        except OSError as e:
            fail(EXIT_IO, "%s: %s" % (args.json, e.strerror or e))
    if args.json != "-":
        print_summary(res)
    if args.json in (None, "-"):
        print(text)
    return code


def fmt_ppm(res, k):
    if res[k + "_ppm"] is None:
        return "-"
    if res[k] == 0:
        return "0 (< %.3g ppm, 95%%)" % res[k + "_ppm_upper95"]
    return "%d (%.3g ppm)" % (res[k], res[k + "_ppm"])


def print_summary(res):
    out = sys.stderr
    out.write("%s: %d of %d rays (%s hit), %d triangles, reference hit %d, file hit %d\n"
              % (TOOL, res["sampled"], res["ray_count"], res["query"], res["triangles"], res["reference_hits"],
                 res["reported_hits"]))
    out.write("  false misses %s, false hits %s, wrong primitives %s\n"
              % (fmt_ppm(res, "false_misses"), fmt_ppm(res, "false_hits"), fmt_ppm(res, "wrong_primitive")))
    if res["max_t_error"] is not None:
        out.write("  relative t error: max %.3e, median %.3e (%d rays)\n"
                  % (res["max_t_error"], res["median_t_error"], res["t_error_rays"]))
    if "compare" in res:
        cmp_ = res["compare"]
        out.write("  against %s (%s, %d rays): %s\n" % (cmp_["file"], cmp_["source"], cmp_["other_verified"],
                                                       "AGREE" if cmp_["agree"] else "DISAGREE"))
        for m, v in cmp_["metrics"].items():
            out.write("    %-16s %6d here, %6d there%s%s\n"
                      % (m, v["recomputed"], v["other"],
                         "" if v["p_value"] is None else ", p = %.3g" % v["p_value"],
                         "" if v["agree"] else "  <- differs"))
        if "max_t_error" in cmp_:
            out.write("    max t error      %.3e here, %.3e there\n"
                      % (cmp_["max_t_error"]["recomputed"], cmp_["max_t_error"]["other"]))


def cmd_table(args):
    rows = []
    for path in args.files:
        try:
            with open(path) as f:
                res = json.load(f)
        except (OSError, ValueError) as e:
            fail(EXIT_INVALID, "%s: not a check result (%s)" % (path, e))
        if res.get("tool") != TOOL or "compare" not in res:
            fail(EXIT_INVALID, "%s: not written by check --compare" % path)
        rows.append((os.path.basename(path), res))
    out = sys.stdout
    out.write("| check | query | sampled | false misses | false hits | wrong primitives | compared with | "
              "its rays | its counts | p (lowest) | max rel. t error here / there | agree |\n")
    out.write("|---|---|---:|---:|---:|---:|---|---:|---|---:|---|---|\n")
    disagree = 0
    for name, res in rows:
        cmp_ = res["compare"]
        m = cmp_["metrics"]
        ps = [v["p_value"] for v in m.values() if v["p_value"] is not None]
        te = cmp_.get("max_t_error")
        out.write("| %s | %s | %d | %d | %d | %d | %s | %d | %s | %s | %s | %s |\n" % (
            name[:-5] if name.endswith(".json") else name, res["query"], res["sampled"], res["false_misses"],
            res["false_hits"], res["wrong_primitive"], cmp_["source"], cmp_["other_verified"],
            " / ".join(str(m[k]["other"]) for k in ("false_misses", "false_hits", "wrong_primitive")),
            "exact" if cmp_["exact"] else ("%.3g" % min(ps) if ps else "-"),
            "%.2e / %.2e" % (te["recomputed"], te["other"]) if te else "-",
            "yes" if cmp_["agree"] else "NO"))
        disagree += not cmp_["agree"]
    out.write("\n%d checks, %d agree, %d disagree.\n" % (len(rows), len(rows) - disagree, disagree))
    return EXIT_DISAGREE if disagree else 0


def main(argv=None):
    p = argparse.ArgumentParser(prog="recompute_errors.py", description=__doc__.split("\n\n")[1],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    def usage_error(parser):
        # argparse exits 2, which the project's tools keep for I/O errors.
        return lambda msg: (parser.print_usage(sys.stderr), sys.stderr.write("%s: error: %s\n" % (TOOL, msg)),
                            sys.exit(EXIT_USAGE))
    p.error = usage_error(p)
    sub = p.add_subparsers(dest="command", required=True)
    c = sub.add_parser("check", help="recompute the figures of a hit file")
    c.add_argument("asf", help="the .asf the hits were traced through (its triangles are the scene)")
    c.add_argument("rays", help="ray file (formats/SPEC.md 4)")
    c.add_argument("hits", help="hit file written by as-trace --rays RAYS --hits-out HITS")
    q = c.add_mutually_exclusive_group()
    q.add_argument("--any-hit", dest="any_hit", action="store_const", const=True, default=None,
                   help="the hits answer an any-hit query (as-trace --any-hit); default: the query of the "
                        "--compare row, else closest hit")
    q.add_argument("--closest-hit", dest="any_hit", action="store_const", const=False,
                   help="the hits answer a closest-hit query")
    c.add_argument("--samples", type=int, default=10000, help="rays to check (default 10000; all when larger)")
    c.add_argument("--seed", type=int, default=1, help="sampling seed (default 1)")
    c.add_argument("--json", metavar="FILE", help="write the figures as JSON to FILE ('-': stdout only)")
    c.add_argument("--compare", metavar="FILE", help="as-trace --format json --verify or as-accuracy JSON")
    c.add_argument("--select", action="append", default=[], metavar="KEY=VALUE",
                   help="the row of --compare to use, e.g. workload=primary, intersector=watertight")
    c.add_argument("--alpha", type=float, default=0.01,
                   help="disagree when the two-sided p-value of equal rates is below this (default 0.01)")
    c.add_argument("-j", "--jobs", type=int, default=os.cpu_count() or 1,
                   help="worker processes (default: one per core)")
    c.add_argument("-q", "--quiet", action="store_true", help="no progress")
    t = sub.add_parser("table", help="one markdown table of check --compare results")
    t.add_argument("files", nargs="+", metavar="CHECK.json")
    r = sub.add_parser("rays", help="write a ray file for as-trace --rays")
    r.add_argument("asf", help="the .asf whose scene box places the default camera and lights")
    r.add_argument("-o", "--output", required=True)
    r.add_argument("--camera", help="camera file: eye, target, up, fov lines (as-trace --camera)")
    r.add_argument("--eye")
    r.add_argument("--target")
    r.add_argument("--up")
    r.add_argument("--fov", type=float)
    r.add_argument("-W", "--width", type=int, default=320)
    r.add_argument("-H", "--height", type=int, default=240)
    r.add_argument("--shadow-from", nargs=2, metavar=("RAYS", "HITS"),
                   help="shadow rays from these hits toward the lights (the light at t = 1)")
    r.add_argument("--toward-vertices", type=int, default=0, metavar="N",
                   help="N rays from the eye aimed at vertices and edge midpoints of random triangles")
    r.add_argument("--seed", type=int, default=1, help="seed of --toward-vertices (default 1)")
    r.add_argument("--light", action="append", metavar="X,Y,Z", help="a point light (repeatable; default four)")
    r.add_argument("--offset", type=float, default=1e-4,
                   help="shadow ray origins leave the surface by this fraction of the scene diagonal "
                        "(at least 4 float spacings of the hit point)")
    c.error, r.error, t.error = usage_error(c), usage_error(r), usage_error(t)
    args = p.parse_args(argv)
    try:
        if args.command == "check":
            if args.samples <= 0 or args.jobs <= 0:
                p.error("--samples and --jobs need positive counts")
            return cmd_check(args)
        if args.command == "table":
            return cmd_table(args)
        if args.width <= 0 or args.height <= 0:
            p.error("--width and --height need positive counts")
        return cmd_rays(args)
    except InputError as e:
        sys.stderr.write("%s: error: %s\n" % (TOOL, e))
        return e.code


if __name__ == "__main__":
    sys.exit(main())
