/* The KD-tree build driver shared by the mid-cut and SAH builders.
 *
 * Perfect splits: a reference's box is the box of the part of its triangle
 * inside the node, found by clipping the triangle polygon against the child
 * box in double precision and rounding the result outwards (Havran's "split
 * clipping", as Wald & Havran 2006 use it), so a box never loses a point of
 * its triangle.
 *
 * Sides: a triangle goes below when its box reaches the plane from below and
 * above when it reaches it from above, so one that touches the plane goes to
 * both sides; a triangle lying in the plane goes to the side the builder
 * chose by cost. Every leaf whose closed box holds a point of a triangle then
 * refers to it. The rope traversal needs that: a path through a vertex on a
 * split plane may cross only the corner of the leaf above it, and the leaf it
 * does visit at that point must hold the triangle. (Wald & Havran's rule,
 * which keeps a touching triangle on its own side, cuts off more empty space
 * (on the bunny 30% of SAH) but leaks there.)
 *
 * Termination, each rule enough to stop: the builder says leaf (leaf size,
 * SAH cost); the depth cap (never deeper than the KD-standard stack); no
 * progress (both children would hold every reference); the reference budget:
 * a node's subtree may hold at most its share of split_budget x triangles,
 * shares handed to children in proportion to their counts, which bounds the
 * total and is independent of the order threads run in.
 *
 * Determinism: a node's split and children depend only on its references, in
 * an order fixed by the parent; leaves sort their indices; the output is one
 * depth-first walk after the build. The bytes are the same for any thread
 * count. */
#include "kd_build.h"
#include "spatial_common.h"
#include "task_pool.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#include <float.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* A right child of this many references or more goes to a waiting thread
 * (children are handed over only while one waits): small, so that a thread
 * that runs out of work near the end of the build soon gets some. */
#define PARALLEL_MIN_REFS 256
#define PARTITION_MIN_REFS 32768
#define KD_PARTITION_CHUNKS 64

typedef struct kd_tmp {
    struct kd_tmp *child[2];   /* NULL for a leaf */
    int axis;
    float pos;
    uint32_t *ids;             /* leaf: sorted source indices */
    uint32_t count;
} kd_tmp;

typedef struct kd_run {
    const kd_ctx *c;
    atomic_int cancelled;
    atomic_int oom;
    pthread_mutex_t lock;
    double done, next_report;
    kd_scratch *free_scratch;  /* under lock; at most one per thread exists */
} kd_run;

void *kd_scratch_reserve(kd_scratch *s, size_t bytes)
{
    if (bytes <= s->buf_size) return s->buf;
    const size_t size = bytes + bytes / 2;
    void *b = malloc(size);
    if (!b) return NULL;
    free(s->buf);
    s->buf = b;
    s->buf_size = size;
    return b;
}

/* The temporary tree's nodes and leaf lists come from per-thread chunks,
 * all freed at once after the tree is written out: one call per chunk
 * instead of one per node and per leaf. */
typedef struct kd_arena_chunk {
    struct kd_arena_chunk *next;
    size_t used, size;
    _Alignas(16) unsigned char data[];
} kd_arena_chunk;

#define KD_ARENA_CHUNK ((size_t)256 << 10)

static void *arena_alloc(kd_scratch *s, size_t bytes)
{
    bytes = (bytes + 15) & ~(size_t)15;
    kd_arena_chunk *c = s->arena;
    if (!c || c->size - c->used < bytes) {
        const size_t size = bytes > KD_ARENA_CHUNK ? bytes : KD_ARENA_CHUNK;
        kd_arena_chunk *n = malloc(sizeof *n + size);
        if (!n) return NULL;
        n->next = c;
        n->used = 0;
        n->size = size;
        s->arena = c = n;
    }
    void *p = c->data + c->used;
    c->used += bytes;
    return p;
}

/* A thread's scratch, kept from task to task: side[] has two bytes per
 * triangle, too big to allocate per node. */
static kd_scratch *scratch_get(kd_run *run)
{
    pthread_mutex_lock(&run->lock);
    kd_scratch *s = run->free_scratch;
    if (s) run->free_scratch = s->next_free;
    pthread_mutex_unlock(&run->lock);
    if (s) return s;
    s = calloc(1, sizeof *s);
    if (s && run->c->ops->child_states)
        /* One spare entry: the SAH builder reads side[] four bytes at a
         * time. */
        s->side = calloc((size_t)run->c->mesh->triangle_count + 1, sizeof(uint16_t));
    if (!s || (run->c->ops->child_states && !s->side)) {
        free(s);
        return NULL;
    }
    return s;
}

static void scratch_put(kd_run *run, kd_scratch *s)
{
    if (!s) return;
    pthread_mutex_lock(&run->lock);
    s->next_free = run->free_scratch;
    run->free_scratch = s;
    pthread_mutex_unlock(&run->lock);
}

static void scratch_free_all(kd_run *run)
{
    while (run->free_scratch) {
        kd_scratch *s = run->free_scratch;
        run->free_scratch = s->next_free;
        free(s->side);
        free(s->clipped[0]);
        free(s->clipped[1]);
        free(s->buf);
        while (s->arena) {
            kd_arena_chunk *c = s->arena;
            s->arena = c->next;
            free(c);
        }
        free(s);
    }
}

static int scratch_clipped_room(kd_scratch *s, uint32_t n)
{
    if (n <= s->clipped_cap) return 1;
    const size_t cap = (size_t)n + n / 2;
    for (int side = 0; side < 2; ++side) {
        free(s->clipped[side]);
        s->clipped[side] = malloc(sizeof(uint32_t) * cap);
    }
    if (!s->clipped[0] || !s->clipped[1]) {
        free(s->clipped[0]);
        free(s->clipped[1]);
        s->clipped[0] = s->clipped[1] = NULL;
        s->clipped_cap = 0;
        return 0;
    }
    s->clipped_cap = cap;
    return 1;
}

/* Leaves report the build's progress in steps of this share of it: the
 * progress callback is called at most every 1%. */
#define REPORT_STEP (1.0 / 1024)

static void report(kd_run *run, double weight)
{
    const as_build_args_t *a = run->c->args;
    pthread_mutex_lock(&run->lock);
    run->done += weight;
    if (a->progress && run->done >= run->next_report) {
        run->next_report = run->done + 0.01;
        if (!a->progress(a->progress_user, run->done > 1.0 ? 1.0 : run->done)) atomic_store(&run->cancelled, 1);
    }
    pthread_mutex_unlock(&run->lock);
}

static int cmp_u32(const void *a, const void *b)
{
    const uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return x < y ? -1 : x > y;
}

static kd_tmp *new_tmp(kd_run *run, kd_scratch *sc)
{
    kd_tmp *t = arena_alloc(sc, sizeof *t);
    if (t) memset(t, 0, sizeof *t);
    else atomic_store(&run->oom, 1);
    return t;
}

static void free_state(const kd_run *run, void *state)
{
    if (state && run->c->ops->free_state) run->c->ops->free_state(state);
}

/* Reference arrays of more than SMALL_REFS are temporaries (as_temp_take). */
static size_t refs_bytes(uint32_t n) { return sizeof(kd_ref) * (n ? n : 1); }
static kd_ref *refs_alloc(uint32_t n) { return as_temp_take(refs_bytes(n), "KD references"); }

/* The reference arrays of small nodes (most of the tree's) are blocks of
 * room for SMALL_REFS, carved from the thread's arena and kept on a free
 * list: a node takes two and gives one back, and malloc and free cost
 * more than the rest of such a node's partition. A block never leaves its
 * thread (only children of PARALLEL_MIN_REFS references or more go to
 * other threads), and the arena frees them all after the build. */
#define SMALL_REFS 64

typedef union small_refs_block {
    union small_refs_block *next;
    kd_ref refs[SMALL_REFS];
} small_refs_block;

static kd_ref *refs_take(kd_scratch *sc, uint32_t n)
{
    if (n > SMALL_REFS) return refs_alloc(n);
    small_refs_block *b = sc->small_refs;
    if (b) {
        sc->small_refs = b->next;
        return b->refs;
    }
    b = arena_alloc(sc, sizeof *b);
    return b ? b->refs : NULL;
}

/* Gives back refs, of n references, taken with refs_take (pooled) or not
 * (the root's). */
static void refs_give(kd_scratch *sc, kd_ref *refs, uint32_t n, int pooled)
{
    if (!pooled || n > SMALL_REFS) {
        as_temp_give(refs);
        return;
    }
    if (!refs) return;
    small_refs_block *b = (small_refs_block *)(void *)refs;
    b->next = sc->small_refs;
    sc->small_refs = b;
}

static kd_tmp *make_leaf(kd_run *run, kd_scratch *sc, kd_ref *refs, uint32_t n, int pooled, void *state, uint32_t depth,
                         double weight)
{
    free_state(run, state);
    kd_tmp *t = new_tmp(run, sc);
    sc->leaves++;
    sc->refs += n;
    sc->empty += n == 0;
    if (depth > sc->max_depth) sc->max_depth = depth;
    if (t && n) {
        t->ids = arena_alloc(sc, sizeof(uint32_t) * n);
        if (!t->ids) {
            atomic_store(&run->oom, 1);
        } else {
            /* References arrive in triangle order (the root's are, children
             * keep their parent's); the sort is for builders that would not. */
            int sorted = 1;
            for (uint32_t i = 0; i < n; ++i) {
                t->ids[i] = refs[i].id;
                sorted &= i == 0 || t->ids[i - 1] < t->ids[i];
            }
            if (!sorted) qsort(t->ids, n, sizeof(uint32_t), cmp_u32);
            t->count = n;
        }
    }
    refs_give(sc, refs, n, pooled);
    sc->unreported += weight;
    if (sc->unreported >= REPORT_STEP) {
        report(run, sc->unreported);
        sc->unreported = 0.0;
    }
    return t;
}

/* Clipping runs once or twice for every reference a split cuts, about a
 * fifth of a small node's references, and which way each comparison below
 * goes is a coin toss: it selects through masks rather than branching.
 * Mispredicted branches were most of its time. */
static inline double select_double(int c, double a, double b)
{
    uint64_t ua, ub;
    memcpy(&ua, &a, 8);
    memcpy(&ub, &b, 8);
    const uint64_t m = (uint64_t)0 - (uint64_t)(c != 0);
    ua = (ua & m) | (ub & ~m);
    memcpy(&a, &ua, 8);
    return a;
}

static inline float select_float(int c, float a, float b)
{
    uint32_t ua, ub;
    memcpy(&ua, &a, 4);
    memcpy(&ub, &b, 4);
    const uint32_t m = 0u - (uint32_t)(c != 0);
    ua = (ua & m) | (ub & ~m);
    memcpy(&a, &ua, 4);
    return a;
}

#if defined(__SSE2__)
/* A lane mask of c, and a where m is set and b elsewhere, in both lanes. */
static inline __m128d mask2(int c) { return _mm_castsi128_pd(_mm_set1_epi64x(-(long long)(c != 0))); }
static inline __m128d select2(__m128d m, __m128d a, __m128d b) { return _mm_or_pd(_mm_and_pd(m, a), _mm_andnot_pd(m, b)); }
#endif

static inline double min_double(double a, double b) { return a < b ? a : b; }
static inline double max_double(double a, double b) { return a > b ? a : b; }

/* x rounded down / up to a float, for x not NaN. */
static inline float round_down(double x)
{
    const float f = (float)x;
    return select_float((double)f > x, as_float_next_down(f), f);
}

static inline float round_up(double x)
{
    const float f = (float)x;
    return select_float((double)f < x, as_float_next_up(f), f);
}

/* The faces of box that a reference's bounds reach, as clip_triangle's
 * plane bits. The reference bounds the triangle's part in the box (every
 * reference the builders make does), so a face it stays clear of cannot cut
 * that part: the triangle clipped without it is the same convex polygon
 * (its computed corners may differ in their last bits, and the bounds,
 * rounded out to floats, rarely by one step). Deep in the tree a triangle
 * reaches past many of a node's faces while its part touches few. */
static inline unsigned faces_touched(const kd_ref *old, const float box[6])
{
    unsigned faces = 0;
    for (int k = 0; k < 3; ++k)
        faces |= (unsigned)(old->lo[k] <= box[k]) << k | (unsigned)(old->hi[k] >= box[k + 3]) << (k + 3);
    return faces;
}

/* Triangle t clipped to `box` (Sutherland-Hodgman, in double precision, the
 * planes in order): the polygon's vertices, in one of `poly`'s two
 * buffers, and their count in *count. Six planes add at most six vertices
 * to the triangle's three; one more slot repeats the first vertex after the
 * last, so that every edge is (v[i], v[i + 1]). */
static const double (*clip_triangle(const as_tri4_t *t, const kd_ref *old, const float box[6], double poly[2][10][3],
                                    int *count))[3]
{
    int cnt = 3, cur = 0;
    const as_f4_t *const tv[3] = {&t->v0, &t->v1, &t->v2};
    for (int v = 0; v < 3; ++v) {
        poly[0][v][0] = tv[v]->x;
        poly[0][v][1] = tv[v]->y;
        poly[0][v][2] = tv[v]->z;
    }
    /* Only planes that some vertex is outside of can cut the triangle. */
    unsigned planes = 0;
    for (int k = 0; k < 3; ++k) {
        const double p0 = poly[0][0][k], p1 = poly[0][1][k], p2 = poly[0][2][k];
        const double lo = min_double(min_double(p0, p1), p2), hi = max_double(max_double(p0, p1), p2);
        planes |= (unsigned)(lo < (double)box[k]) << k | (unsigned)(hi > (double)box[k + 3]) << (k + 3);
    }
    planes &= faces_touched(old, box);
    while (planes && cnt > 0) {
        const int plane = __builtin_ctz(planes), axis = plane % 3, upper = plane >= 3;
        planes &= planes - 1;
        const double bound = box[plane];
        double (*const in)[3] = poly[cur], (*const out)[3] = poly[1 - cur];
        double dist[10];
        in[cnt][0] = in[0][0];
        in[cnt][1] = in[0][1];
        in[cnt][2] = in[0][2];
        for (int i = 0; i < cnt; ++i) dist[i] = upper ? bound - in[i][axis] : in[i][axis] - bound;
        dist[cnt] = dist[0];
        /* Every vertex and crossing is written; the count passes the kept
         * ones. */
        int outc = 0;
        for (int i = 0; i < cnt; ++i) {
            const double *p = in[i], *q = in[i + 1];
            const double dp = dist[i], dq = dist[i + 1];
            out[outc][0] = p[0];
            out[outc][1] = p[1];
            out[outc][2] = p[2];
            outc += dp >= 0;
            /* Divided by the difference only where the edge crosses (it is
             * nonzero there): an edge parallel to the plane would divide by
             * zero and leave the caller's floating-point flags raised. */
            const int cross = ((dp > 0) & (dq < 0)) | ((dp < 0) & (dq > 0));
            const double s = dp / select_double(cross, dp - dq, 1.0);
            double *r = out[outc];
            for (int k = 0; k < 3; ++k) r[k] = p[k] + s * (q[k] - p[k]);
            r[axis] = bound;
            outc += cross;
        }
        cnt = outc;
        cur = 1 - cur;
    }
    *count = cnt;
    return (const double (*)[3])poly[cur];
}

void kd_clipped_ref_plain(const kd_ref *old, const float box[6], const double *dlo, const double *dhi, kd_ref *out)
{
    for (int k = 0; k < 3; ++k) {
        float lo = old->lo[k] > box[k] ? old->lo[k] : box[k];
        float hi = old->hi[k] < box[k + 3] ? old->hi[k] : box[k + 3];
        if (dlo) {
            const float fl = round_down(dlo[k]), fh = round_up(dhi[k]);
            lo = select_float((fl > lo) & (fl <= hi), fl, lo);
            hi = select_float((fh < hi) & (fh >= lo), fh, hi);
        }
        out->lo[k] = lo;
        out->hi[k] = hi;
    }
    out->id = old->id;
}

#if defined(__SSE2__)
/* The plain form's steps, the three axes in the lanes of one vector (the
 * fourth lane is zero and unused): a third of its time, which was a fifth
 * of clipping's. */
static inline __m128 load3_zero_lanes(__m128 v) { return _mm_and_ps(v, _mm_castsi128_ps(_mm_set_epi32(0, -1, -1, -1))); }

/* x, y, z from p (which has a fourth float after them, inside its struct),
 * and a zero. */
static inline __m128 load3_zero(const float *p) { return load3_zero_lanes(_mm_loadu_ps(p)); }

/* d[0..2] converted to floats, and the lanes where the float is above
 * (*above) or below (*below) the double it came from. */
static inline __m128 floats_of(const double *d, __m128 *above, __m128 *below)
{
    const __m128d d01 = _mm_loadu_pd(d), d2 = _mm_load_sd(d + 2);
    const __m128 f01 = _mm_cvtpd_ps(d01), f2 = _mm_cvtpd_ps(d2);
    const __m128d b01 = _mm_cvtps_pd(f01), b2 = _mm_cvtps_pd(f2);
    /* The 64-bit masks' low halves make the 32-bit lanes. */
    *above = _mm_shuffle_ps(_mm_castpd_ps(_mm_cmpgt_pd(b01, d01)), _mm_castpd_ps(_mm_cmpgt_sd(b2, d2)),
                            _MM_SHUFFLE(2, 0, 2, 0));
    *below = _mm_shuffle_ps(_mm_castpd_ps(_mm_cmplt_pd(b01, d01)), _mm_castpd_ps(_mm_cmplt_sd(b2, d2)),
                            _MM_SHUFFLE(2, 0, 2, 0));
    return _mm_movelh_ps(f01, f2);
}

/* as_float_next_down in every lane. */
static inline __m128 next_down4(__m128 f)
{
    const __m128i u = _mm_castps_si128(f);
    const __m128i step = _mm_add_epi32(_mm_sub_epi32(u, _mm_set1_epi32(1)), _mm_slli_epi32(_mm_srli_epi32(u, 31), 1));
    const __m128i zero = _mm_cmpeq_epi32(_mm_slli_epi32(u, 1), _mm_setzero_si128());
    const __m128i minus_inf = _mm_cmpeq_epi32(u, _mm_set1_epi32((int)0xff800000u));
    __m128i r = _mm_andnot_si128(_mm_or_si128(zero, minus_inf), step);
    r = _mm_or_si128(r, _mm_and_si128(zero, _mm_set1_epi32((int)0x80000001u)));
    r = _mm_or_si128(r, _mm_and_si128(minus_inf, u));
    return _mm_castsi128_ps(r);
}

static inline __m128 next_up4(__m128 f)
{
    const __m128 sign = _mm_castsi128_ps(_mm_set1_epi32((int)0x80000000u));
    return _mm_xor_ps(next_down4(_mm_xor_ps(f, sign)), sign);
}

static inline __m128 select4(__m128 m, __m128 a, __m128 b) { return _mm_or_ps(_mm_and_ps(m, a), _mm_andnot_ps(m, b)); }

/* The clipped reference from old's box within `box`, narrowed to the
 * clipped triangle's bounds rounded out to floats (fl, fh; `clipped` 0 when
 * clipping left nothing): the steps every vector form shares. Returns the
 * events of old that the clipped reference keeps, clipped_keep's bits for
 * child 0, made from the bounds still in registers. */
static inline unsigned clipped_ref_finish(const kd_ref *old, const float box[6], int clipped, __m128 fl, __m128 fh,
                                          kd_ref *out)
{
    const __m128 old_lo = load3_zero(old->lo), old_hi = load3_zero(old->hi);
    __m128 lo = _mm_max_ps(old_lo, load3_zero(box));
    /* box[3..5] from the four floats ending there: box has six. */
    const __m128 box_hi = _mm_loadu_ps(box + 2);
    __m128 hi = _mm_min_ps(old_hi, load3_zero_lanes(_mm_shuffle_ps(box_hi, box_hi, _MM_SHUFFLE(3, 3, 2, 1))));
    if (clipped) {
        lo = select4(_mm_and_ps(_mm_cmpgt_ps(fl, lo), _mm_cmple_ps(fl, hi)), fl, lo);
        hi = select4(_mm_and_ps(_mm_cmplt_ps(fh, hi), _mm_cmpge_ps(fh, lo)), fh, hi);
    }
    float l[4], h[4];
    _mm_storeu_ps(l, lo);
    _mm_storeu_ps(h, hi);
    memcpy(out->lo, l, sizeof out->lo);
    memcpy(out->hi, h, sizeof out->hi);
    out->id = old->id;
    const __m128 old_flat = _mm_cmpeq_ps(old_lo, old_hi), now_flat = _mm_cmpeq_ps(lo, hi);
    const __m128 keep_lo = _mm_or_ps(old_flat, _mm_andnot_ps(now_flat, _mm_cmpeq_ps(lo, old_lo)));
    const __m128 keep_hi = _mm_andnot_ps(_mm_or_ps(old_flat, now_flat), _mm_cmpeq_ps(hi, old_hi));
    /* Axis a's two bits at 2a and 2a + 1. */
    static const uint8_t spread[8] = {0, 1, 4, 5, 16, 17, 20, 21};
    return (unsigned)spread[_mm_movemask_ps(keep_lo) & 7] | (unsigned)spread[_mm_movemask_ps(keep_hi) & 7] << 1;
}

void kd_clipped_ref_sse2(const kd_ref *old, const float box[6], const double *dlo, const double *dhi, kd_ref *out)
{
    __m128 fl = _mm_setzero_ps(), fh = _mm_setzero_ps();
    if (dlo) {
        __m128 above, below;
        const __m128 f = floats_of(dlo, &above, &below);
        fl = select4(above, next_down4(f), f);
        const __m128 g = floats_of(dhi, &above, &below);
        fh = select4(below, next_up4(g), g);
    }
    (void)clipped_ref_finish(old, box, dlo != NULL, fl, fh, out);
}
#endif

static inline void clipped_ref(const kd_ref *old, const float box[6], const double *dlo, const double *dhi, kd_ref *out)
{
#if defined(__SSE2__)
    kd_clipped_ref_sse2(old, box, dlo, dhi, out);
#else
    kd_clipped_ref_plain(old, box, dlo, dhi, out);
#endif
}

/* The box of triangle `old->id` clipped to `box`, intersected with `old`. */
static void clip_ref(const as_tri4_t *tris, const kd_ref *old, const float box[6], kd_ref *out)
{
    double poly[2][10][3];
    int cnt;
    const double (*v)[3] = clip_triangle(&tris[old->id], old, box, poly, &cnt);
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int i = 0; i < cnt; ++i)
        for (int k = 0; k < 3; ++k) {
            lo[k] = min_double(lo[k], v[i][k]);
            hi[k] = max_double(hi[k], v[i][k]);
        }
    clipped_ref(old, box, cnt ? lo : NULL, hi, out);
}

/* Both children's references of a triangle that crosses the split plane:
 * the triangle clipped once to the node's box, then that polygon's two
 * parts on either side of the plane bounded in one pass, the crossing
 * points shared. Each part is the one clip_ref gives for its child, the
 * planes taken in another order. */
static void clip_ref_split(const as_tri4_t *tris, const kd_ref *old, const float node_box[6], const float box[2][6],
                           int axis, float pos, kd_ref *out[2])
{
    double poly[2][10][3];
    int cnt;
    const double (*v)[3] = clip_triangle(&tris[old->id], old, node_box, poly, &cnt);
    double lo[2][3], hi[2][3];
    int below = 0, above = 0;
#if defined(__SSE2__)
    /* The plain loop's steps below, two coordinates per vector: (x, y) in
     * one, (z, unused) in the other. Selecting through integer masks, three
     * coordinates at a time, took most of this function's instructions. */
    const __m128d inf = _mm_set1_pd(INFINITY), ninf = _mm_set1_pd(-INFINITY), at = _mm_set1_pd((double)pos);
    const __m128d on_xy = _mm_castsi128_pd(_mm_set_epi64x(axis == 1 ? -1 : 0, axis == 0 ? -1 : 0));
    const __m128d on_z = _mm_castsi128_pd(_mm_set_epi64x(0, axis == 2 ? -1 : 0));
    __m128d lo0_xy = inf, lo0_z = inf, hi0_xy = ninf, hi0_z = ninf, lo1_xy = inf, lo1_z = inf, hi1_xy = ninf,
            hi1_z = ninf;
    for (int i = 0; i < cnt; ++i) {
        const double *p = v[i], *q = v[i + 1 < cnt ? i + 1 : 0];
        const double dp = p[axis] - pos, dq = q[axis] - pos;
        const int l = dp <= 0, r = dp >= 0, x = ((dp > 0) & (dq < 0)) | ((dp < 0) & (dq > 0));
        const double s = dp / select_double(x, dp - dq, 1.0); /* as in clip_triangle */
        const __m128d p_xy = _mm_loadu_pd(p), p_z = _mm_load_sd(p + 2), sv = _mm_set1_pd(s);
        __m128d c_xy = _mm_add_pd(p_xy, _mm_mul_pd(sv, _mm_sub_pd(_mm_loadu_pd(q), p_xy)));
        __m128d c_z = _mm_add_pd(p_z, _mm_mul_pd(sv, _mm_sub_pd(_mm_load_sd(q + 2), p_z)));
        c_xy = select2(on_xy, at, c_xy);
        c_z = select2(on_z, at, c_z);
        const __m128d xm = mask2(x), lm = mask2(l), rm = mask2(r);
        const __m128d cl_xy = select2(xm, c_xy, inf), cl_z = select2(xm, c_z, inf);
        const __m128d ch_xy = select2(xm, c_xy, ninf), ch_z = select2(xm, c_z, ninf);
        lo0_xy = _mm_min_pd(lo0_xy, _mm_min_pd(select2(lm, p_xy, inf), cl_xy));
        lo0_z = _mm_min_pd(lo0_z, _mm_min_pd(select2(lm, p_z, inf), cl_z));
        hi0_xy = _mm_max_pd(hi0_xy, _mm_max_pd(select2(lm, p_xy, ninf), ch_xy));
        hi0_z = _mm_max_pd(hi0_z, _mm_max_pd(select2(lm, p_z, ninf), ch_z));
        lo1_xy = _mm_min_pd(lo1_xy, _mm_min_pd(select2(rm, p_xy, inf), cl_xy));
        lo1_z = _mm_min_pd(lo1_z, _mm_min_pd(select2(rm, p_z, inf), cl_z));
        hi1_xy = _mm_max_pd(hi1_xy, _mm_max_pd(select2(rm, p_xy, ninf), ch_xy));
        hi1_z = _mm_max_pd(hi1_z, _mm_max_pd(select2(rm, p_z, ninf), ch_z));
        below |= l | x;
        above |= r | x;
    }
    _mm_storeu_pd(lo[0], lo0_xy);
    _mm_store_sd(lo[0] + 2, lo0_z);
    _mm_storeu_pd(hi[0], hi0_xy);
    _mm_store_sd(hi[0] + 2, hi0_z);
    _mm_storeu_pd(lo[1], lo1_xy);
    _mm_store_sd(lo[1] + 2, lo1_z);
    _mm_storeu_pd(hi[1], hi1_xy);
    _mm_store_sd(hi[1] + 2, hi1_z);
#else
    for (int k = 0; k < 3; ++k) lo[0][k] = lo[1][k] = INFINITY, hi[0][k] = hi[1][k] = -INFINITY;
    for (int i = 0; i < cnt; ++i) {
        const double *p = v[i], *q = v[i + 1 < cnt ? i + 1 : 0];
        const double dp = p[axis] - pos, dq = q[axis] - pos;
        const int l = dp <= 0, r = dp >= 0, x = ((dp > 0) & (dq < 0)) | ((dp < 0) & (dq > 0));
        const double s = dp / select_double(x, dp - dq, 1.0); /* as in clip_triangle */
        double c[3];
        for (int k = 0; k < 3; ++k) c[k] = p[k] + s * (q[k] - p[k]);
        c[axis] = pos;
        for (int k = 0; k < 3; ++k) {
            const double cl = select_double(x, c[k], INFINITY), ch = select_double(x, c[k], -INFINITY);
            lo[0][k] = min_double(lo[0][k], min_double(select_double(l, p[k], INFINITY), cl));
            hi[0][k] = max_double(hi[0][k], max_double(select_double(l, p[k], -INFINITY), ch));
            lo[1][k] = min_double(lo[1][k], min_double(select_double(r, p[k], INFINITY), cl));
            hi[1][k] = max_double(hi[1][k], max_double(select_double(r, p[k], -INFINITY), ch));
        }
        below |= l | x;
        above |= r | x;
    }
#endif
    clipped_ref(old, box[0], below ? lo[0] : NULL, hi[0], out[0]);
    clipped_ref(old, box[1], above ? lo[1] : NULL, hi[1], out[1]);
}

#if defined(__x86_64__) && defined(__GNUC__)
#define KD_CLIP_AVX2 1
#include <immintrin.h>

/* kd_clipped_ref_sse2 with the bounds in a vector of four doubles: the
 * same floats. */
__attribute__((target("avx2"))) static inline unsigned clipped_ref_avx2(const kd_ref *old, const float box[6], int clipped,
                                                                        __m256d dlo, __m256d dhi, kd_ref *out)
{
    __m128 fl = _mm_setzero_ps(), fh = _mm_setzero_ps();
    if (clipped) {
        /* The 64-bit compares' low halves make the 32-bit lanes. */
        const __m256i halves = _mm256_setr_epi32(0, 2, 4, 6, 0, 2, 4, 6);
        const __m128 f = _mm256_cvtpd_ps(dlo), g = _mm256_cvtpd_ps(dhi);
        const __m128 above = _mm256_castps256_ps128(_mm256_permutevar8x32_ps(
            _mm256_castpd_ps(_mm256_cmp_pd(_mm256_cvtps_pd(f), dlo, _CMP_GT_OQ)), halves));
        const __m128 below = _mm256_castps256_ps128(_mm256_permutevar8x32_ps(
            _mm256_castpd_ps(_mm256_cmp_pd(_mm256_cvtps_pd(g), dhi, _CMP_LT_OQ)), halves));
        fl = select4(above, next_down4(f), f);
        fh = select4(below, next_up4(g), g);
    }
    return clipped_ref_finish(old, box, clipped, fl, fh, out);
}

/* A mask of the lane of one axis, per axis. */
static const int64_t clip_axis_lane[3][4] = {{-1, 0, 0, 0}, {0, -1, 0, 0}, {0, 0, -1, 0}};

/* clip_triangle with each vertex in one vector of four doubles (x, y, z,
 * and a zero), on processors with AVX2: the same operations in the same
 * order (no fused multiply-add), so the same bits, in about half the
 * instructions of two vectors per vertex. The polygon is in poly[*cur], its
 * first vertex repeated after the last; returns its vertex count. */
__attribute__((target("avx2"), always_inline)) static inline int clip_triangle_avx2(const as_tri4_t *t, const kd_ref *old, const float box[6],
                                                              double poly[2][10][4], int *cur_out)
{
    /* The fourth float (an index's bits in v0) is not converted: it may
     * read as a signaling NaN. */
    const __m128 xyz = _mm_castsi128_ps(_mm_setr_epi32(-1, -1, -1, 0));
    const __m256d v0 = _mm256_cvtps_pd(_mm_and_ps(_mm_loadu_ps(&t->v0.x), xyz));
    const __m256d v1 = _mm256_cvtps_pd(_mm_and_ps(_mm_loadu_ps(&t->v1.x), xyz));
    const __m256d v2 = _mm256_cvtps_pd(_mm_and_ps(_mm_loadu_ps(&t->v2.x), xyz));
    _mm256_store_pd(poly[0][0], v0);
    _mm256_store_pd(poly[0][1], v1);
    _mm256_store_pd(poly[0][2], v2);
    /* Only planes that some vertex is outside of. */
    const __m256d box_lo = _mm256_cvtps_pd(_mm_setr_ps(box[0], box[1], box[2], 0.0f));
    const __m256d box_hi = _mm256_cvtps_pd(_mm_setr_ps(box[3], box[4], box[5], 0.0f));
    const __m256d lo = _mm256_min_pd(_mm256_min_pd(v0, v1), v2), hi = _mm256_max_pd(_mm256_max_pd(v0, v1), v2);
    unsigned planes = ((unsigned)_mm256_movemask_pd(_mm256_cmp_pd(lo, box_lo, _CMP_LT_OQ)) & 7u) |
                      (((unsigned)_mm256_movemask_pd(_mm256_cmp_pd(hi, box_hi, _CMP_GT_OQ)) & 7u) << 3);
    planes &= faces_touched(old, box);
    int cnt = 3, cur = 0;
    while (planes && cnt > 0) {
        const int plane = __builtin_ctz(planes), pa = plane % 3, upper = plane >= 3;
        planes &= planes - 1;
        const double bound = box[plane];
        double (*const in)[4] = poly[cur], (*const o)[4] = poly[1 - cur];
        _mm256_store_pd(in[cnt], _mm256_load_pd(in[0]));
        double dist[10];
        for (int i = 0; i < cnt; ++i) dist[i] = upper ? bound - in[i][pa] : in[i][pa] - bound;
        dist[cnt] = dist[0];
        const __m256d on_axis = _mm256_castsi256_pd(_mm256_loadu_si256((const __m256i *)clip_axis_lane[pa]));
        const __m256d at = _mm256_set1_pd(bound);
        int outc = 0;
        for (int i = 0; i < cnt; ++i) {
            const __m256d p = _mm256_load_pd(in[i]), q = _mm256_load_pd(in[i + 1]);
            const double dp = dist[i], dq = dist[i + 1];
            _mm256_store_pd(o[outc], p);
            outc += dp >= 0;
            const int cross = ((dp > 0) & (dq < 0)) | ((dp < 0) & (dq > 0));
            const double s = dp / select_double(cross, dp - dq, 1.0);
            const __m256d r = _mm256_add_pd(p, _mm256_mul_pd(_mm256_set1_pd(s), _mm256_sub_pd(q, p)));
            _mm256_store_pd(o[outc], _mm256_blendv_pd(r, at, on_axis));
            outc += cross;
        }
        cnt = outc;
        cur = 1 - cur;
    }
    _mm256_store_pd(poly[cur][cnt], _mm256_load_pd(poly[cur][0]));
    *cur_out = cur;
    return cnt;
}

/* clip_ref in the AVX2 form; returns clipped_keep's bits for child 0. */
__attribute__((target("avx2"))) static unsigned clip_ref_avx2(const as_tri4_t *tris, const kd_ref *old, const float box[6],
                                                              kd_ref *out)
{
    _Alignas(32) double poly[2][10][4];
    int cur;
    const int cnt = clip_triangle_avx2(&tris[old->id], old, box, poly, &cur);
    __m256d lo = _mm256_set1_pd(INFINITY), hi = _mm256_set1_pd(-INFINITY);
    for (int i = 0; i < cnt; ++i) {
        const __m256d p = _mm256_load_pd(poly[cur][i]);
        lo = _mm256_min_pd(lo, p);
        hi = _mm256_max_pd(hi, p);
    }
    return clipped_ref_avx2(old, box, cnt != 0, lo, hi, out);
}

/* clip_ref_split in the AVX2 form, with clipped_keep's bits of each child
 * (for child 0) in keep. */
__attribute__((target("avx2"))) static void clip_ref_split_avx2(const as_tri4_t *tris, const kd_ref *old,
                                                                const float node_box[6], const float box[2][6], int axis,
                                                                float pos, kd_ref *out[2], unsigned keep[2])
{
    _Alignas(32) double poly[2][10][4];
    int cur;
    const int cnt = clip_triangle_avx2(&tris[old->id], old, node_box, poly, &cur);
    /* The polygon's parts on either side of the split plane. */
    double (*const v)[4] = poly[cur];
    const __m256d inf = _mm256_set1_pd(INFINITY), ninf = _mm256_set1_pd(-INFINITY), at = _mm256_set1_pd((double)pos);
    const __m256d on_axis = _mm256_castsi256_pd(_mm256_loadu_si256((const __m256i *)clip_axis_lane[axis]));
    __m256d lo0 = inf, hi0 = ninf, lo1 = inf, hi1 = ninf;
    int below = 0, above = 0;
    for (int i = 0; i < cnt; ++i) {
        const __m256d p = _mm256_load_pd(v[i]), q = _mm256_load_pd(v[i + 1]);
        const double dp = v[i][axis] - pos, dq = v[i + 1][axis] - pos;
        const int l = dp <= 0, r = dp >= 0, x = ((dp > 0) & (dq < 0)) | ((dp < 0) & (dq > 0));
        const double s = dp / select_double(x, dp - dq, 1.0);
        const __m256d c = _mm256_blendv_pd(_mm256_add_pd(p, _mm256_mul_pd(_mm256_set1_pd(s), _mm256_sub_pd(q, p))), at, on_axis);
        const __m256d xm = _mm256_castsi256_pd(_mm256_set1_epi64x(-(long long)x));
        const __m256d lm = _mm256_castsi256_pd(_mm256_set1_epi64x(-(long long)l));
        const __m256d rm = _mm256_castsi256_pd(_mm256_set1_epi64x(-(long long)r));
        const __m256d cl = _mm256_blendv_pd(inf, c, xm), ch = _mm256_blendv_pd(ninf, c, xm);
        lo0 = _mm256_min_pd(lo0, _mm256_min_pd(_mm256_blendv_pd(inf, p, lm), cl));
        hi0 = _mm256_max_pd(hi0, _mm256_max_pd(_mm256_blendv_pd(ninf, p, lm), ch));
        lo1 = _mm256_min_pd(lo1, _mm256_min_pd(_mm256_blendv_pd(inf, p, rm), cl));
        hi1 = _mm256_max_pd(hi1, _mm256_max_pd(_mm256_blendv_pd(ninf, p, rm), ch));
        below |= l | x;
        above |= r | x;
    }
    keep[0] = clipped_ref_avx2(old, box[0], below, lo0, hi0, out[0]);
    keep[1] = clipped_ref_avx2(old, box[1], above, lo1, hi1, out[1]);
}
#endif

/* The events of `old` that a clipped reference `now` keeps, as child 0's
 * bits (child 1's are these shifted by six): a bound that clipping did not
 * move keeps its event, unless the box became flat along the axis (its one
 * event is then a new PLANAR one). A flat box stays flat and where it was.
 * The vector forms make the same bits as they clip (clipped_ref_finish). */
static unsigned clipped_keep(const kd_ref *old, const kd_ref *now)
{
    unsigned keep = 0;
    for (int a = 0; a < 3; ++a) {
        if (old->lo[a] == old->hi[a]) {
            keep |= KD_KEEP_BIT(0, a, 0);
        } else if (now->lo[a] != now->hi[a]) {
            if (now->lo[a] == old->lo[a]) keep |= KD_KEEP_BIT(0, a, 0);
            if (now->hi[a] == old->hi[a]) keep |= KD_KEEP_BIT(0, a, 1);
        }
    }
    return keep;
}

/* A reference clipped to box, in the fastest form this processor has;
 * returns clipped_keep's bits for child 0. */
static unsigned clip_ref_fastest(const as_tri4_t *tris, const kd_ref *old, const float box[6], kd_ref *out)
{
#if defined(KD_CLIP_AVX2)
    if (as_cpu_has_avx2()) return clip_ref_avx2(tris, old, box, out);
#endif
    clip_ref(tris, old, box, out);
    return clipped_keep(old, out);
}

/* Both children's references of a crossing triangle, in the fastest form
 * this processor has, with clipped_keep's bits of each (for child 0). */
static void clip_ref_split_fastest(const as_tri4_t *tris, const kd_ref *old, const float node_box[6],
                                   const float box[2][6], int axis, float pos, kd_ref *out[2], unsigned keep[2])
{
#if defined(KD_CLIP_AVX2)
    if (as_cpu_has_avx2()) {
        clip_ref_split_avx2(tris, old, node_box, box, axis, pos, out, keep);
        return;
    }
#endif
    clip_ref_split(tris, old, node_box, box, axis, pos, out);
    keep[0] = clipped_keep(old, out[0]);
    keep[1] = clipped_keep(old, out[1]);
}

void kd_clip_reference(const as_tri4_t *tris, const kd_ref *old, const float box[6], kd_ref *out)
{
    (void)clip_ref_fastest(tris, old, box, out);
}

void kd_clip_reference_portable(const as_tri4_t *tris, const kd_ref *old, const float box[6], kd_ref *out)
{
    clip_ref(tris, old, box, out);
}

static void clip_reference_split(const as_tri4_t *tris, const kd_ref *old, const float node_box[6], int axis, float pos,
                                 kd_ref out[2], int fastest)
{
    float box[2][6];
    memcpy(box[0], node_box, sizeof box[0]);
    memcpy(box[1], node_box, sizeof box[1]);
    box[0][axis + 3] = pos;
    box[1][axis] = pos;
    kd_ref *outs[2] = {&out[0], &out[1]};
    unsigned keep[2];
    if (fastest) clip_ref_split_fastest(tris, old, node_box, (const float(*)[6])box, axis, pos, outs, keep);
    else clip_ref_split(tris, old, node_box, (const float(*)[6])box, axis, pos, outs);
}

void kd_clip_reference_split(const as_tri4_t *tris, const kd_ref *old, const float node_box[6], int axis, float pos,
                             kd_ref out[2])
{
    clip_reference_split(tris, old, node_box, axis, pos, out, 1);
}

void kd_clip_reference_split_portable(const as_tri4_t *tris, const kd_ref *old, const float node_box[6], int axis,
                                      float pos, kd_ref out[2])
{
    clip_reference_split(tris, old, node_box, axis, pos, out, 0);
}

/* A subtree to build: the node's references, the builder's data, its box,
 * and where the finished subtree goes (its parent's child pointer). */
typedef struct kd_task {
    kd_ref *refs;
    uint32_t n;
    int pooled;        /* refs came from refs_take */
    void *state;
    float box[6];
    uint32_t depth;
    double share, weight;
    kd_tmp **slot;
} kd_task;

static int goes_left(const kd_ref *r, const kd_split *s)
{
    const float lo = r->lo[s->axis], hi = r->hi[s->axis];
    if (lo == hi && lo == s->pos) return s->planar_left;
    return lo <= s->pos;
}

static int goes_right(const kd_ref *r, const kd_split *s)
{
    const float lo = r->lo[s->axis], hi = r->hi[s->axis];
    if (lo == hi && lo == s->pos) return !s->planar_left;
    return hi >= s->pos;
}

/* Where a node's references go: both children's arrays, the indices of
 * the clipped ones in them, and for the SAH builder a byte per triangle
 * saying which of its events each child keeps (KD_KEEP_*). */
typedef struct kd_partition {
    const kd_ctx *c;
    const kd_ref *refs;
    const kd_split *sp;
    kd_ref *out[2];
    uint32_t at[2], clipped_at[2]; /* the whole node's counts, after partition_range or partition_fill_chunks */
    uint32_t *clipped[2];          /* NULL: not recorded */
    uint16_t *side;                /* NULL: not recorded */
    uint32_t n;
    unsigned chunks;
    float node_box[6], box[2][6];
    /* partition_count_chunks: each chunk's counts, then where it writes. */
    uint32_t (*chunk_at)[4];
} kd_partition;

/* References [begin, end) into the children, from at[] and clipped_at[]
 * on; the counts are advanced. */
static void partition_range(kd_partition *p, uint32_t begin, uint32_t end, uint32_t at_io[2], uint32_t clipped_at_io[2])
{
    /* The split and the counts in locals: the stores into the children's
     * arrays could alias them, and the compiler would reload them. */
    const kd_split *sp = p->sp;
    const int axis = sp->axis, planar_left = sp->planar_left;
    const float pos = sp->pos;
    const kd_ref *const refs = p->refs;
    kd_ref *const o0 = p->out[0], *const o1 = p->out[1];
    uint16_t *const side = p->side;
    uint32_t at[2] = {at_io[0], at_io[1]}, clipped_at[2] = {clipped_at_io[0], clipped_at_io[1]};
    for (uint32_t i = begin; i < end; ++i) {
        const kd_ref *r = &refs[i];
        const float lo = r->lo[axis], hi = r->hi[axis];
        unsigned keep = 0;
        if (lo < pos && hi > pos) {
            kd_ref *out[2] = {&o0[at[0]], &o1[at[1]]};
            unsigned kept[2];
            clip_ref_split_fastest(p->c->tris, r, p->node_box, p->box, axis, pos, out, kept);
            keep = kept[0] | kept[1] << 6;
            for (int s = 0; s < 2; ++s) {
                if (p->clipped[s]) p->clipped[s][clipped_at[s]] = at[s];
                ++clipped_at[s];
                ++at[s];
            }
            if (side) side[r->id] = (uint16_t)keep;
            continue;
        }
        /* goes_left and goes_right. */
        const int in_plane = lo == hi && lo == pos;
        const int l = in_plane ? planar_left : lo <= pos, rt = in_plane ? !planar_left : hi >= pos;
        if (!((l && hi > pos) || (rt && lo < pos))) {
            /* Not clipped: copied where it goes. */
            if (l) o0[at[0]++] = *r;
            if (rt) o1[at[1]++] = *r;
            if (side) side[r->id] = (uint16_t)((l ? KD_KEEP_SIDE(0) : 0u) | (rt ? KD_KEEP_SIDE(1) : 0u));
            continue;
        }
        /* Touching the plane from one side (a bound in it): that side's
         * copy is clipped to a flat box, the other side's is not. */
        for (int s = 0; s < 2; ++s) {
            if (!(s ? rt : l)) continue;
            kd_ref *out = s ? &o1[at[1]] : &o0[at[0]];
            if (s ? lo < pos : hi > pos) {
                keep |= clip_ref_fastest(p->c->tris, r, p->box[s], out) << (6 * s);
                if (p->clipped[s]) p->clipped[s][clipped_at[s]] = at[s];
                ++clipped_at[s];
            } else {
                *out = *r;
                keep |= KD_KEEP_SIDE(s);
            }
            ++at[s];
        }
        if (side) side[r->id] = (uint16_t)keep;
    }
    at_io[0] = at[0];
    at_io[1] = at[1];
    clipped_at_io[0] = clipped_at[0];
    clipped_at_io[1] = clipped_at[1];
}

/* A big node's partition on the build's threads: contiguous chunks, each
 * counted (which also gives the children's sizes), then each written from
 * where the chunks before it end, so the children's arrays are those of one
 * pass. */
static unsigned partition_chunks(const kd_ctx *c, uint32_t n)
{
    const unsigned threads = as_thread_count(c->args->thread_count);
    if (threads < 2 || n < PARTITION_MIN_REFS) return 1;
    unsigned chunks = threads * 2;
    if (chunks > KD_PARTITION_CHUNKS) chunks = KD_PARTITION_CHUNKS;
    return chunks;
}

static void partition_count_chunk(void *user, unsigned i, unsigned n)
{
    kd_partition *p = user;
    (void)n;
    const kd_split *sp = p->sp;
    uint32_t begin, end, nl = 0, nr = 0, cl = 0, cr = 0;
    as_chunk_range(p->n, i, p->chunks, &begin, &end);
    for (uint32_t k = begin; k < end; ++k) {
        const kd_ref *r = &p->refs[k];
        const unsigned l = (unsigned)goes_left(r, sp), rt = (unsigned)goes_right(r, sp);
        nl += l;
        nr += rt;
        cl += l & (r->hi[sp->axis] > sp->pos);
        cr += rt & (r->lo[sp->axis] < sp->pos);
    }
    p->chunk_at[i][0] = nl;
    p->chunk_at[i][1] = nr;
    p->chunk_at[i][2] = cl;
    p->chunk_at[i][3] = cr;
}

static void partition_fill_chunk(void *user, unsigned i, unsigned n)
{
    kd_partition *p = user;
    (void)n;
    uint32_t begin, end;
    as_chunk_range(p->n, i, p->chunks, &begin, &end);
    uint32_t at[2] = {p->chunk_at[i][0], p->chunk_at[i][1]}, clipped_at[2] = {p->chunk_at[i][2], p->chunk_at[i][3]};
    partition_range(p, begin, end, at, clipped_at);
}

/* The chunks' counts (chunk_at has room for `chunks`), and the node's sums:
 * the references going left and right. */
static void partition_count_chunks(kd_partition *p, uint32_t n, unsigned chunks, uint32_t (*chunk_at)[4],
                                   uint32_t *nl, uint32_t *nr)
{
    p->n = n;
    p->chunks = chunks;
    p->chunk_at = chunk_at;
    as_parallel_run(chunks, partition_count_chunk, p);
    *nl = *nr = 0;
    for (unsigned i = 0; i < chunks; ++i) {
        *nl += chunk_at[i][0];
        *nr += chunk_at[i][1];
    }
}

/* After partition_count_chunks: each chunk written from where the chunks
 * before it end. */
static void partition_fill_chunks(kd_partition *p)
{
    uint32_t sum[4] = {0, 0, 0, 0};
    for (unsigned i = 0; i < p->chunks; ++i)
        for (int k = 0; k < 4; ++k) {
            const uint32_t v = p->chunk_at[i][k];
            p->chunk_at[i][k] = sum[k];
            sum[k] += v;
        }
    as_parallel_run(p->chunks, partition_fill_chunk, p);
    p->at[0] = sum[0];
    p->at[1] = sum[1];
    p->clipped_at[0] = sum[2];
    p->clipped_at[1] = sum[3];
}

/* Hands the oldest right child this task has not started to a waiting
 * thread, if one waits (task_pool.h). */
static void offer_pending(as_task_pool *pool, kd_scratch *sc)
{
    as_pending *p = as_pending_next_offer(pool, &sc->pending);
    if (p) p->given = as_task_pool_push(pool, p->task);
}

/* Builds the subtree of task t: recurses into the left child and loops on
 * the right one, and hands the right child to an idle thread when it is big
 * enough to be worth it. */
static void build_subtree(as_task_pool *pool, kd_run *run, kd_scratch *sc, kd_task t)
{
    const kd_ctx *c = run->c;
    const kd_builder_ops *ops = c->ops;
    for (;;) {
        offer_pending(pool, sc);
        kd_ref *const refs = t.refs;
        const uint32_t n = t.n;
        const float *const box = t.box;
        kd_split sp;
        if (atomic_load(&run->cancelled) || atomic_load(&run->oom) || n == 0 || t.depth >= c->max_depth ||
            !ops->choose(c, t.state, refs, n, box, t.depth, &sp) ||
            !(sp.pos > box[sp.axis] && sp.pos < box[sp.axis + 3])) {
            *t.slot = make_leaf(run, sc, refs, n, t.pooled, t.state, t.depth, t.weight);
            return;
        }
        /* Where the references go, counted once: a big node's chunks are
         * counted on every thread and filled from those counts; the SAH
         * sweep's plane comes with its counts. */
        kd_partition part = {.c = c, .refs = refs, .sp = &sp};
        uint32_t nl = 0, nr = 0;
        const unsigned chunks = partition_chunks(c, n);
        uint32_t(*chunk_at)[4] = chunks > 1 ? malloc(sizeof *chunk_at * chunks) : NULL;
        if (chunk_at) {
            partition_count_chunks(&part, n, chunks, chunk_at, &nl, &nr);
        } else if (sp.counted) {
            nl = sp.count[0];
            nr = sp.count[1];
        } else {
            for (uint32_t i = 0; i < n; ++i) {
                nl += (uint32_t)goes_left(&refs[i], &sp);
                nr += (uint32_t)goes_right(&refs[i], &sp);
            }
        }
        if ((nl == n && nr == n) || (double)nl + (double)nr > t.share) {
            free(chunk_at);
            *t.slot = make_leaf(run, sc, refs, n, t.pooled, t.state, t.depth, t.weight);
            return;
        }
        kd_ref *lr = refs_take(sc, nl), *rr = refs_take(sc, nr);
        /* A node without lists (a small one) has none to hand down: its
         * partition need not note the sides and clipped references. */
        const int hand_down = ops->child_states != NULL && t.state != NULL;
        kd_tmp *node = new_tmp(run, sc);
        if (!lr || !rr || !node || (hand_down && !scratch_clipped_room(sc, n))) {
            free(chunk_at);
            refs_give(sc, lr, nl, 1);
            refs_give(sc, rr, nr, 1);
            atomic_store(&run->oom, 1);
            *t.slot = make_leaf(run, sc, refs, n, t.pooled, t.state, t.depth, t.weight);
            return;
        }
        part.out[0] = lr;
        part.out[1] = rr;
        part.side = hand_down ? sc->side : NULL;
        memcpy(part.node_box, box, sizeof part.node_box);
        /* Each child's box copied from the node's, then its plane set (here
         * and for the tasks below): a copy of a box just written a float at
         * a time would wait for those stores. */
        memcpy(part.box[0], box, sizeof part.box[0]);
        memcpy(part.box[1], box, sizeof part.box[1]);
        part.box[0][sp.axis + 3] = sp.pos;
        part.box[1][sp.axis] = sp.pos;
        if (hand_down) {
            part.clipped[0] = sc->clipped[0];
            part.clipped[1] = sc->clipped[1];
        }
        if (chunk_at) {
            partition_fill_chunks(&part);
            free(chunk_at);
        } else {
            partition_range(&part, 0, n, part.at, part.clipped_at);
        }
        const uint32_t cl = part.clipped_at[0], cr = part.clipped_at[1];
        void *child_state[2] = {NULL, NULL};
        if (hand_down) {
            const kd_ref *const child_refs[2] = {lr, rr};
            const uint32_t child_n[2] = {nl, nr};
            sc->clipped_n[0] = cl;
            sc->clipped_n[1] = cr;
            if (!ops->child_states(c, t.state, sc, n, child_refs, child_n, child_state)) atomic_store(&run->oom, 1);
        }
        free_state(run, t.state);
        refs_give(sc, refs, n, t.pooled);
        node->axis = sp.axis;
        node->pos = sp.pos;
        *t.slot = node;
        sc->inner++;
        const double fl = (double)nl / ((double)nl + (double)nr);
        kd_task lt = {lr, nl, 1, child_state[0], {0}, t.depth + 1, t.share * fl, t.weight * fl, &node->child[0]};
        kd_task rt = {rr, nr, 1, child_state[1], {0}, t.depth + 1, t.share * (1.0 - fl), t.weight * (1.0 - fl),
                      &node->child[1]};
        memcpy(lt.box, box, sizeof lt.box);
        memcpy(rt.box, box, sizeof rt.box);
        lt.box[sp.axis + 3] = sp.pos;
        rt.box[sp.axis] = sp.pos;
        if (pool && nr >= PARALLEL_MIN_REFS && as_task_pool_hungry(pool) && as_task_pool_push(pool, &rt)) {
            t = lt;
            continue;
        }
        /* Kept: offered again while the left subtree is built. */
        as_pending rp = {&rt, 0};
        const int tracked = pool && nr >= PARALLEL_MIN_REFS && as_pending_push(&sc->pending, &rp);
        build_subtree(pool, run, sc, lt);
        if (tracked) as_pending_pop(&sc->pending);
        if (rp.given) return;
        t = rt;
    }
}

static void build_task(as_task_pool *pool, void *task, void *user)
{
    kd_run *run = user;
    kd_task t;
    memcpy(&t, task, sizeof t);
    kd_scratch *sc = scratch_get(run);
    if (!sc) {
        atomic_store(&run->oom, 1);
        free_state(run, t.state);
        if (!t.pooled || t.n > SMALL_REFS) as_temp_give(t.refs); /* else in an arena, freed after the build */
        return;
    }
    build_subtree(pool, run, sc, t);
    if (sc->unreported > 0.0) {
        report(run, sc->unreported);
        sc->unreported = 0.0;
    }
    scratch_put(run, sc);
}

typedef struct kd_counts {
    uint64_t nodes, inner, leaves, empty, refs;
    uint32_t max_depth;
} kd_counts;

typedef struct kd_emit {
    as_kd_node_t *nodes;
    uint32_t *prim;
    uint64_t node_next, prim_next;
    uint32_t leaf_next;
    double ct, ci, root_area;
    as_sah_sum sah;                /* the SAH cost, summed as as_kd_sah_cost sums it */
    double *terms;                 /* or each node's term by its index (pre-order), NULL: summed */
} kd_emit;

static void emit_term(kd_emit *e, uint64_t me, double term)
{
    if (e->terms) e->terms[me] = term;
    else as_sah_sum_add(&e->sah, term);
}

/* The write on several threads. The tree is cut at one depth, chosen so
 * that it holds about 64 subtrees per thread (or at the leaves above it);
 * each subtree's size (nodes, PRIM entries, leaves) is counted on every
 * thread, fixing where its nodes, entries and leaf numbers go whatever is in
 * it; the nodes above the cut are written on one thread, the subtrees on
 * every thread, and the SAH terms, stored by node index (which is the
 * pre-order position), added in that order afterwards: the bytes and the
 * sum of one walk. */
typedef struct kd_emit_part {
    const kd_tmp *t;
    float box[6];
    uint64_t nodes, prims;     /* the subtree's size */
    uint32_t leaves;
    uint64_t node_at, prim_at; /* where it goes */
    uint32_t leaf_at;
    int bad;
} kd_emit_part;

typedef struct kd_emit_plan {
    uint32_t cut;              /* the depth of the subtrees' roots */
    kd_emit_part *parts;
    size_t count, capacity;
    size_t next;               /* the top walk: the next part it meets */
} kd_emit_plan;

/* Writes the subtree of t (box `box`) in preorder, the left child first, and
 * adds its SAH cost in that order: the sum as_kd_sah_cost makes from the
 * written tree, bit for bit, without walking it again. With a plan (the top
 * of a write on several threads) a part's subtree is not written: it gets
 * its box and its places, in the order plan_parts listed the parts. */
static void emit(const kd_tmp *t, const float box[6], kd_emit *e, kd_emit_plan *p)
{
    if (p && p->next < p->count && p->parts[p->next].t == t) {
        kd_emit_part *k = &p->parts[p->next++];
        memcpy(k->box, box, sizeof k->box);
        k->node_at = e->node_next;
        k->prim_at = e->prim_next;
        k->leaf_at = e->leaf_next;
        e->node_next += k->nodes;
        e->prim_next += k->prims;
        e->leaf_next += k->leaves;
        return;
    }
    const uint64_t me = e->node_next++;
    const double ratio = e->root_area > 0 ? as_spatial_half_area(box, box + 3) / e->root_area : 1.0;
    if (!t->child[0]) {
        emit_term(e, me, e->ci * t->count * ratio);
        e->nodes[me].word0 = (uint32_t)e->prim_next;
        e->nodes[me].word1 = (e->leaf_next++ << 2) | AS_KD_LEAF_TAG;
        e->prim[e->prim_next++] = t->count;
        if (t->count) memcpy(e->prim + e->prim_next, t->ids, sizeof(uint32_t) * t->count); /* ids may be NULL */
        e->prim_next += t->count;
        return;
    }
    emit_term(e, me, e->ct * ratio);
    float child_box[6];
    memcpy(child_box, box, sizeof child_box);
    child_box[t->axis + 3] = t->pos;
    emit(t->child[0], child_box, e, p);
    e->nodes[me].word0 = as_float_as_uint(t->pos);
    e->nodes[me].word1 = ((uint32_t)e->node_next << 2) | (uint32_t)t->axis;
    child_box[t->axis + 3] = box[t->axis + 3];
    child_box[t->axis] = t->pos;
    emit(t->child[1], child_box, e, p);
}

static void subtree_size(const kd_tmp *t, kd_emit_part *p)
{
    if (!t->child[0]) {
        p->nodes++;
        p->prims += 1 + (uint64_t)t->count;
        p->leaves++;
        return;
    }
    p->nodes++;
    subtree_size(t->child[0], p);
    subtree_size(t->child[1], p);
}

/* The subtrees at the cut, and the leaves above it, in pre-order; 0 when
 * the list cannot grow. */
static int plan_parts(kd_emit_plan *p, const kd_tmp *t, uint32_t depth)
{
    if (!t->child[0] || depth == p->cut) {
        if (p->count == p->capacity) {
            const size_t cap = p->capacity ? 2 * p->capacity : 256;
            kd_emit_part *grown = realloc(p->parts, sizeof *grown * cap);
            if (!grown) return 0;
            p->parts = grown;
            p->capacity = cap;
        }
        memset(&p->parts[p->count], 0, sizeof p->parts[0]);
        p->parts[p->count++].t = t;
        return 1;
    }
    return plan_parts(p, t->child[0], depth + 1) && plan_parts(p, t->child[1], depth + 1);
}

typedef struct kd_emit_job {
    const kd_emit *top;
    kd_emit_plan *plan;
} kd_emit_job;

static void part_size(void *user, size_t i)
{
    kd_emit_job *j = user;
    subtree_size(j->plan->parts[i].t, &j->plan->parts[i]);
}

static void part_emit(void *user, size_t i)
{
    kd_emit_job *j = user;
    kd_emit_part *k = &j->plan->parts[i];
    kd_emit e = *j->top;
    e.node_next = k->node_at;
    e.prim_next = k->prim_at;
    e.leaf_next = k->leaf_at;
    emit(k->t, k->box, &e, NULL);
    k->bad = e.node_next != k->node_at + k->nodes || e.prim_next != k->prim_at + k->prims ||
             e.leaf_next != k->leaf_at + k->leaves;
}

/* Trees of fewer nodes than this are written on one thread. */
#define EMIT_MT_MIN_NODES 16384

/* Subtrees at the cut and leaves above it under t, counting stops once it
 * reaches `limit`. */
static size_t parts_at(const kd_tmp *t, uint32_t depth, uint32_t cut, size_t limit)
{
    if (!t->child[0] || depth == cut) return 1;
    const size_t left = parts_at(t->child[0], depth + 1, cut, limit);
    return left >= limit ? left : left + parts_at(t->child[1], depth + 1, cut, limit - left);
}

/* Writes the tree of `nodes` nodes under root into e; 0 when the sizes
 * counted disagree with what was written. */
static int emit_tree(const kd_tmp *root, const float box[6], kd_emit *e, uint64_t nodes, unsigned threads)
{
    kd_emit_plan p = {0, NULL, 0, 0, 0};
    if (threads > 1 && nodes >= EMIT_MT_MIN_NODES) {
        /* The first depth at which the tree holds 64 parts per thread, at
         * most 24 deep (a run of empty-space cuts near the root adds a level
         * and a part each). */
        const size_t want = 64 * (size_t)threads;
        p.cut = 1;
        while (p.cut < 24 && parts_at(root, 0, p.cut, want) < want) p.cut++;
        e->terms = as_temp_take(sizeof(double) * nodes, "KD SAH terms");
        if (!e->terms || !plan_parts(&p, root, 0)) {
            as_temp_give(e->terms);
            e->terms = NULL;
        }
    }
    if (!e->terms) {
        free(p.parts);
        emit(root, box, e, NULL);
        return e->node_next == nodes;
    }
    kd_emit_job j = {e, &p};
    as_parallel_for(threads, p.count, part_size, &j);
    emit(root, box, e, &p);
    int ok = p.next == p.count && e->node_next == nodes;
    if (ok) as_parallel_for(threads, p.count, part_emit, &j);
    for (size_t i = 0; ok && i < p.count; ++i) ok = !p.parts[i].bad;
    if (ok) e->sah = as_sah_sum_terms(e->terms, nodes, threads);
    as_temp_give(e->terms);
    e->terms = NULL;
    free(p.parts);
    return ok;
}

#define KD_INIT_CHUNKS 256

typedef struct kd_init_job {
    const as_mesh_t *mesh;
    kd_ref *refs;
    unsigned chunks;
    uint32_t offset[KD_INIT_CHUNKS];
    float box[KD_INIT_CHUNKS][6];
} kd_init_job;

/* Minimum and maximum of finite values without libm's call; of +0 and -0
 * the second, as the minss and maxss instructions (and x86-64's fminf and
 * fmaxf) give. */
static float min2(float a, float b) { return a < b ? a : b; }
static float max2(float a, float b) { return a > b ? a : b; }

static void init_fill(void *user, unsigned ch, unsigned chunks)
{
    kd_init_job *job = user;
    const as_mesh_t *mesh = job->mesh;
    uint32_t first, end, k = job->offset[ch];
    as_chunk_range(mesh->triangle_count, ch, chunks, &first, &end);
    float box[6] = {FLT_MAX, FLT_MAX, FLT_MAX, -FLT_MAX, -FLT_MAX, -FLT_MAX};
    for (uint32_t i = first; i < end; ++i) {
        if (as_mesh_triangle_is_degenerate(mesh, i)) continue;
        const uint32_t *ix = mesh->indices + 3 * (size_t)i;
        const float *v[3] = {mesh->positions + 3 * (size_t)ix[0], mesh->positions + 3 * (size_t)ix[1],
                             mesh->positions + 3 * (size_t)ix[2]};
        kd_ref *r = &job->refs[k++];
        r->id = i;
        for (int a = 0; a < 3; ++a) {
            r->lo[a] = min2(v[0][a], min2(v[1][a], v[2][a]));
            r->hi[a] = max2(v[0][a], max2(v[1][a], v[2][a]));
            if (r->lo[a] < box[a]) box[a] = r->lo[a];
            if (r->hi[a] > box[a + 3]) box[a + 3] = r->hi[a];
        }
    }
    memcpy(job->box[ch], box, sizeof box);
}

as_error_t kd_build(const as_mesh_t *mesh, const as_build_args_t *args, const kd_builder_ops *ops, as_structure_t *s)
{
    const double t_start = as_now_ms();
    if (args->layout != AS_LAYOUT_KD_STANDARD && args->layout != AS_LAYOUT_KD_ROPES)
        return as_set_error(AS_ERROR_UNSUPPORTED, "a KD tree has no layout 0x%04x (kd-standard or kd-ropes)",
                            (unsigned)args->layout);
    if (args->max_leaf_size < 1) return as_set_error(AS_ERROR_INVALID_ARGUMENT, "max leaf size must be at least 1");
    if (!(args->cost_traversal >= 0.0f) || !(args->cost_intersection > 0.0f) || !isfinite(args->cost_traversal) ||
        !isfinite(args->cost_intersection))
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "SAH costs must be finite, traversal >= 0, intersection > 0");
    if (!(args->split_budget >= 1.0f))
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "KD split budget %g must be at least 1", (double)args->split_budget);

    /* Zero-area triangles stay in TRIS but get no reference. The references
     * are filled in contiguous chunks, one per thread, each starting where
     * the earlier chunks' end (the mesh's bits count the zero-area ones), so
     * they keep the source order. */
    const unsigned threads = as_thread_count(args->thread_count);
    kd_init_job init;
    memset(&init, 0, sizeof init);
    init.mesh = mesh;
    init.chunks = mesh->triangle_count >= 65536 ? threads : 1;
    if (init.chunks > KD_INIT_CHUNKS) init.chunks = KD_INIT_CHUNKS;
    uint32_t n = 0;
    for (unsigned ch = 0; ch < init.chunks; ++ch) {
        uint32_t first, end;
        as_chunk_range(mesh->triangle_count, ch, init.chunks, &first, &end);
        init.offset[ch] = n;
        n += end - first - as_mesh_degenerate_in_range(mesh, first, end);
    }
    init.refs = refs_alloc(n);
    as_tri4_t *tris = as_spatial_tris(mesh, threads);
    if (!init.refs || !tris) {
        as_temp_give(init.refs);
        free(tris);
        return as_set_error(AS_ERROR_OUT_OF_MEMORY, "out of memory building a KD tree");
    }
    as_parallel_run(init.chunks, init_fill, &init);
    kd_ref *refs = init.refs;
    float box[6] = {FLT_MAX, FLT_MAX, FLT_MAX, -FLT_MAX, -FLT_MAX, -FLT_MAX};
    for (unsigned ch = 0; ch < init.chunks; ++ch)
        for (int k = 0; k < 3; ++k) {
            if (init.box[ch][k] < box[k]) box[k] = init.box[ch][k];
            if (init.box[ch][k + 3] > box[k + 3]) box[k + 3] = init.box[ch][k + 3];
        }
    if (n == 0) memset(box, 0, sizeof box);

    kd_ctx ctx = {args, mesh, ops, 0, tris, 0};
    /* The default depth cap grows with log N (8 + 1.3 log2 N, the usual
     * rule), never beyond the traversal stack. */
    uint32_t cap = (uint32_t)(8.0 + 1.3 * log2((double)(n > 1 ? n : 1)));
    if (args->max_depth) cap = args->max_depth;
    if (cap > AS_KD_MAX_DEPTH) cap = AS_KD_MAX_DEPTH;
    ctx.max_depth = cap;

    kd_run run;
    memset(&run, 0, sizeof run);
    run.c = &ctx;
    pthread_mutex_init(&run.lock, NULL);
    void *root_state = ops->root_state ? ops->root_state(&ctx, refs, n) : NULL;
    if (ops->root_state && !root_state) atomic_store(&run.oom, 1);
    kd_tmp *root = NULL;
    kd_task first = {refs, n, 0, root_state, {0}, 0, (double)args->split_budget * (double)n, 1.0, &root};
    memcpy(first.box, box, sizeof box);
    if (threads < 2 || n < 2 * PARALLEL_MIN_REFS || !as_task_pool_run(threads, sizeof first, &first, build_task, &run))
        build_task(NULL, &first, &run);
    pthread_mutex_destroy(&run.lock);
    if (atomic_load(&run.cancelled) || atomic_load(&run.oom) || !root) {
        scratch_free_all(&run);
        free(tris);
        if (atomic_load(&run.cancelled)) return as_set_error(AS_ERROR_CANCELLED, "KD build cancelled by the progress callback");
        return as_set_error(AS_ERROR_OUT_OF_MEMORY, "out of memory building a KD tree");
    }
    kd_counts kc;
    memset(&kc, 0, sizeof kc);
    for (const kd_scratch *sc = run.free_scratch; sc; sc = sc->next_free) {
        kc.inner += sc->inner;
        kc.leaves += sc->leaves;
        kc.empty += sc->empty;
        kc.refs += sc->refs;
        if (sc->max_depth > kc.max_depth) kc.max_depth = sc->max_depth;
    }
    kc.nodes = kc.inner + kc.leaves;
    if (kc.nodes >= (1u << 30) || kc.leaves + kc.refs >= UINT32_MAX) {
        scratch_free_all(&run);
        free(tris);
        return as_set_error(AS_ERROR_UNSUPPORTED, "KD tree too large for 32-bit indices");
    }
    as_kd_node_t *nodes = as_aligned_alloc(sizeof(as_kd_node_t) * kc.nodes, "KD nodes");
    uint32_t *prim = as_aligned_alloc(sizeof(uint32_t) * (kc.leaves + kc.refs), "KD PRIM");
    if (!nodes || !prim) {
        free(nodes);
        free(prim);
        free(tris);
        scratch_free_all(&run);
        return as_get_error();
    }
    kd_emit e = {nodes, prim, 0, 0, 0, args->cost_traversal, args->cost_intersection, as_spatial_half_area(box, box + 3),
                 {0.0, 0.0, 0}, NULL};
    const int written = emit_tree(root, box, &e, kc.nodes, threads);
    scratch_free_all(&run);
    if (!written || e.prim_next != kc.leaves + kc.refs) {
        free(nodes);
        free(prim);
        free(tris);
        return as_set_error(AS_ERROR_UNKNOWN, "KD build bookkeeping: %llu nodes and %llu PRIM entries written, %llu and %llu counted",
                            (unsigned long long)e.node_next, (unsigned long long)e.prim_next,
                            (unsigned long long)kc.nodes, (unsigned long long)(kc.leaves + kc.refs));
    }

    as_spatial_meta(s, mesh, args, AS_STRUCT_KD, AS_LAYOUT_KD_STANDARD, AS_KD_LAYOUT_VERSION, ops->builder);
    /* The tree's root box, which the traversal starts from. */
    memcpy(s->meta.bounds_lo, box, sizeof s->meta.bounds_lo);
    memcpy(s->meta.bounds_hi, box + 3, sizeof s->meta.bounds_hi);
    s->meta.node_count = kc.inner;
    s->meta.leaf_count = kc.leaves - kc.empty;
    s->meta.empty_leaf_count = kc.empty;
    s->meta.reference_count = kc.refs;
    s->meta.max_depth = kc.max_depth;
    s->meta.max_depth_limit = cap;
    s->meta.split_budget = args->split_budget;
    as_structure_add_section(s, ASF_TAG_KDN8, nodes, kc.nodes, sizeof(as_kd_node_t));
    as_structure_add_section(s, ASF_TAG_PRIM, prim, kc.leaves + kc.refs, sizeof(uint32_t));
    as_spatial_add_tris(s, tris, mesh->triangle_count);
    s->meta.sah_cost = as_sah_sum_value(&e.sah);
    if (args->layout == AS_LAYOUT_KD_ROPES) {
        const as_error_t err = as_kd_add_ropes(s);
        if (err != AS_OK) return err;
    }
    s->build_ms = as_now_ms() - t_start;
    return AS_OK;
}
