/* OBJ, PLY and OFF through OpenMesh's parsers, into an importer of our own.
 *
 * OpenMesh's mesh types (IO::read_mesh into a TriMesh) drop zero-area faces
 * and split non-manifold vertices, so triangle indices would stop matching
 * the file's face order. Its readers only talk to a BaseImporter, though, and
 * ours records every vertex and face exactly as the reader reports them.
 * One reader still filters before the importer sees anything: the OBJ reader
 * removes repeated corners of a face, skips faces left with fewer than 3
 * corners and skips "v" lines whose numbers it cannot parse (nan, inf). So
 * OBJ faces come from a scan of our own that OpenMesh's faces are checked
 * against, and a vertex OpenMesh skipped is reported, not renumbered around.
 * (The STL reader drops faces with coincident corners too; STL is read in
 * mesh_import.c instead.)
 */
#include <OpenMesh/Core/IO/importer/BaseImporter.hh>
#include <OpenMesh/Core/IO/reader/OBJReader.hh>
#include <OpenMesh/Core/IO/reader/OFFReader.hh>
#include <OpenMesh/Core/IO/reader/PLYReader.hh>
#include <OpenMesh/Core/System/omstream.hh>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <istream>
#include <map>
#include <mutex>
#include <new>
#include <streambuf>
#include <string>
#include <vector>

#include <stdlib.h>
#include <unistd.h>

extern "C" {
#include "as_internal.h"
}
#include "mesh_import_shims.h"

namespace {

using OpenMesh::EdgeHandle;
using OpenMesh::FaceHandle;
using OpenMesh::HalfedgeHandle;
using OpenMesh::Vec2f;
using OpenMesh::Vec3d;
using OpenMesh::Vec3f;
using OpenMesh::Vec3uc;
using OpenMesh::Vec4f;
using OpenMesh::Vec4uc;
using OpenMesh::VertexHandle;
namespace Attributes = OpenMesh::Attributes;

/* An istream over the caller's bytes, without a copy. Seekable, because the
 * OBJ reader makes two passes. */
class MemoryBuf final : public std::streambuf {
public:
    MemoryBuf(const void *data, size_t size)
    {
        char *p = const_cast<char *>(static_cast<const char *>(data));
        setg(p, p, p + size);
    }

protected:
    pos_type seekoff(off_type off, std::ios_base::seekdir dir,
                     std::ios_base::openmode which) override
    {
        if (!(which & std::ios_base::in)) return pos_type(off_type(-1));
        off_type base = 0;
        if (dir == std::ios_base::cur) base = gptr() - eback();
        else if (dir == std::ios_base::end) base = egptr() - eback();
        const off_type target = base + off;
        if (target < 0 || target > egptr() - eback()) return pos_type(off_type(-1));
        setg(eback(), eback() + target, egptr());
        return pos_type(target);
    }
    pos_type seekpos(pos_type pos, std::ios_base::openmode which) override
    {
        return seekoff(off_type(pos), std::ios_base::beg, which);
    }
};

/* Records what a reader reports, in the order it reports it. Vertex and face
 * handles are plain indices: a face's handle is its position in the file. */
class Recorder final : public OpenMesh::IO::BaseImporter {
public:
    explicit Recorder(size_t input_bytes) : input_bytes_(input_bytes) {}

    std::vector<float> positions;   /* 3 per vertex */
    std::vector<float> normals;     /* 3 per vertex once any normal arrives */
    std::vector<float> uvs;         /* 2 per vertex once any UV arrives */
    std::vector<char> has_normal, has_uv;
    size_t normal_count = 0, uv_count = 0; /* vertices given one */
    std::vector<int> corners;       /* every face's corners as the reader gave them */
    std::vector<size_t> face_end;   /* end of each face in `corners` */
    bool reserved = false;
    unsigned reserved_vertices = 0, reserved_faces = 0;

    /* Thrown when a reader reports more than its input could hold: the
     * readers trust the counts of damaged headers and would otherwise loop
     * billions of times past the end. */
    struct TooMany {};

    using BaseImporter::add_vertex;
    VertexHandle add_vertex(const Vec3f &p) override
    {
        if (n_vertices() >= input_bytes_) throw TooMany();
        positions.insert(positions.end(), {p[0], p[1], p[2]});
        return VertexHandle(int(n_vertices() - 1));
    }
    VertexHandle add_vertex() override { return add_vertex(Vec3f(0.0f, 0.0f, 0.0f)); }
    void set_point(VertexHandle vh, const Vec3f &p) override
    {
        if (!in_range(vh)) return;
        float *dst = &positions[size_t(vh.idx()) * 3];
        dst[0] = p[0], dst[1] = p[1], dst[2] = p[2];
    }

    using BaseImporter::add_face;
    FaceHandle add_face(const VHandles &vs) override
    {
        if (n_faces() >= input_bytes_ || corners.size() + vs.size() > input_bytes_) throw TooMany();
        for (const VertexHandle &v : vs) corners.push_back(v.idx());
        face_end.push_back(corners.size());
        return FaceHandle(int(face_end.size() - 1));
    }
    /* Only the OM format builds faces from half-edges; we never read it. */
    FaceHandle add_face(HalfedgeHandle) override { return FaceHandle(); }
    HalfedgeHandle add_edge(VertexHandle, VertexHandle) override { return HalfedgeHandle(); }

    void set_normal(VertexHandle vh, const Vec3f &n) override
    {
        if (!in_range(vh)) return;
        if (normals.size() < positions.size()) {
            normals.resize(positions.size(), 0.0f);
            has_normal.resize(n_vertices(), 0);
        }
        const size_t i = size_t(vh.idx());
        normals[i * 3] = n[0], normals[i * 3 + 1] = n[1], normals[i * 3 + 2] = n[2];
        if (!has_normal[i]) has_normal[i] = 1, ++normal_count;
    }
    void set_normal(VertexHandle vh, const Vec3d &n) override { set_normal(vh, Vec3f(n)); }
    void set_texcoord(VertexHandle vh, const Vec2f &t) override
    {
        if (!in_range(vh)) return;
        if (uvs.size() < n_vertices() * 2) {
            uvs.resize(n_vertices() * 2, 0.0f);
            has_uv.resize(n_vertices(), 0);
        }
        const size_t i = size_t(vh.idx());
        uvs[i * 2] = t[0], uvs[i * 2 + 1] = t[1];
        if (!has_uv[i]) has_uv[i] = 1, ++uv_count;
    }

    void reserve(unsigned nv, unsigned, unsigned nf) override
    {
        reserved = true;
        reserved_vertices = nv;
        reserved_faces = nf;
        /* A header can claim anything; never reserve more than the bytes
         * could hold (a vertex or a face takes at least two bytes). */
        const size_t cap = input_bytes_ / 2;
        positions.reserve(std::min<size_t>(nv, cap) * 3);
        face_end.reserve(std::min<size_t>(nf, cap));
        corners.reserve(std::min<size_t>(nf, cap) * 3);
    }

    size_t n_vertices() const override { return positions.size() / 3; }
    size_t n_faces() const override { return face_end.size(); }
    size_t n_edges() const override { return 0; }

    /* What a ray tracer does not keep. */
    void add_face_texcoords(FaceHandle, VertexHandle, const std::vector<Vec2f> &) override {}
    void add_face_texcoords(FaceHandle, VertexHandle, const std::vector<Vec3f> &) override {}
    void set_face_texindex(FaceHandle, int) override {}
    void set_halfedge(VertexHandle, HalfedgeHandle) override {}
    void set_color(VertexHandle, const Vec3uc &) override {}
    void set_color(VertexHandle, const Vec4uc &) override {}
    void set_color(VertexHandle, const Vec3f &) override {}
    void set_color(VertexHandle, const Vec4f &) override {}
    void set_status(VertexHandle, const Attributes::StatusInfo &) override {}
    void set_next(HalfedgeHandle, HalfedgeHandle) override {}
    void set_face(HalfedgeHandle, FaceHandle) override {}
    void request_face_texcoords2D() override {}
    void set_texcoord(HalfedgeHandle, const Vec2f &) override {}
    void set_texcoord(VertexHandle, const Vec3f &) override {}
    void set_texcoord(HalfedgeHandle, const Vec3f &) override {}
    void set_status(HalfedgeHandle, const Attributes::StatusInfo &) override {}
    void set_color(EdgeHandle, const Vec3uc &) override {}
    void set_color(EdgeHandle, const Vec4uc &) override {}
    void set_color(EdgeHandle, const Vec3f &) override {}
    void set_color(EdgeHandle, const Vec4f &) override {}
    void set_status(EdgeHandle, const Attributes::StatusInfo &) override {}
    void set_normal(FaceHandle, const Vec3f &) override {}
    void set_normal(FaceHandle, const Vec3d &) override {}
    void set_color(FaceHandle, const Vec3uc &) override {}
    void set_color(FaceHandle, const Vec4uc &) override {}
    void set_color(FaceHandle, const Vec3f &) override {}
    void set_color(FaceHandle, const Vec4f &) override {}
    void set_status(FaceHandle, const Attributes::StatusInfo &) override {}
    void add_texture_information(int, std::string) override {}

private:
    bool in_range(VertexHandle vh) const
    {
        return vh.idx() >= 0 && size_t(vh.idx()) < n_vertices();
    }
    size_t input_bytes_;
};

/* ------------------------------------------------------------------------ */
/* Our own pass over an OBJ file: the corners of every face statement, the
 * material in force, and the "v" lines OpenMesh may skip. */

struct ObjScan {
    std::vector<int64_t> corners;     /* 0-based position index per corner */
    std::vector<size_t> face_end;
    std::vector<uint32_t> face_line;
    std::vector<uint32_t> face_material;
    uint64_t vertex_lines = 0;
    bool has_usemtl = false;
    /* The first "v" line whose coordinates strtod reads as non-finite, or
     * cannot read at all. */
    bool bad_vertex = false, bad_vertex_unreadable = false;
    uint64_t bad_vertex_index = 0;
    uint32_t bad_vertex_line = 0;
    double bad_xyz[3] = {0, 0, 0};
};

bool is_blank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v'; }

/* Returns false (error set) on a face corner that is not a number. */
bool obj_scan(const char *data, size_t size, const char *name, ObjScan &scan)
{
    std::map<std::string, uint32_t> materials;
    uint32_t material = 0; /* 0: before any usemtl */
    uint32_t line = 0;
    size_t pos = 0;
    std::string token;
    while (pos < size) {
        ++line;
        const char *nl = static_cast<const char *>(std::memchr(data + pos, '\n', size - pos));
        const size_t end = nl ? size_t(nl - data) : size;
        size_t p = pos;
        pos = end + 1;
        while (p < end && is_blank(data[p])) ++p;
        size_t kw_end = p;
        while (kw_end < end && !is_blank(data[kw_end])) ++kw_end;
        const size_t kw_len = kw_end - p;
        if (kw_len == 1 && data[p] == 'v') {
            const uint64_t index = scan.vertex_lines++;
            if (scan.bad_vertex) continue;
            std::string rest(data + kw_end, end - kw_end);
            const char *s = rest.c_str();
            double xyz[3];
            bool readable = true;
            for (double &c : xyz) {
                char *after;
                c = std::strtod(s, &after);
                if (after == s) readable = false;
                s = after;
            }
            if (!readable || !std::isfinite(xyz[0]) || !std::isfinite(xyz[1]) ||
                !std::isfinite(xyz[2])) {
                scan.bad_vertex = true;
                scan.bad_vertex_unreadable = !readable;
                scan.bad_vertex_index = index;
                scan.bad_vertex_line = line;
                std::memcpy(scan.bad_xyz, xyz, sizeof xyz);
            }
        } else if (kw_len == 1 && data[p] == 'f') {
            size_t q = kw_end;
            while (q < end) {
                while (q < end && is_blank(data[q])) ++q;
                if (q >= end) break;
                size_t t_end = q;
                while (t_end < end && !is_blank(data[t_end])) ++t_end;
                token.assign(data + q, t_end - q);
                q = t_end;
                /* The whole number (a NUL inside the word would end
                 * strtoll's reading early), up to a '/' before texture and
                 * normal indices, and within range. */
                char *after;
                errno = 0;
                const long long v = std::strtoll(token.c_str(), &after, 10);
                const bool whole = after == token.c_str() + token.size() || *after == '/';
                if (after == token.c_str() || !whole || errno == ERANGE || v == 0) {
                    std::string shown(token);
                    for (char &ch : shown)
                        if (!std::isprint((unsigned char)ch)) ch = '?';
                    as_set_error(AS_ERROR_PARSE, "%s: line %u: cannot parse face corner '%s'",
                                 name, line, shown.c_str());
                    return false;
                }
                /* OBJ counts from 1; negative indices count back from the
                 * latest vertex. */
                scan.corners.push_back(v > 0 ? int64_t(v) - 1
                                             : int64_t(scan.vertex_lines) + int64_t(v));
            }
            scan.face_end.push_back(scan.corners.size());
            scan.face_line.push_back(line);
            scan.face_material.push_back(material);
        } else if (kw_len == 6 && std::memcmp(data + p, "usemtl", 6) == 0) {
            size_t a = kw_end, b = end;
            while (a < b && is_blank(data[a])) ++a;
            while (b > a && is_blank(data[b - 1])) --b;
            const std::string mtl(data + a, b - a);
            auto it = materials.find(mtl);
            if (it == materials.end())
                it = materials.emplace(mtl, uint32_t(materials.size() + 1)).first;
            material = it->second;
            scan.has_usemtl = true;
        }
    }
    return true;
}

/* ------------------------------------------------------------------------ */

/* Lines and blank-separated words of a text in memory. */
class LineWords {
public:
    LineWords(const char *data, size_t size) : data_(data), size_(size) {}
    /* The next line's words; false at the end. */
    bool next(std::vector<std::string> &words)
    {
        if (pos_ >= size_) return false;
        ++line_;
        const char *nl = static_cast<const char *>(std::memchr(data_ + pos_, '\n', size_ - pos_));
        const size_t end = nl ? size_t(nl - data_) : size_;
        words.clear();
        for (size_t p = pos_; p < end;) {
            while (p < end && is_blank(data_[p])) ++p;
            size_t q = p;
            while (q < end && !is_blank(data_[q])) ++q;
            if (q > p) words.emplace_back(data_ + p, q - p);
            p = q;
        }
        pos_ = end + 1;
        return true;
    }
    /* The next line that has words. */
    bool next_nonblank(std::vector<std::string> &words)
    {
        while (next(words))
            if (!words.empty()) return true;
        return false;
    }
    /* The number of the line last read, from 1. */
    size_t line() const { return line_; }

private:
    const char *data_;
    size_t size_, pos_ = 0, line_ = 0;
};

/* A plain number the OFF reader reads whole into its 32-bit counts and
 * indices: the whole word (a NUL inside it would end strtoull's reading
 * early), at most 4294967295 (a larger one fails the reader's stream, and it
 * then pushed corners until it had taken 16 GB). */
bool parse_count(const std::string &w, unsigned long long &n)
{
    char *after;
    if (w.empty() || !std::isdigit((unsigned char)w[0])) return false;
    errno = 0;
    n = std::strtoull(w.c_str(), &after, 10);
    return after == w.c_str() + w.size() && errno == 0 && n <= 0xffffffffull;
}

/* A word the OFF reader reads whole as a coordinate: a decimal number and
 * nothing after it. */
bool parse_real(const std::string &w)
{
    if (w.empty() || w.find_first_not_of("0123456789+-.eE") != std::string::npos) return false;
    char *after;
    std::strtod(w.c_str(), &after);
    return after == w.c_str() + w.size();
}

/* A face line of a text OFF file must hold exactly the corners its count
 * announces, each a plain number. OpenMesh's reader reads faces number by
 * number across lines and trusts each count ("-3" reads as 4294967293, "2-3"
 * as 2 then -3, and a number left over, such as a face colour, as the next
 * face's count), pushing that many corners past a failed stream. */
bool face_line_sane(const std::vector<std::string> &words, bool colours)
{
    unsigned long long k, v;
    if (words.empty() || !parse_count(words[0], k)) return false;
    /* With face colours (COFF, CNOFF, ...) the reader takes the rest of
     * the line after the corners as the colour. */
    if (colours ? k > words.size() - 1 : k != words.size() - 1) return false;
    for (size_t i = 1; i <= k; ++i)
        if (!parse_count(words[i], v)) return false;
    return true;
}

/* A text OFF file's counts line and the lines they promise, and the corner
 * counts of its faces. OpenMesh's OFF reader reads the counts and each
 * vertex's coordinates (and normal) number by number across lines, and
 * trusts what it reads: a counts line of two numbers made it take the first
 * face's corner count for the edge count and a corner index for a corner
 * count, and push that many corners; a vertex line one number short shifts
 * everything after it the same way. Nor does it notice a missing or
 * unreadable counts line, nor a body shorter than the counts: it reads on at
 * the end of the stream with counts it never set, which loops or allocates
 * gigabytes. So the lines must hold what the reader will take from them;
 * false with the line and what is wrong in *why. */
bool off_faces_sane(const char *data, size_t size, std::string *why)
{
    std::vector<std::string> words;
    LineWords lines(data, size);
    char at[160];
    if (!lines.next(words) || words.empty() || words.size() > 2) {
        *why = "line 1: no OFF keyword line";
        return false;
    }
    /* The header line is the keyword (letters and digits ending in OFF:
     * OFF, NOFF, COFF, STOFF, 4OFF, ...) and at most the word BINARY; on
     * anything else OpenMesh may guess ASCII or binary either way, so the
     * checks below could not speak for the reader. */
    const std::string &magic = words[0];
    bool keyword = magic.size() >= 3 && magic.compare(magic.size() - 3, 3, "OFF") == 0;
    for (char ch : magic)
        if (!std::isalnum(static_cast<unsigned char>(ch))) keyword = false;
    if (!keyword || (words.size() == 2 && words[1] != "BINARY")) {
        *why = "line 1: no OFF keyword line";
        return false;
    }
    if (words.size() == 2) return true; /* the reader checks the binary body */
    /* With normals (NOFF, CNOFF, STNOFF, ...) a vertex is six numbers, the
     * reader takes any colour or texture coordinates from the rest of its
     * line. */
    const size_t per_vertex = magic.find('N') != std::string::npos ? 6 : 3;
    const bool colours = magic.find('C') != std::string::npos;
    unsigned long long nv, nf, ne;
    if (!lines.next_nonblank(words) || words.size() != 3 || !parse_count(words[0], nv) ||
        !parse_count(words[1], nf) || !parse_count(words[2], ne)) {
        std::snprintf(at, sizeof at, "line %zu: the counts line must hold three counts: vertices, faces, edges",
                      lines.line());
        *why = at;
        return false;
    }
    for (unsigned long long i = 0; i < nv; ++i) {
        if (!lines.next_nonblank(words)) {
            std::snprintf(at, sizeof at, "the file ends after %llu of its %llu vertices", i, nv);
            *why = at;
            return false;
        }
        bool numbers = words.size() >= per_vertex;
        for (size_t k = 0; numbers && k < per_vertex; ++k) numbers = parse_real(words[k]);
        if (!numbers) {
            std::snprintf(at, sizeof at, "line %zu: vertex %llu must begin with %zu numbers", lines.line(), i,
                          per_vertex);
            *why = at;
            return false;
        }
    }
    for (unsigned long long i = 0; i < nf; ++i) {
        if (!lines.next_nonblank(words)) {
            std::snprintf(at, sizeof at, "the file ends after %llu of its %llu faces", i, nf);
            *why = at;
            return false;
        }
        if (!face_line_sane(words, colours)) {
            std::snprintf(at, sizeof at, "line %zu: face %llu must be its corner count and %sthat many vertex indices",
                          lines.line(), i, colours ? "" : "exactly ");
            *why = at;
            return false;
        }
    }
    return true;
}

/* OpenMesh's OFF reader takes the header's flags (normals, colours, texture
 * coordinates, BINARY) from a previous can_u_read(filename) call, not from
 * the stream it reads, and the stream overload of can_u_read is private. So
 * the header is shown to it through a file: the source file itself, or, for
 * decompressed data, a temporary file holding only the first line (all that
 * it reads). Returns false when the header is not OFF. */
bool off_prepare_header(const char *data, size_t size, const char *file_path)
{
    if (file_path) return OpenMesh::IO::OFFReader().can_u_read(std::string(file_path));
    const char *nl = static_cast<const char *>(std::memchr(data, '\n', size));
    const size_t len = nl ? size_t(nl - data) + 1 : size;
    const char *dir = std::getenv("TMPDIR");
    std::string tmpl = std::string(dir && *dir ? dir : "/tmp") + "/libas-off-XXXXXX.off";
    std::vector<char> name(tmpl.begin(), tmpl.end());
    name.push_back('\0');
    const int fd = mkstemps(name.data(), 4);
    if (fd < 0) return false;
    const bool written = write(fd, data, len) == ssize_t(len);
    close(fd);
    const bool ok = written && OpenMesh::IO::OFFReader().can_u_read(std::string(name.data()));
    unlink(name.data());
    return ok;
}

std::mutex openmesh_mutex;

/* OpenMesh's readers write warnings to omerr/omlog/omout; the tools print
 * only our message, so they are muted while a reader runs. */
class QuietOpenMesh {
public:
    QuietOpenMesh()
        : err_(::omerr().is_enabled()), log_(::omlog().is_enabled()),
          out_(::omout().is_enabled()), cerr_(std::cerr.rdbuf(&null_))
    {
        ::omerr().disable();
        ::omlog().disable();
        ::omout().disable();
    }
    ~QuietOpenMesh()
    {
        if (err_) ::omerr().enable();
        if (log_) ::omlog().enable();
        if (out_) ::omout().enable();
        std::cerr.rdbuf(cerr_);
    }

private:
    /* Swallows everything: a few PLY paths write to std::cerr directly. The
     * swap is not synchronised with other threads writing to std::cerr; the
     * library and its tools write to stderr only through stdio. */
    struct NullBuf : std::streambuf {
        int overflow(int c) override { return traits_type::not_eof(c); }
    };
    bool err_, log_, out_;
    NullBuf null_;
    std::streambuf *cerr_;
};

const char *upper(const std::string &format)
{
    if (format == "obj") return "OBJ";
    if (format == "ply") return "PLY";
    return "OFF";
}

/* Checks the faces and moves everything into the mesh. `corners` and
 * `face_end` are the faces in file order (from the recorder or, for OBJ, from
 * the scan). */
template <typename Index>
as_error_t build_mesh(const Recorder &rec, const std::vector<Index> &corners,
                      const std::vector<size_t> &face_end, const uint32_t *face_line,
                      const uint32_t *face_material, const char *name, as_mesh_t *mesh)
{
    const uint64_t nv = rec.n_vertices();
    if (nv > UINT32_MAX)
        return as_set_error(AS_ERROR_UNSUPPORTED, "%s: %llu vertices (at most 2^32 - 1)", name,
                            (unsigned long long)nv);
    uint64_t triangles = 0;
    uint32_t polygons = 0;
    size_t begin = 0;
    for (size_t f = 0; f < face_end.size(); ++f) {
        const size_t k = face_end[f] - begin;
        char where[32] = "";
        if (face_line) std::snprintf(where, sizeof where, " (line %u)", face_line[f]);
        if (k < 3)
            return as_set_error(AS_ERROR_INVALID_MESH,
                                "%s: face %zu%s has %zu corners (a face needs at least 3)",
                                name, f, where, k);
        for (size_t c = begin; c < face_end[f]; ++c) {
            if (corners[c] < 0 || uint64_t(corners[c]) >= nv)
                return as_set_error(AS_ERROR_INVALID_MESH,
                                    "%s: face %zu%s refers to vertex %lld but the file has "
                                    "%llu vertices",
                                    name, f, where, (long long)corners[c],
                                    (unsigned long long)nv);
        }
        triangles += k - 2;
        if (k > 3) ++polygons;
        begin = face_end[f];
    }
    if (triangles > UINT32_MAX)
        return as_set_error(AS_ERROR_UNSUPPORTED, "%s: %llu triangles (at most 2^32 - 1)", name,
                            (unsigned long long)triangles);

    mesh->vertex_count = uint32_t(nv);
    mesh->triangle_count = uint32_t(triangles);
    mesh->faces_in_file = face_end.size();
    mesh->polygon_faces = polygons;
    mesh->positions = static_cast<float *>(as_malloc(nv * 3 * sizeof(float) + 1, "positions"));
    mesh->indices = static_cast<uint32_t *>(as_malloc(triangles * 3 * sizeof(uint32_t) + 1, "indices"));
    const bool normals = nv > 0 && rec.normal_count == nv;
    const bool uvs = nv > 0 && rec.uv_count == nv;
    if (normals) mesh->normals = static_cast<float *>(as_malloc(nv * 3 * sizeof(float), "normals"));
    if (uvs) mesh->uvs = static_cast<float *>(as_malloc(nv * 2 * sizeof(float), "UVs"));
    if (face_material)
        mesh->material_ids = static_cast<uint32_t *>(
            as_malloc(triangles * sizeof(uint32_t) + 1, "material ids"));
    if (!mesh->positions || !mesh->indices || (normals && !mesh->normals) ||
        (uvs && !mesh->uvs) || (face_material && !mesh->material_ids))
        return AS_ERROR_OUT_OF_MEMORY;

    if (nv) std::memcpy(mesh->positions, rec.positions.data(), nv * 3 * sizeof(float));
    if (normals) std::memcpy(mesh->normals, rec.normals.data(), nv * 3 * sizeof(float));
    if (uvs) std::memcpy(mesh->uvs, rec.uvs.data(), nv * 2 * sizeof(float));
    /* A face of k corners becomes the fan (c0, ci, ci+1), i = 1 .. k-2, so
     * its triangles stay consecutive and in the file's winding. */
    uint32_t *tri = mesh->indices;
    size_t t = 0;
    begin = 0;
    for (size_t f = 0; f < face_end.size(); ++f) {
        for (size_t c = begin + 1; c + 1 < face_end[f]; ++c, ++t) {
            *tri++ = uint32_t(corners[begin]);
            *tri++ = uint32_t(corners[c]);
            *tri++ = uint32_t(corners[c + 1]);
            if (face_material) mesh->material_ids[t] = face_material[f];
        }
        begin = face_end[f];
    }
    return AS_OK;
}

as_error_t read_obj(const Recorder &rec, const ObjScan &scan, const char *name, as_mesh_t *mesh)
{
    if (rec.n_vertices() != scan.vertex_lines) {
        if (scan.bad_vertex && !scan.bad_vertex_unreadable)
            return as_set_error(AS_ERROR_INVALID_MESH,
                                "%s: vertex %llu (line %u) has a non-finite coordinate "
                                "(%g, %g, %g)",
                                name, (unsigned long long)scan.bad_vertex_index,
                                scan.bad_vertex_line, scan.bad_xyz[0], scan.bad_xyz[1],
                                scan.bad_xyz[2]);
        if (scan.bad_vertex)
            return as_set_error(AS_ERROR_PARSE, "%s: line %u: cannot parse vertex %llu", name,
                                scan.bad_vertex_line,
                                (unsigned long long)scan.bad_vertex_index);
        return as_set_error(AS_ERROR_PARSE,
                            "%s: cannot parse as OBJ (%llu vertex lines, %zu vertices read)",
                            name, (unsigned long long)scan.vertex_lines, rec.n_vertices());
    }

    /* OpenMesh's faces must be ours with repeated corners removed and faces
     * of fewer than 3 distinct corners left out; anything else means the two
     * parsers read the file differently. */
    size_t om_face = 0, begin = 0;
    std::vector<int64_t> distinct;
    for (size_t f = 0; f < scan.face_end.size(); ++f) {
        distinct.clear();
        for (size_t c = begin; c < scan.face_end[f]; ++c)
            if (std::find(distinct.begin(), distinct.end(), scan.corners[c]) == distinct.end())
                distinct.push_back(scan.corners[c]);
        begin = scan.face_end[f];
        if (distinct.size() < 3) continue;
        bool same = om_face < rec.face_end.size();
        if (same) {
            const size_t b = om_face ? rec.face_end[om_face - 1] : 0;
            same = rec.face_end[om_face] - b == distinct.size();
            for (size_t i = 0; same && i < distinct.size(); ++i)
                same = rec.corners[b + i] == distinct[i];
        }
        if (!same)
            return as_set_error(AS_ERROR_PARSE, "%s: line %u: cannot parse face %zu as OBJ",
                                name, scan.face_line[f], f);
        ++om_face;
    }
    if (om_face != rec.face_end.size())
        return as_set_error(AS_ERROR_PARSE, "%s: cannot parse as OBJ (%zu faces, %zu read)",
                            name, om_face, rec.face_end.size());

    return build_mesh(rec, scan.corners, scan.face_end, scan.face_line.data(),
                      scan.has_usemtl ? scan.face_material.data() : nullptr, name, mesh);
}

void free_mesh_arrays(as_mesh_t *mesh)
{
    std::free(mesh->positions);
    std::free(mesh->indices);
    std::free(mesh->normals);
    std::free(mesh->uvs);
    std::free(mesh->material_ids);
    std::memset(mesh, 0, sizeof *mesh);
}

as_error_t read_openmesh(const void *data, size_t size, const std::string &format,
                         const char *name, const char *file_path, as_mesh_t *mesh)
{
    Recorder rec(size);
    /* Before OpenMesh: its OBJ reader asserts on a face corner without a
     * vertex index ("f /1/1 ..."), which the scan refuses. */
    ObjScan scan;
    if (format == "obj" && !obj_scan(static_cast<const char *>(data), size, name, scan))
        return as_get_error();
    if (format == "ply" && as_mesh_check_ply(data, size, name) != AS_OK) return as_get_error();
    bool ok = false;
    bool stream_failed;
    std::string off_why;
    {
        std::lock_guard<std::mutex> lock(openmesh_mutex);
        QuietOpenMesh quiet;
        MemoryBuf buf(data, size);
        std::istream in(&buf);
        /* What we ask for; each reader answers with what the file has. */
        OpenMesh::IO::Options opt = OpenMesh::IO::Options::VertexNormal |
                                    OpenMesh::IO::Options::VertexTexCoord;
        try {
        if (format == "obj") {
            ok = OpenMesh::IO::OBJReader().read(in, rec, opt);
        } else if (format == "ply") {
            ok = OpenMesh::IO::PLYReader().read(in, rec, opt);
        } else {
            ok = off_faces_sane(static_cast<const char *>(data), size, &off_why) &&
                 off_prepare_header(static_cast<const char *>(data), size, file_path) &&
                 OpenMesh::IO::OFFReader().read(in, rec, opt);
        }
        } catch (const Recorder::TooMany &) {
            ok = false;
        }
        stream_failed = in.fail();
    }
    const char *fmt = upper(format);
    if (!ok && !off_why.empty()) return as_set_error(AS_ERROR_PARSE, "%s: cannot parse as %s (%s)", name, fmt, off_why.c_str());
    if (!ok) return as_set_error(AS_ERROR_PARSE, "%s: cannot parse as %s", name, fmt);
    if (format == "obj") return read_obj(rec, scan, name, mesh);

    /* The PLY and OFF readers stop early or read zeros past a damaged or
     * truncated body and still report success: the header's counts and the
     * stream's state tell. */
    if (rec.reserved && (rec.n_vertices() != rec.reserved_vertices ||
                         rec.n_faces() != rec.reserved_faces))
        return as_set_error(AS_ERROR_PARSE,
                            "%s: cannot parse as %s (read %zu of %u vertices and %zu of %u "
                            "faces)",
                            name, fmt, rec.n_vertices(), rec.reserved_vertices, rec.n_faces(),
                            rec.reserved_faces);
    if (stream_failed)
        return as_set_error(AS_ERROR_PARSE, "%s: cannot parse as %s (damaged or truncated)",
                            name, fmt);
    return build_mesh(rec, rec.corners, rec.face_end, nullptr, nullptr, name, mesh);
}

} // namespace

extern "C" as_error_t as_mesh_read_openmesh(const void *data, size_t size, const char *format,
                                            const char *name, const char *file_path,
                                            as_mesh_t *mesh)
{
    std::memset(mesh, 0, sizeof *mesh);
    as_error_t err;
    try {
        err = read_openmesh(data, size, format, name, file_path, mesh);
    } catch (const std::bad_alloc &) {
        err = as_set_error(AS_ERROR_OUT_OF_MEMORY, "%s: out of memory while reading", name);
    } catch (const std::exception &e) {
        err = as_set_error(AS_ERROR_PARSE, "%s: cannot parse (%s)", name, e.what());
    } catch (...) {
        err = as_set_error(AS_ERROR_PARSE, "%s: cannot parse", name);
    }
    if (err != AS_OK) free_mesh_arrays(mesh);
    return err;
}
