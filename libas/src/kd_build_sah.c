/* KD builder, SAH with perfect splits (Wald & Havran 2006, "On building fast
 * kd-trees for ray tracing, and on doing that in O(N log N)").
 *
 * Candidates are the bounds of every reference's clipped box (kd_build.c
 * clips triangles to the node box, so these are the "perfect" planes). Each
 * candidate plane is swept with three event kinds: end, planar, start.
 * A triangle counts below when it starts below or in the plane, above when
 * it ends above or in it: the driver's sides (kd_build.c) give a triangle
 * that touches the plane to both children, so the cost counts what each
 * child will hold. (Wald & Havran count a triangle that ends in the plane
 * below only and one that starts in it above only, as their sides do; with
 * this driver that undercounted, and its trees traced 1.16 to 1.9 times
 * slower on the GPU on bunny, bathroom and bmw-m6, docs/results/
 * 2026-11-26-build-bench-13.md.) Triangles lying in the plane are tried on
 * either side and put where the cost is lower (section 4.3 of the paper).
 * The cost is lambda (C_t + C_i (A_L N_L + A_R N_R) / A) with lambda = 0.8
 * when a side is empty (the empty-space bonus); a node becomes a leaf when
 * no plane costs less than C_i N.
 *
 * The events are sorted once, at the root, one list per axis (section 5 of
 * the paper). A node hands its lists down: the events of a reference that
 * reaches a child unchanged keep their order, so they are filtered, not
 * sorted again; only the references clipped by the split (the straddling
 * ones, usually few) get new events, which are sorted on their own and
 * merged in. An event is one 64-bit word, (position, kind, reference), so
 * the lists' order is the words' order and a merge compares words.
 *
 * The reference in an event is its triangle index, not its place in the
 * node's array: a node's references are in triangle order (the root's are,
 * and children keep their parent's order), so the two orders agree, and a
 * child takes its parent's events as they are, without renumbering; a byte
 * per triangle (kd_scratch.side) says which child keeps an event.
 *
 * Below SMALL_NODE_REFS references a node has no lists: every candidate is
 * counted against every reference in vector compares, which costs less
 * there than making, sorting and sweeping lists, and gives the same plane
 * (sah_choose_small). */
#include "kd_build.h"
#include "task_pool.h"

#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
/* Loops that have an AVX2 form, chosen at run time (as_cpu_has_avx2): the
 * functions may use AVX2, never FMA, so they compute what the others do. */
#if defined(__x86_64__) && defined(__GNUC__)
#define KD_AVX2 1
#include <immintrin.h>
#include <pthread.h>
#endif

enum { EV_END = 0, EV_PLANAR = 1, EV_START = 2 };

/* A float's bits, ordered as the floats are. */
static uint32_t float_key(float f)
{
    const uint32_t u = as_float_as_uint(f == 0.0f ? 0.0f : f);
    return (u & 0x80000000u) ? ~u : u | 0x80000000u;
}

static float key_float(uint32_t k)
{
    return as_uint_as_float((k & 0x80000000u) ? k & 0x7fffffffu : ~k);
}


/* Sorts event keys (34 significant bits): LSD radix sort, linear in the
 * count, so a node costs O(n) and the build O(N log N); short lists use
 * insertion sort. One read pass makes every digit's histogram, and a digit
 * that all keys share (the high bits of positions inside one node's box
 * mostly are) costs no pass. `tmp` has room for m keys. */
/* An event: the position's ordered bits, its kind, and the index of its
 * reference in the node's array; the words sort as (position, kind, index). */
#define EV_INDEX_BITS 30
#define EV_INDEX_MASK ((1u << EV_INDEX_BITS) - 1u)
#define EV_SORT_SHIFT EV_INDEX_BITS /* the 34 bits above the index are the sort key */

static uint64_t make_event(float pos, int kind, uint32_t index)
{
    return ((uint64_t)float_key(pos) << 32) | ((uint64_t)kind << EV_INDEX_BITS) | index;
}

static uint32_t event_key(uint64_t ev) { return (uint32_t)(ev >> 32); }
static int event_kind(uint64_t ev) { return (int)((ev >> EV_INDEX_BITS) & 3); }
static uint32_t event_index(uint64_t ev) { return (uint32_t)ev & EV_INDEX_MASK; }

/* Stable LSD radix sort of events on their 34 key bits, linear in the
 * count. Events made in increasing index order come out in full word
 * order. One read pass makes every digit's histogram, and a digit that all
 * keys share (the high bits of positions inside one box mostly are) costs
 * no pass. `tmp` has room for m events. */
static void radix_sort_digits(uint64_t *ev, uint64_t *tmp, size_t m, int bits, int passes, size_t *count)
{
    const size_t buckets = (size_t)1 << bits, mask = buckets - 1;
    memset(count, 0, sizeof(size_t) * buckets * (size_t)passes);
    for (size_t i = 0; i < m; ++i)
        for (int pass = 0; pass < passes; ++pass)
            count[(size_t)pass * buckets + ((ev[i] >> (EV_SORT_SHIFT + bits * pass)) & mask)]++;
    uint64_t *src = ev, *dst = tmp;
    for (int pass = 0; pass < passes; ++pass) {
        size_t *c = count + (size_t)pass * buckets;
        const int shift = EV_SORT_SHIFT + bits * pass;
        if (c[(src[0] >> shift) & mask] == m) continue; /* one bucket: order kept */
        size_t sum = 0;
        for (size_t k = 0; k < buckets; ++k) { const size_t n = c[k]; c[k] = sum; sum += n; }
        for (size_t i = 0; i < m; ++i) dst[c[(src[i] >> shift) & mask]++] = src[i];
        uint64_t *t = src; src = dst; dst = t;
    }
    if (src != ev) memcpy(ev, src, sizeof(uint64_t) * m);
}

static void sort_events(uint64_t *ev, uint64_t *tmp, size_t m)
{
    if (m < 48) {
        for (size_t i = 1; i < m; ++i) {
            const uint64_t k = ev[i];
            size_t j = i;
            for (; j > 0 && ev[j - 1] > k; --j) ev[j] = ev[j - 1];
            ev[j] = k;
        }
        return;
    }
    /* 5 digits of 7 bits for short lists (small histograms to clear), 3 of
     * 12 bits for long ones; both cover the 34 bits of a key. */
    static _Thread_local size_t count[3 << 12];
    if (m < 8192) radix_sort_digits(ev, tmp, m, 7, 5, count);
    else radix_sort_digits(ev, tmp, m, 12, 3, count);
}

/* A node's events, one sorted list per axis, in one allocation. */
typedef struct sah_events {
    uint64_t *list[3];
    size_t count[3];
    uint32_t n;      /* references in the node: each has one PLANAR event or a START and an END per axis,
                      * so an axis of m events has 2n - m PLANAR ones */
    uint32_t root_n; /* references at the root */
} sah_events;

/* The three axes' work runs on threads of its own in a node that holds
 * more than a thread's share of the root's references: the root, and the
 * big child of an uneven split (an empty-space cut near the root leaves
 * nearly everything on one side), where the other subtrees cannot keep the
 * threads busy. The axes' results do not depend on which thread ran them. */
#define PIECES_MAX 32
#define PIECE_MIN_EVENTS 16384

/* Nodes of at most this many references choose their planes without
 * event lists (sah_choose_small). */
#define SMALL_NODE_REFS 64

static unsigned axis_threads(const kd_ctx *c, const sah_events *e, uint32_t n)
{
    const unsigned threads = as_thread_count(c->args->thread_count);
    if (threads < 2 || (uint64_t)n * threads <= e->root_n) return 1;
    return threads < 3 ? threads : 3;
}

/* With more threads than axes, a big node's lists are taken in pieces, so
 * that every thread has work: as many per axis as threads, each of at least
 * PIECE_MIN_EVENTS events. */
static unsigned pieces_per_axis(const kd_ctx *c, const sah_events *e, uint32_t n)
{
    const unsigned threads = as_thread_count(c->args->thread_count);
    if (threads <= 3 || (uint64_t)n * threads <= e->root_n) return 1;
    uint64_t per = (2 * (uint64_t)n) / PIECE_MIN_EVENTS;
    if (per > threads) per = threads;
    if (per > PIECES_MAX) per = PIECES_MAX;
    return per < 2 ? 1 : (unsigned)per;
}

typedef struct axis_job {
    void (*fn)(void *user, int axis);
    void *user;
} axis_job;

static void axis_job_run(void *user, unsigned i, unsigned n)
{
    const axis_job *j = user;
    for (unsigned a = i; a < 3; a += n) j->fn(j->user, (int)a);
}

/* fn(user, axis) for the three axes, on `threads` threads. */
static void for_each_axis(unsigned threads, void (*fn)(void *user, int axis), void *user)
{
    if (threads < 2) {
        for (int a = 0; a < 3; ++a) fn(user, a);
        return;
    }
    axis_job j = {fn, user};
    as_parallel_run(threads, axis_job_run, &j);
}

/* Each list has spare slots: the children's lists are filled by writing
 * every event (four at a time with AVX2) and advancing only past the kept
 * ones, and a finished list ends there with a sentinel above every event
 * (UINT64_MAX, whose key no finite position has), so the sweep can read
 * one event past the last. */
#define EVENTS_SPARE 4

/* Lists are temporaries (as_temp_take): a build makes and frees them level
 * after level. */
static sah_events *events_alloc(size_t per_axis)
{
    sah_events *e = as_temp_take(sizeof *e + sizeof(uint64_t) * 3 * (per_axis + EVENTS_SPARE), "KD event lists");
    if (!e) return NULL;
    uint64_t *base = (uint64_t *)(e + 1);
    for (int a = 0; a < 3; ++a) {
        e->list[a] = base + (size_t)a * (per_axis + EVENTS_SPARE);
        e->count[a] = 0;
    }
    return e;
}

static void events_free(void *state) { as_temp_give(state); }

/* Appends the events of reference `r` (index `index`) on `axis`. */
static size_t put_events(uint64_t *out, const kd_ref *r, int axis, uint32_t index)
{
    const float lo = r->lo[axis], hi = r->hi[axis];
    if (lo == hi) {
        out[0] = make_event(lo, EV_PLANAR, index);
        return 1;
    }
    out[0] = make_event(lo, EV_START, index);
    out[1] = make_event(hi, EV_END, index);
    return 2;
}

/* The root's lists: each axis's references in two halves (so that two
 * threads share three axes evenly), each half's events made and sorted on
 * their own, then the halves merged. The merged list is the one sorting all
 * at once gives: the events are ordered by their whole word. */
#define ROOT_HALVES 2

/* Appends the events of clipped reference `r` on `axis` that child `s`
 * does not keep from its parent (keep: its side[] bits). */
static size_t put_fresh_events(uint64_t *out, const kd_ref *r, int axis, unsigned keep, int s)
{
    const float lo = r->lo[axis], hi = r->hi[axis];
    const int keep_lo = (keep & KD_KEEP_BIT(s, axis, 0)) != 0, keep_hi = (keep & KD_KEEP_BIT(s, axis, 1)) != 0;
    if (lo == hi) {
        if (keep_lo) return 0;
        out[0] = make_event(lo, EV_PLANAR, r->id);
        return 1;
    }
    size_t k = 0;
    if (!keep_lo) out[k++] = make_event(lo, EV_START, r->id);
    if (!keep_hi) out[k++] = make_event(hi, EV_END, r->id);
    return k;
}

/* Whether child s keeps the parent's event ev on axis a: its side[] bit for
 * the event's bound (END: high; START, PLANAR: low). */
static unsigned keeps_event(unsigned keep, int s, int a, uint64_t ev)
{
    return (keep >> (s * 6 + a * 2 + (event_kind(ev) == EV_END))) & 1u;
}

/* Both children's keep bits of ev on axis a, child 0's in bit 0 and child
 * 1's in bit 6: one shift of its reference's side[] entry. */
static inline unsigned event_keep_bits(const uint16_t *side, int a, uint64_t ev)
{
    return (unsigned)side[event_index(ev)] >> (a * 2 + (event_kind(ev) == EV_END));
}

typedef struct root_job {
    const kd_ref *refs;
    uint32_t n;
    sah_events *e;                       /* per axis: both halves' sorted events, each ending in a sentinel */
    size_t run_count[3][ROOT_HALVES];
    atomic_int failed;
} root_job;

static void root_half_range(uint32_t n, int h, uint32_t *first, uint32_t *end)
{
    *first = (uint32_t)((uint64_t)n * (unsigned)h / ROOT_HALVES);
    *end = (uint32_t)((uint64_t)n * (unsigned)(h + 1) / ROOT_HALVES);
}

/* Where half h's events start in a list: room for the earlier halves'
 * events and sentinels. */
static size_t root_half_at(uint32_t n, int h)
{
    uint32_t first, end;
    root_half_range(n, h, &first, &end);
    return 2 * (size_t)first + (size_t)h;
}

static void root_sort_half(void *user, unsigned i, unsigned count)
{
    root_job *r = user;
    for (unsigned piece = i; piece < 3 * ROOT_HALVES; piece += count) {
        const int a = (int)(piece % 3), h = (int)(piece / 3);
        uint32_t first, end;
        root_half_range(r->n, h, &first, &end);
        const size_t at = root_half_at(r->n, h);
        uint64_t *out = r->e->list[a] + at,
                 *tmp = as_temp_take(sizeof(uint64_t) * 2 * (size_t)(end > first ? end - first : 1), "KD root events");
        if (!tmp) {
            atomic_store(&r->failed, 1);
            return;
        }
        size_t m = 0;
        for (uint32_t k = first; k < end; ++k) m += put_events(out + m, &r->refs[k], a, r->refs[k].id);
        sort_events(out, tmp, m);
        as_temp_give(tmp);
        out[m] = UINT64_MAX;
        r->run_count[a][h] = m;
    }
}

static void root_merge_axis(void *user, int a)
{
    root_job *r = user;
    const uint64_t *x = r->e->list[a], *y = r->e->list[a] + root_half_at(r->n, 1);
    const size_t m = r->run_count[a][0] + r->run_count[a][1];
    uint64_t *out = as_temp_take(sizeof(uint64_t) * (m ? m : 1), "KD root events");
    if (!out) {
        atomic_store(&r->failed, 1);
        return;
    }
    for (size_t k = 0; k < m; ++k) out[k] = *x < *y ? *x++ : *y++;
    memcpy(r->e->list[a], out, sizeof(uint64_t) * m);
    as_temp_give(out);
    r->e->list[a][m] = UINT64_MAX;
    r->e->count[a] = m;
}

/* The root's lists on many threads: each axis's list sorted by a parallel
 * LSD radix sort, the halves-and-merge above using at most six threads and
 * then three. Every pass is stable and the events are made in reference
 * order in chunks kept in order, so the lists are the same words in the
 * same order. Each pass counts its digit per chunk of the list, gives each
 * chunk its place per bucket, and moves the events; a digit that all events
 * of an axis share costs no move. */
#define ROOT_RADIX_BITS 12
#define ROOT_RADIX_BUCKETS (1u << ROOT_RADIX_BITS)
#define ROOT_RADIX_PASSES 3 /* 36 bits cover the 34 of a key */
#define ROOT_RADIX_MIN_REFS 16384
#define ROOT_RADIX_MIN_THREADS 4

typedef struct root_radix {
    const kd_ref *refs;
    uint32_t n;
    unsigned chunks;                 /* per axis */
    uint64_t *src[3], *dst[3];       /* the pass's input and output per axis */
    size_t m[3];                     /* events per axis */
    size_t *made;                    /* [a][c]: events chunk c made (pass 0 reads them where it made them) */
    uint32_t *count;                 /* [a][c][bucket]: the pass's counts, then the chunk's next places */
    int pass;
    int moves[3];                    /* whether the pass moves the axis's events */
} root_radix;

static uint32_t *radix_counts(root_radix *r, int a, unsigned c)
{
    return r->count + ((size_t)a * r->chunks + c) * ROOT_RADIX_BUCKETS;
}

static unsigned radix_digit(uint64_t ev, int pass)
{
    return (unsigned)(ev >> (EV_SORT_SHIFT + ROOT_RADIX_BITS * pass)) & (ROOT_RADIX_BUCKETS - 1);
}

/* The events of chunk c of axis a in the pass's input: pass 0 reads them
 * where radix_count made them (at twice the chunk's first reference),
 * later passes read the list in equal ranges. */
static void radix_range(const root_radix *r, int a, unsigned c, const uint64_t **first, size_t *count)
{
    if (r->pass == 0) {
        uint32_t f, e;
        as_chunk_range(r->n, c, r->chunks, &f, &e);
        *first = r->src[a] + 2 * (size_t)f;
        *count = r->made[(size_t)a * r->chunks + c];
        return;
    }
    size_t f = r->m[a] * c / r->chunks, e = r->m[a] * (c + 1) / r->chunks;
    *first = r->src[a] + f;
    *count = e - f;
}

/* Job i (axis i % 3, chunk i / 3): the chunk's events made (pass 0 only)
 * and its digit counted. */
static void radix_count(void *user, size_t i)
{
    root_radix *r = user;
    const int a = (int)(i % 3);
    const unsigned c = (unsigned)(i / 3);
    if (r->pass == 0) {
        uint32_t f, e;
        as_chunk_range(r->n, c, r->chunks, &f, &e);
        uint64_t *out = r->src[a] + 2 * (size_t)f;
        size_t m = 0;
        for (uint32_t k = f; k < e; ++k) m += put_events(out + m, &r->refs[k], a, r->refs[k].id);
        r->made[(size_t)a * r->chunks + c] = m;
    }
    const uint64_t *ev;
    size_t m;
    radix_range(r, a, c, &ev, &m);
    uint32_t *cnt = radix_counts(r, a, c);
    memset(cnt, 0, sizeof(uint32_t) * ROOT_RADIX_BUCKETS);
    for (size_t k = 0; k < m; ++k) cnt[radix_digit(ev[k], r->pass)]++;
}

/* Axis a: each chunk's first place per bucket (the buckets in order, the
 * chunks in order within one), and whether the pass moves anything. */
static void radix_places(void *user, int a)
{
    root_radix *r = user;
    if (r->pass == 0) {
        r->m[a] = 0;
        for (unsigned c = 0; c < r->chunks; ++c) r->m[a] += r->made[(size_t)a * r->chunks + c];
    }
    size_t at = 0;
    int buckets_used = 0;
    for (uint32_t b = 0; b < ROOT_RADIX_BUCKETS; ++b) {
        size_t in_bucket = 0;
        for (unsigned c = 0; c < r->chunks; ++c) {
            uint32_t *cnt = radix_counts(r, a, c);
            const uint32_t k = cnt[b];
            cnt[b] = (uint32_t)at;
            at += k;
            in_bucket += k;
        }
        buckets_used += in_bucket > 0;
    }
    /* Pass 0 always moves: its input is spread out where it was made. */
    r->moves[a] = r->pass == 0 || buckets_used > 1;
}

static void radix_move(void *user, size_t i)
{
    root_radix *r = user;
    const int a = (int)(i % 3);
    const unsigned c = (unsigned)(i / 3);
    if (!r->moves[a]) return;
    const uint64_t *ev;
    size_t m;
    radix_range(r, a, c, &ev, &m);
    uint32_t *next = radix_counts(r, a, c);
    uint64_t *out = r->dst[a];
    for (size_t k = 0; k < m; ++k) out[next[radix_digit(ev[k], r->pass)]++] = ev[k];
}

/* The sorted lists into e (per_axis room each), on `threads` threads; 0
 * when out of memory. */
static int sah_root_events_radix(const kd_ref *refs, uint32_t n, unsigned threads, sah_events *e)
{
    root_radix r;
    memset(&r, 0, sizeof r);
    r.refs = refs;
    r.n = n;
    r.chunks = threads > 64 ? 64 : threads;
    uint64_t *scratch = as_temp_take(sizeof(uint64_t) * 3 * 2 * (size_t)n, "KD root events");
    r.made = malloc(sizeof(size_t) * 3 * r.chunks);
    r.count = as_temp_take(sizeof(uint32_t) * 3 * r.chunks * ROOT_RADIX_BUCKETS, "KD root radix counts");
    if (!scratch || !r.made || !r.count) {
        as_temp_give(scratch);
        free(r.made);
        as_temp_give(r.count);
        return 0;
    }
    /* Pass 0 makes the events in the scratch and moves them to the list;
     * later passes go back and forth, each axis from where it is. */
    for (int a = 0; a < 3; ++a) {
        r.src[a] = scratch + (size_t)a * 2 * n;
        r.dst[a] = e->list[a];
    }
    for (r.pass = 0; r.pass < ROOT_RADIX_PASSES; ++r.pass) {
        as_parallel_for(threads, 3 * (size_t)r.chunks, radix_count, &r);
        for_each_axis(3, radix_places, &r);
        as_parallel_for(threads, 3 * (size_t)r.chunks, radix_move, &r);
        for (int a = 0; a < 3; ++a) {
            if (!r.moves[a]) continue;
            uint64_t *t = r.src[a];
            r.src[a] = r.dst[a];
            r.dst[a] = r.pass == 0 ? scratch + (size_t)a * 2 * n : t;
        }
    }
    for (int a = 0; a < 3; ++a) {
        if (r.src[a] != e->list[a]) memcpy(e->list[a], r.src[a], sizeof(uint64_t) * r.m[a]);
        e->list[a][r.m[a]] = UINT64_MAX;
        e->count[a] = r.m[a];
    }
    as_temp_give(scratch);
    free(r.made);
    as_temp_give(r.count);
    return 1;
}

static void *sah_root_events(const kd_ctx *c, const kd_ref *refs, uint32_t n)
{
    if (c->mesh->triangle_count > (uint64_t)EV_INDEX_MASK + 1) return NULL;
    /* Two events per reference, and a sentinel after each half. */
    const size_t per_axis = 2 * (size_t)n + ROOT_HALVES;
    sah_events *e = events_alloc(per_axis);
    if (!e) return NULL;
    e->root_n = n;
    e->n = n;
    root_job r;
    memset(&r, 0, sizeof r);
    r.refs = refs;
    r.n = n;
    r.e = e;
    atomic_init(&r.failed, 0);
    const unsigned threads = as_thread_count(c->args->thread_count);
    if (threads >= ROOT_RADIX_MIN_THREADS && n >= ROOT_RADIX_MIN_REFS) {
        if (sah_root_events_radix(refs, n, threads, e)) return e;
        events_free(e);
        return NULL;
    }
    as_parallel_run(threads < 2 ? 1 : (threads < 3 * ROOT_HALVES ? threads : 3 * ROOT_HALVES), root_sort_half, &r);
    if (!atomic_load(&r.failed)) for_each_axis(axis_threads(c, e, n), root_merge_axis, &r);
    if (atomic_load(&r.failed)) {
        events_free(e);
        return NULL;
    }
    return e;
}

/* What the children's lists are made from, shared by the axes. */
typedef struct child_job {
    const sah_events *parent;
    const kd_scratch *how;
    const kd_ref *const *child_refs;
    sah_events *e[2];
    uint64_t *fresh[3];  /* per axis: both sides' clipped references' events, then the sort's scratch */
} child_job;

/* Runs of the parent's events below both children's next fresh events
 * (nothing to merge in among them), from k on in blocks of four: each
 * written to both children's lists and kept by advancing (KD_KEEP_BIT of
 * the event's bound). Returns where the runs end; writes up to three
 * words past a list's last event (EVENTS_SPARE). */
typedef struct kept_run {
    const uint64_t *src;
    size_t m;
    const uint16_t *keep;
    int axis;
    unsigned kept[2]; /* 1 for a child with lists, 0 for one without (its events go to a spare) */
    uint64_t *out[2];
    size_t n[2];
} kept_run;

static size_t kept_runs(kept_run *r, size_t k, uint64_t below)
{
    const uint64_t *const src = r->src;
    uint64_t *const o0 = r->out[0], *const o1 = r->out[1];
    size_t n0 = r->n[0], n1 = r->n[1];
    const unsigned kept0 = r->kept[0], kept1 = r->kept[1];
    for (; k + 4 <= r->m && src[k + 3] < below; k += 4)
        for (int u = 0; u < 4; ++u) {
            const uint64_t ev = src[k + u];
            const unsigned f = event_keep_bits(r->keep, r->axis, ev);
            o0[n0] = ev;
            o1[n1] = ev;
            n0 += f & kept0;
            n1 += (f >> 6) & kept1;
        }
    r->n[0] = n0;
    r->n[1] = n1;
    return k;
}

#if defined(KD_AVX2)
/* For each mask of four 64-bit lanes, the 32-bit lanes that pack the kept
 * ones in order. */
static const int32_t kept_pack4[16][8] = {
    {0, 1, 0, 1, 0, 1, 0, 1}, {0, 1, 0, 1, 0, 1, 0, 1}, {2, 3, 0, 1, 0, 1, 0, 1}, {0, 1, 2, 3, 0, 1, 0, 1},
    {4, 5, 0, 1, 0, 1, 0, 1}, {0, 1, 4, 5, 0, 1, 0, 1}, {2, 3, 4, 5, 0, 1, 0, 1}, {0, 1, 2, 3, 4, 5, 0, 1},
    {6, 7, 0, 1, 0, 1, 0, 1}, {0, 1, 6, 7, 0, 1, 0, 1}, {2, 3, 6, 7, 0, 1, 0, 1}, {0, 1, 2, 3, 6, 7, 0, 1},
    {4, 5, 6, 7, 0, 1, 0, 1}, {0, 1, 4, 5, 6, 7, 0, 1}, {2, 3, 4, 5, 6, 7, 0, 1}, {0, 1, 2, 3, 4, 5, 6, 7},
};

/* kept_runs four events at a time: their keep bits gathered (two bytes
 * each, read as four: side[] has a spare entry), shifted per lane to the
 * event's bound, and the kept events packed by a permutation. */
__attribute__((target("avx2"))) static size_t kept_runs_avx2(kept_run *r, size_t k, uint64_t below)
{
    const uint64_t *const src = r->src;
    uint64_t *const o0 = r->out[0], *const o1 = r->out[1];
    size_t n0 = r->n[0], n1 = r->n[1];
    const int mask0 = r->kept[0] ? 0xf : 0, mask1 = r->kept[1] ? 0xf : 0;
    const __m256i low_halves = _mm256_setr_epi32(0, 2, 4, 6, 0, 2, 4, 6);
    const __m128i index_mask = _mm_set1_epi32((int)EV_INDEX_MASK), a2 = _mm_set1_epi32(r->axis * 2);
    for (; k + 4 <= r->m && src[k + 3] < below; k += 4) {
        /* A big node's lists are read once, in order, mostly from memory:
         * asked for 96 events ahead, they are in cache when read. */
        _mm_prefetch((const char *)(src + k + 96), _MM_HINT_T0);
        const __m256i ev = _mm256_loadu_si256((const __m256i *)(src + k));
        /* Each event's low word: its kind (bits 30-31) and index. */
        const __m128i w = _mm256_castsi256_si128(_mm256_permutevar8x32_epi32(ev, low_halves));
        const __m128i bits = _mm_i32gather_epi32((const int *)r->keep, _mm_and_si128(w, index_mask), 2);
        const __m128i is_end = _mm_cmpeq_epi32(_mm_srli_epi32(w, EV_INDEX_BITS), _mm_setzero_si128());
        const __m128i f = _mm_srlv_epi32(bits, _mm_sub_epi32(a2, is_end));
        const int m0 = _mm_movemask_ps(_mm_castsi128_ps(_mm_slli_epi32(f, 31))) & mask0;
        const int m1 = _mm_movemask_ps(_mm_castsi128_ps(_mm_slli_epi32(f, 25))) & mask1;
        _mm256_storeu_si256((__m256i *)(o0 + n0),
                            _mm256_permutevar8x32_epi32(ev, _mm256_loadu_si256((const __m256i *)kept_pack4[m0])));
        _mm256_storeu_si256((__m256i *)(o1 + n1),
                            _mm256_permutevar8x32_epi32(ev, _mm256_loadu_si256((const __m256i *)kept_pack4[m1])));
        n0 += (size_t)__builtin_popcount((unsigned)m0);
        n1 += (size_t)__builtin_popcount((unsigned)m1);
    }
    r->n[0] = n0;
    r->n[1] = n1;
    return k;
}
#endif

/* One axis of both children: the parent's events of references that reach
 * a child unchanged, merged, in the same pass, with the sorted events of the
 * clipped ones. A fresh list ends with a sentinel above every event, so the
 * merge needs no bounds check; a fresh event is never equal to a kept one
 * (their triangles differ). */
static void child_axis_events(void *user, int a)
{
    child_job *cj = user;
    const kd_scratch *how = cj->how;
    sah_events *const *e = cj->e;
    uint64_t *fresh[2], *const tmp = cj->fresh[a] + 2 * ((size_t)how->clipped_n[0] + how->clipped_n[1]) + 2;
    fresh[0] = cj->fresh[a];
    for (int side = 0; side < 2; ++side) {
        size_t nf = 0;
        for (uint32_t k = 0; e[side] && k < how->clipped_n[side]; ++k) {
            const kd_ref *r = &cj->child_refs[side][how->clipped[side][k]];
            nf += put_fresh_events(fresh[side] + nf, r, a, how->side[r->id], side);
        }
        sort_events(fresh[side], tmp, nf);
        fresh[side][nf] = UINT64_MAX;
        if (side == 0) fresh[1] = fresh[0] + nf + 1;
    }
    const uint16_t *const keep = how->side;
    /* A small child gets no lists (SMALL_NODE_REFS): its events are all
     * written to spare words, none kept. */
    uint64_t spare[EVENTS_SPARE];
    uint64_t *o0 = e[0] ? e[0]->list[a] : spare, *o1 = e[1] ? e[1]->list[a] : spare;
    const unsigned kept0 = e[0] ? 1u : 0u, kept1 = e[1] ? 1u : 0u;
    const uint64_t *f0 = fresh[0], *f1 = fresh[1];
    size_t n0 = 0, n1 = 0;
    const uint64_t *src = cj->parent->list[a];
    const size_t m = cj->parent->count[a];
    kept_run run = {src, m, keep, a, {kept0, kept1}, {o0, o1}, {0, 0}};
#if defined(KD_AVX2)
    const int avx2 = as_cpu_has_avx2();
#endif
    /* The next fresh events live in registers: the compiler must assume
     * the children's stores can change the fresh lists, and would load
     * them again after every event. */
    uint64_t y0 = *f0, y1 = *f1;
    for (size_t k = 0; k < m; ++k) {
        /* Most events lie between two fresh ones: the runs take them. */
        run.n[0] = n0;
        run.n[1] = n1;
        const uint64_t below = y0 < y1 ? y0 : y1;
#if defined(KD_AVX2)
        k = avx2 ? kept_runs_avx2(&run, k, below) : kept_runs(&run, k, below);
#else
        k = kept_runs(&run, k, below);
#endif
        n0 = run.n[0];
        n1 = run.n[1];
        if (k == m) break;
        const uint64_t ev = src[k];
        const unsigned f = event_keep_bits(keep, a, ev);
        while (y0 < ev) {
            o0[n0++] = y0;
            y0 = *++f0;
        }
        while (y1 < ev) {
            o1[n1++] = y1;
            y1 = *++f1;
        }
        /* Written always, kept by advancing: no branch on the side. */
        o0[n0] = ev;
        o1[n1] = ev;
        n0 += f & kept0;
        n1 += (f >> 6) & kept1;
    }
    while (y0 != UINT64_MAX) {
        o0[n0++] = y0;
        y0 = *++f0;
    }
    while (y1 != UINT64_MAX) {
        o1[n1++] = y1;
        y1 = *++f1;
    }
    if (e[0]) e[0]->count[a] = n0;
    if (e[1]) e[1]->count[a] = n1;
    o0[n0] = UINT64_MAX;
    o1[n1] = UINT64_MAX;
}

/* A big node's children's lists on many threads: the clipped references'
 * events made and sorted per axis and side, then each axis's parent list
 * in pieces. A piece takes the fresh events that the one-pass merge would
 * put among its events (those from the last event of the piece before, not
 * below the next piece's), its kept events are counted, and each piece
 * writes from where the pieces before it end: the lists are those of the
 * one-pass merge. */
typedef struct child_pieces {
    child_job *cj;
    unsigned per_axis;
    uint64_t *fresh[3][2], *tmp[3][2]; /* sorted, ending in a sentinel; the sorts' scratch */
    size_t fresh_n[3][2];
    size_t begin[3][PIECES_MAX + 1];          /* the pieces of the parent's list */
    size_t cut[3][2][PIECES_MAX + 1];         /* the pieces of the fresh lists */
    size_t at[3][2][PIECES_MAX + 1];          /* kept counts, then where each piece writes */
} child_pieces;

static void child_fresh_sort(void *user, unsigned i, unsigned n)
{
    child_pieces *cp = user;
    const kd_scratch *how = cp->cj->how;
    for (unsigned job = i; job < 6; job += n) {
        const int a = (int)(job % 3), side = (int)(job / 3);
        uint64_t *out = cp->fresh[a][side];
        size_t nf = 0;
        for (uint32_t k = 0; k < how->clipped_n[side]; ++k) {
            const kd_ref *r = &cp->cj->child_refs[side][how->clipped[side][k]];
            nf += put_fresh_events(out + nf, r, a, how->side[r->id], side);
        }
        sort_events(out, cp->tmp[a][side], nf);
        out[nf] = UINT64_MAX;
        cp->fresh_n[a][side] = nf;
    }
}

/* The first of the n sorted events that is not below x. */
static size_t events_lower_bound(const uint64_t *ev, size_t n, uint64_t x)
{
    size_t lo = 0, hi = n;
    while (lo < hi) {
        const size_t mid = lo + (hi - lo) / 2;
        if (ev[mid] < x) lo = mid + 1;
        else hi = mid;
    }
    return lo;
}

static void child_piece_count(void *user, unsigned i, unsigned n)
{
    child_pieces *cp = user;
    const uint16_t *const keep = cp->cj->how->side;
    for (unsigned job = i; job < 3 * cp->per_axis; job += n) {
        const int a = (int)(job % 3);
        const unsigned piece = job / 3;
        const uint64_t *src = cp->cj->parent->list[a];
        size_t k0 = 0, k1 = 0;
        for (size_t k = cp->begin[a][piece]; k < cp->begin[a][piece + 1]; ++k) {
            const unsigned f = keep[event_index(src[k])];
            k0 += keeps_event(f, 0, a, src[k]);
            k1 += keeps_event(f, 1, a, src[k]);
        }
        cp->at[a][0][piece] = k0;
        cp->at[a][1][piece] = k1;
    }
}

static void child_piece_merge(void *user, unsigned i, unsigned n)
{
    child_pieces *cp = user;
    const uint16_t *const keep = cp->cj->how->side;
    for (unsigned job = i; job < 3 * cp->per_axis; job += n) {
        const int a = (int)(job % 3);
        const unsigned piece = job / 3;
        const uint64_t *src = cp->cj->parent->list[a];
        uint64_t *const o0 = cp->cj->e[0]->list[a], *const o1 = cp->cj->e[1]->list[a];
        size_t n0 = cp->at[a][0][piece], n1 = cp->at[a][1][piece];
        const uint64_t *f0 = cp->fresh[a][0] + cp->cut[a][0][piece], *f1 = cp->fresh[a][1] + cp->cut[a][1][piece];
        const uint64_t *const f0_end = cp->fresh[a][0] + cp->cut[a][0][piece + 1];
        const uint64_t *const f1_end = cp->fresh[a][1] + cp->cut[a][1][piece + 1];
        /* Written only when kept: another piece writes right after this
         * one's last event. */
        /* The next fresh events in registers, as in child_axis_events (a
         * piece's end is inside a list that ends in a sentinel, so reading
         * one past it is safe). */
        uint64_t y0 = *f0, y1 = *f1;
        for (size_t k = cp->begin[a][piece]; k < cp->begin[a][piece + 1]; ++k) {
            const uint64_t ev = src[k];
            const unsigned f = keep[event_index(ev)];
            while (f0 < f0_end && y0 < ev) {
                o0[n0++] = y0;
                y0 = *++f0;
            }
            while (f1 < f1_end && y1 < ev) {
                o1[n1++] = y1;
                y1 = *++f1;
            }
            if (keeps_event(f, 0, a, ev)) o0[n0++] = ev;
            if (keeps_event(f, 1, a, ev)) o1[n1++] = ev;
        }
        while (f0 < f0_end) o0[n0++] = *f0++;
        while (f1 < f1_end) o1[n1++] = *f1++;
    }
}

static int child_events_in_pieces(child_job *cj, kd_scratch *how, unsigned threads, unsigned per_axis)
{
    child_pieces *cp = malloc(sizeof *cp);
    const size_t nc[2] = {how->clipped_n[0], how->clipped_n[1]};
    /* Per axis: both fresh lists with their sentinels, then both sorts'
     * scratch. */
    const size_t per_axis_words = 4 * (nc[0] + nc[1]) + 2;
    uint64_t *buf = kd_scratch_reserve(how, sizeof(uint64_t) * 3 * per_axis_words);
    if (!cp || !buf) {
        free(cp);
        return 0;
    }
    cp->cj = cj;
    cp->per_axis = per_axis;
    for (int a = 0; a < 3; ++a) {
        uint64_t *b = buf + (size_t)a * per_axis_words;
        cp->fresh[a][0] = b;
        cp->fresh[a][1] = b + 2 * nc[0] + 1;
        cp->tmp[a][0] = b + 2 * (nc[0] + nc[1]) + 2;
        cp->tmp[a][1] = cp->tmp[a][0] + 2 * nc[0];
    }
    as_parallel_run(threads < 6 ? threads : 6, child_fresh_sort, cp);
    for (int a = 0; a < 3; ++a) {
        const uint64_t *src = cj->parent->list[a];
        const size_t m = cj->parent->count[a];
        for (unsigned piece = 0; piece <= per_axis; ++piece) cp->begin[a][piece] = m * piece / per_axis;
        for (int side = 0; side < 2; ++side) {
            cp->cut[a][side][0] = 0;
            for (unsigned piece = 1; piece < per_axis; ++piece) {
                const size_t b = cp->begin[a][piece];
                cp->cut[a][side][piece] = b ? events_lower_bound(cp->fresh[a][side], cp->fresh_n[a][side], src[b - 1]) : 0;
            }
            cp->cut[a][side][per_axis] = cp->fresh_n[a][side];
        }
    }
    as_parallel_run(threads, child_piece_count, cp);
    for (int a = 0; a < 3; ++a)
        for (int side = 0; side < 2; ++side) {
            size_t at = 0;
            for (unsigned piece = 0; piece < per_axis; ++piece) {
                const size_t kept = cp->at[a][side][piece];
                cp->at[a][side][piece] = at;
                at += kept + cp->cut[a][side][piece + 1] - cp->cut[a][side][piece];
            }
            cp->at[a][side][per_axis] = at;
            cj->e[side]->count[a] = at;
        }
    as_parallel_run(threads, child_piece_merge, cp);
    for (int a = 0; a < 3; ++a)
        for (int side = 0; side < 2; ++side) cj->e[side]->list[a][cj->e[side]->count[a]] = UINT64_MAX;
    free(cp);
    return 1;
}

/* The children's lists, one pass over the parent's events per axis feeding
 * both children. */
static int sah_child_events(const kd_ctx *c, const void *parent_state, kd_scratch *how, uint32_t parent_n,
                            const kd_ref *const child_refs[2], const uint32_t child_n[2], void *out[2])
{
    const sah_events *p = parent_state;
    out[0] = out[1] = NULL;
    const unsigned pieces = p ? pieces_per_axis(c, p, parent_n) : 1;
    /* Small children choose their planes without lists; the pieces below
     * make both children's. */
    const int listed[2] = {pieces > 1 || child_n[0] > SMALL_NODE_REFS, pieces > 1 || child_n[1] > SMALL_NODE_REFS};
    if (!p || (!listed[0] && !listed[1])) return 1;
    child_job cj;
    memset(&cj, 0, sizeof cj);
    cj.parent = p;
    cj.how = how;
    cj.child_refs = child_refs;
    for (int side = 0; side < 2; ++side) {
        if (!listed[side]) continue;
        cj.e[side] = events_alloc(2 * (size_t)child_n[side]);
        if (!cj.e[side]) goto fail;
        cj.e[side]->root_n = p->root_n;
        cj.e[side]->n = child_n[side];
    }
    if (pieces > 1) {
        if (!child_events_in_pieces(&cj, how, as_thread_count(c->args->thread_count), pieces)) goto fail;
    } else {
        const unsigned threads = axis_threads(c, p, parent_n);
        const size_t nc0 = how->clipped_n[0], nc1 = how->clipped_n[1];
        /* Per axis: both fresh lists with their sentinels, and the sort's
         * scratch for the longer one. */
        const size_t per_axis = 2 * (nc0 + nc1) + 2 + 2 * (nc0 > nc1 ? nc0 : nc1);
        uint64_t *fresh = kd_scratch_reserve(how, sizeof(uint64_t) * per_axis * (threads > 1 ? 3 : 1));
        if (!fresh) goto fail;
        for (int a = 0; a < 3; ++a) cj.fresh[a] = threads > 1 ? fresh + (size_t)a * per_axis : fresh;
        for_each_axis(threads, child_axis_events, &cj);
    }
    out[0] = cj.e[0];
    out[1] = cj.e[1];
    return 1;
fail:
    events_free(cj.e[0]);
    events_free(cj.e[1]);
    out[0] = out[1] = NULL;
    return 0;
}

static double half_area(const float b[6])
{
    const double dx = (double)b[3] - b[0], dy = (double)b[4] - b[1], dz = (double)b[5] - b[2];
    return dx * dy + dy * dz + dz * dx;
}

/* The best plane of one axis: the first of the lowest cost below `limit`. */
typedef struct axis_best {
    double cost;
    float pos;
    int planar_left;
    int found;
    uint32_t count[2]; /* the references each side gets (kd_split.count) */
} axis_best;

typedef struct choose_job {
    const sah_events *e;
    const float *box;
    double ct, ci, area, limit;
    axis_best best[3];
} choose_job;

/* The sweep takes a list in chunks of events, three passes per chunk:
 *  1. the groups of events at one position, in a row: every event writes
 *     its running counts and advances past the group's last, so the groups
 *     (1 event up to a vertex's valence) need no loop of their own;
 *  2. every group's lower cost in single precision, a loop the compiler
 *     vectorizes;
 *  3. the exact cost, in double precision, only of the groups whose single
 *     precision cost is within SWEEP_MARGIN of the chunk's or the sweep's
 *     lowest: all others cost more than the plane kept. The single
 *     precision terms are non-negative, each rounded a few times, so they
 *     are within 1e-6 of the exact ones; the planes chosen are those of a
 *     double precision sweep over every group. */
#define SWEEP_CHUNK 256
#define SWEEP_MARGIN 1e-5

typedef struct sweep_chunk {
    /* Index 0 is the last group of the chunk before (or zeros). Per group:
     * its key and the events up to and including it (high half), and the
     * END (low half) and PLANAR events among those: two stores per event. */
    uint64_t key_events[SWEEP_CHUNK + 8], counts[SWEEP_CHUNK + 8];
    float cost[SWEEP_CHUNK + 8]; /* seven spare slots: the vector loops price groups eight at a time */
} sweep_chunk;

/* What an event adds to the END (low half) and PLANAR (high half) counts,
 * by kind. */
static const uint64_t sweep_count_step[4] = {1, (uint64_t)1 << 32, 0, 0};

/* The sides of a plane at group q of chunk g: below (*nl0), the references
 * that start or lie before the plane or start in it; above (*nr0), those
 * that end or lie after it or end in it; *p_eq lie in it and go to one side
 * or the other. */
static inline void group_sides(const sweep_chunk *g, size_t q, uint32_t np_total, uint32_t p_total, uint32_t *nl0,
                               uint32_t *nr0, uint32_t *p_eq)
{
    const uint32_t planars = (uint32_t)(g->counts[q] >> 32), ends = (uint32_t)g->counts[q];
    const uint32_t p = planars - (uint32_t)(g->counts[q - 1] >> 32), e_eq = ends - (uint32_t)g->counts[q - 1];
    const uint32_t s_eq = (uint32_t)g->key_events[q] - (uint32_t)g->key_events[q - 1] - e_eq - p;
    *nl0 = (uint32_t)g->key_events[q - 1] - (uint32_t)g->counts[q - 1] + s_eq;
    *nr0 = (np_total - ends) + (p_total - planars) + e_eq;
    *p_eq = p;
}

/* What pricing a group needs of its axis and node. */
typedef struct sweep_prices {
    uint32_t np_total, p_total, key_lo, key_hi;
    float face, rim, lo, hi, ct, ci;
} sweep_prices;

/* The single-precision cost of a plane at pos with nl0 references below,
 * nr0 above and p_eq in it (the lower of the two sides for those). It only
 * decides which planes are priced exactly; the exact price is
 * price_plane_exactly's. */
static inline float price_plane(float pos, uint32_t nl0, uint32_t nr0, uint32_t p_eq, const sweep_prices *sp)
{
    const float al = sp->face + sp->rim * (pos - sp->lo), ar = sp->face + sp->rim * (sp->hi - pos);
    const uint32_t nl = nl0 + p_eq, nr = nr0 + p_eq;
    const float lambda_l = (nl == 0 || nr0 == 0) ? 0.8f : 1.0f;
    const float lambda_r = (nl0 == 0 || nr == 0) ? 0.8f : 1.0f;
    const float cost_l = lambda_l * (sp->ct + sp->ci * (al * (float)nl + ar * (float)nr0));
    const float cost_r = lambda_r * (sp->ct + sp->ci * (al * (float)nl0 + ar * (float)nr));
    return cost_l < cost_r ? cost_l : cost_r;
}

#if defined(__SSE2__)
/* price_plane for four planes, each step the scalar form's in the same
 * order (SSE2 has no fused multiply-add, and neither has the scalar code),
 * so the costs are the same floats. */
static inline __m128 price_planes4(__m128 pos, __m128i nl0, __m128i nr0, __m128i p_eq, const sweep_prices *sp)
{
    const __m128i zero = _mm_setzero_si128();
    const __m128 bonus = _mm_set1_ps(0.8f), one = _mm_set1_ps(1.0f);
    const __m128 face = _mm_set1_ps(sp->face), rim = _mm_set1_ps(sp->rim), ct = _mm_set1_ps(sp->ct), ci = _mm_set1_ps(sp->ci);
    const __m128i nl = _mm_add_epi32(nl0, p_eq), nr = _mm_add_epi32(nr0, p_eq);
    const __m128 al = _mm_add_ps(face, _mm_mul_ps(rim, _mm_sub_ps(pos, _mm_set1_ps(sp->lo))));
    const __m128 ar = _mm_add_ps(face, _mm_mul_ps(rim, _mm_sub_ps(_mm_set1_ps(sp->hi), pos)));
    const __m128i empty_l = _mm_or_si128(_mm_cmpeq_epi32(nl, zero), _mm_cmpeq_epi32(nr0, zero));
    const __m128i empty_r = _mm_or_si128(_mm_cmpeq_epi32(nl0, zero), _mm_cmpeq_epi32(nr, zero));
    const __m128 lambda_l = _mm_or_ps(_mm_and_ps(_mm_castsi128_ps(empty_l), bonus), _mm_andnot_ps(_mm_castsi128_ps(empty_l), one));
    const __m128 lambda_r = _mm_or_ps(_mm_and_ps(_mm_castsi128_ps(empty_r), bonus), _mm_andnot_ps(_mm_castsi128_ps(empty_r), one));
    const __m128 cost_l = _mm_mul_ps(
        lambda_l, _mm_add_ps(ct, _mm_mul_ps(ci, _mm_add_ps(_mm_mul_ps(al, _mm_cvtepi32_ps(nl)), _mm_mul_ps(ar, _mm_cvtepi32_ps(nr0))))));
    const __m128 cost_r = _mm_mul_ps(
        lambda_r, _mm_add_ps(ct, _mm_mul_ps(ci, _mm_add_ps(_mm_mul_ps(al, _mm_cvtepi32_ps(nl0)), _mm_mul_ps(ar, _mm_cvtepi32_ps(nr))))));
    return _mm_min_ps(cost_l, cost_r);
}

/* The lowest of four costs. */
static inline float lowest4(__m128 v)
{
    v = _mm_min_ps(v, _mm_shuffle_ps(v, v, _MM_SHUFFLE(1, 0, 3, 2)));
    v = _mm_min_ps(v, _mm_shuffle_ps(v, v, _MM_SHUFFLE(2, 3, 0, 1)));
    return _mm_cvtss_f32(v);
}
#endif

#if defined(KD_AVX2)
/* price_planes4's steps for eight planes (without fused multiply-adds: the
 * function may use AVX2, not FMA), so the costs are the same floats. */
__attribute__((target("avx2"))) static inline __m256 price_planes8(__m256 pos, __m256i nl0, __m256i nr0, __m256i p_eq,
                                                                   const sweep_prices *sp)
{
    const __m256i zero = _mm256_setzero_si256();
    const __m256 bonus = _mm256_set1_ps(0.8f), one = _mm256_set1_ps(1.0f);
    const __m256 face = _mm256_set1_ps(sp->face), rim = _mm256_set1_ps(sp->rim), ct = _mm256_set1_ps(sp->ct),
                 ci = _mm256_set1_ps(sp->ci);
    const __m256i nl = _mm256_add_epi32(nl0, p_eq), nr = _mm256_add_epi32(nr0, p_eq);
    const __m256 al = _mm256_add_ps(face, _mm256_mul_ps(rim, _mm256_sub_ps(pos, _mm256_set1_ps(sp->lo))));
    const __m256 ar = _mm256_add_ps(face, _mm256_mul_ps(rim, _mm256_sub_ps(_mm256_set1_ps(sp->hi), pos)));
    const __m256i empty_l = _mm256_or_si256(_mm256_cmpeq_epi32(nl, zero), _mm256_cmpeq_epi32(nr0, zero));
    const __m256i empty_r = _mm256_or_si256(_mm256_cmpeq_epi32(nl0, zero), _mm256_cmpeq_epi32(nr, zero));
    const __m256 lambda_l = _mm256_blendv_ps(one, bonus, _mm256_castsi256_ps(empty_l));
    const __m256 lambda_r = _mm256_blendv_ps(one, bonus, _mm256_castsi256_ps(empty_r));
    const __m256 cost_l = _mm256_mul_ps(
        lambda_l, _mm256_add_ps(ct, _mm256_mul_ps(ci, _mm256_add_ps(_mm256_mul_ps(al, _mm256_cvtepi32_ps(nl)),
                                                                     _mm256_mul_ps(ar, _mm256_cvtepi32_ps(nr0))))));
    const __m256 cost_r = _mm256_mul_ps(
        lambda_r, _mm256_add_ps(ct, _mm256_mul_ps(ci, _mm256_add_ps(_mm256_mul_ps(al, _mm256_cvtepi32_ps(nl0)),
                                                                     _mm256_mul_ps(ar, _mm256_cvtepi32_ps(nr))))));
    return _mm256_min_ps(cost_l, cost_r);
}

#endif

/* Pass 2 of sweep_range: the single-precision cost of groups 1 .. k-1 of g
 * into g->cost (infinite for planes on the node's faces), and the lowest. */
static float price_groups(sweep_chunk *g, size_t k, const sweep_prices *sp)
{
#if defined(__SSE2__)
    /* Four groups at a time. The groups past the last are copies of it on
     * the low face, so they price as infinite. */
    for (size_t j = 0; j < 3; ++j) {
        g->key_events[k + j] = ((uint64_t)sp->key_lo << 32) | (uint32_t)g->key_events[k - 1];
        g->counts[k + j] = g->counts[k - 1];
    }
    const __m128i sign = _mm_set1_epi32((int)0x80000000u), ones = _mm_set1_epi32(-1);
    const __m128i np_total = _mm_set1_epi32((int)sp->np_total), p_total = _mm_set1_epi32((int)sp->p_total);
    const __m128i key_lo = _mm_xor_si128(_mm_set1_epi32((int)sp->key_lo), sign);
    const __m128i key_hi = _mm_xor_si128(_mm_set1_epi32((int)sp->key_hi), sign);
    const __m128 inf = _mm_set1_ps(INFINITY);
    __m128 low = inf;
#define LOW_HALVES(a, b) _mm_castps_si128(_mm_shuffle_ps(_mm_castsi128_ps(a), _mm_castsi128_ps(b), _MM_SHUFFLE(2, 0, 2, 0)))
#define HIGH_HALVES(a, b) _mm_castps_si128(_mm_shuffle_ps(_mm_castsi128_ps(a), _mm_castsi128_ps(b), _MM_SHUFFLE(3, 1, 3, 1)))
    for (size_t q = 1; q < k; q += 4) {
        const __m128i ke0 = _mm_loadu_si128((const __m128i *)&g->key_events[q]);
        const __m128i ke1 = _mm_loadu_si128((const __m128i *)&g->key_events[q + 2]);
        const __m128i kp0 = _mm_loadu_si128((const __m128i *)&g->key_events[q - 1]);
        const __m128i kp1 = _mm_loadu_si128((const __m128i *)&g->key_events[q + 1]);
        const __m128i c0 = _mm_loadu_si128((const __m128i *)&g->counts[q]);
        const __m128i c1 = _mm_loadu_si128((const __m128i *)&g->counts[q + 2]);
        const __m128i cp0 = _mm_loadu_si128((const __m128i *)&g->counts[q - 1]);
        const __m128i cp1 = _mm_loadu_si128((const __m128i *)&g->counts[q + 1]);
        const __m128i key = HIGH_HALVES(ke0, ke1), events = LOW_HALVES(ke0, ke1), events_before = LOW_HALVES(kp0, kp1);
        const __m128i ends = LOW_HALVES(c0, c1), planars = HIGH_HALVES(c0, c1);
        const __m128i ends_before = LOW_HALVES(cp0, cp1), planars_before = HIGH_HALVES(cp0, cp1);
        /* group_sides, lane by lane. */
        const __m128i p = _mm_sub_epi32(planars, planars_before), e_eq = _mm_sub_epi32(ends, ends_before);
        const __m128i s_eq = _mm_sub_epi32(_mm_sub_epi32(_mm_sub_epi32(events, events_before), e_eq), p);
        const __m128i nl0 = _mm_add_epi32(_mm_sub_epi32(events_before, ends_before), s_eq);
        const __m128i nr0 =
            _mm_add_epi32(_mm_add_epi32(_mm_sub_epi32(np_total, ends), _mm_sub_epi32(p_total, planars)), e_eq);
        /* key_float: the bits of a negative position are the key's
         * complement, those of a positive one the key without its top bit. */
        const __m128i negative = _mm_srai_epi32(key, 31);
        const __m128 pos = _mm_castsi128_ps(_mm_or_si128(_mm_and_si128(negative, _mm_andnot_si128(sign, key)),
                                                         _mm_andnot_si128(negative, _mm_xor_si128(key, ones))));
        const __m128i signed_key = _mm_xor_si128(key, sign);
        const __m128 inside =
            _mm_castsi128_ps(_mm_and_si128(_mm_cmpgt_epi32(signed_key, key_lo), _mm_cmplt_epi32(signed_key, key_hi)));
        const __m128 cost =
            _mm_or_ps(_mm_and_ps(inside, price_planes4(pos, nl0, nr0, p, sp)), _mm_andnot_ps(inside, inf));
        _mm_storeu_ps(&g->cost[q], cost);
        low = _mm_min_ps(low, cost);
    }
#undef LOW_HALVES
#undef HIGH_HALVES
    return lowest4(low);
#else
    float low = INFINITY;
    for (size_t q = 1; q < k; ++q) {
        const uint32_t key = (uint32_t)(g->key_events[q] >> 32);
        uint32_t nl0, nr0, p_eq;
        group_sides(g, q, sp->np_total, sp->p_total, &nl0, &nr0, &p_eq);
        g->cost[q] = (key > sp->key_lo && key < sp->key_hi) ? price_plane(key_float(key), nl0, nr0, p_eq, sp) : INFINITY;
        low = g->cost[q] < low ? g->cost[q] : low;
    }
    return low;
#endif
}

#if defined(KD_AVX2)
/* price_groups eight groups at a time, with AVX2: the same steps in the
 * lanes (price_planes8), so the same costs. The halves of the 64-bit words
 * are taken within each 128-bit lane, which orders the groups 0, 1, 4, 5,
 * 2, 3, 6, 7; the costs are put back in order before they are stored. */
__attribute__((target("avx2"))) static float price_groups_avx2(sweep_chunk *g, size_t k, const sweep_prices *sp)
{
    for (size_t j = 0; j < 7; ++j) {
        g->key_events[k + j] = ((uint64_t)sp->key_lo << 32) | (uint32_t)g->key_events[k - 1];
        g->counts[k + j] = g->counts[k - 1];
    }
    const __m256i sign = _mm256_set1_epi32((int)0x80000000u), ones = _mm256_set1_epi32(-1);
    const __m256i np_total = _mm256_set1_epi32((int)sp->np_total), p_total = _mm256_set1_epi32((int)sp->p_total);
    const __m256i key_lo = _mm256_xor_si256(_mm256_set1_epi32((int)sp->key_lo), sign);
    const __m256i key_hi = _mm256_xor_si256(_mm256_set1_epi32((int)sp->key_hi), sign);
    const __m256i in_order = _mm256_setr_epi32(0, 1, 4, 5, 2, 3, 6, 7);
    const __m256 inf = _mm256_set1_ps(INFINITY);
    __m256 low = inf;
#define LOW_HALVES8(a, b) _mm256_castps_si256(_mm256_shuffle_ps(_mm256_castsi256_ps(a), _mm256_castsi256_ps(b), _MM_SHUFFLE(2, 0, 2, 0)))
#define HIGH_HALVES8(a, b) _mm256_castps_si256(_mm256_shuffle_ps(_mm256_castsi256_ps(a), _mm256_castsi256_ps(b), _MM_SHUFFLE(3, 1, 3, 1)))
    for (size_t q = 1; q < k; q += 8) {
        const __m256i ke0 = _mm256_loadu_si256((const __m256i *)&g->key_events[q]);
        const __m256i ke1 = _mm256_loadu_si256((const __m256i *)&g->key_events[q + 4]);
        const __m256i kp0 = _mm256_loadu_si256((const __m256i *)&g->key_events[q - 1]);
        const __m256i kp1 = _mm256_loadu_si256((const __m256i *)&g->key_events[q + 3]);
        const __m256i c0 = _mm256_loadu_si256((const __m256i *)&g->counts[q]);
        const __m256i c1 = _mm256_loadu_si256((const __m256i *)&g->counts[q + 4]);
        const __m256i cp0 = _mm256_loadu_si256((const __m256i *)&g->counts[q - 1]);
        const __m256i cp1 = _mm256_loadu_si256((const __m256i *)&g->counts[q + 3]);
        const __m256i key = HIGH_HALVES8(ke0, ke1), events = LOW_HALVES8(ke0, ke1), events_before = LOW_HALVES8(kp0, kp1);
        const __m256i ends = LOW_HALVES8(c0, c1), planars = HIGH_HALVES8(c0, c1);
        const __m256i ends_before = LOW_HALVES8(cp0, cp1), planars_before = HIGH_HALVES8(cp0, cp1);
        /* group_sides, lane by lane. */
        const __m256i p = _mm256_sub_epi32(planars, planars_before), e_eq = _mm256_sub_epi32(ends, ends_before);
        const __m256i s_eq = _mm256_sub_epi32(_mm256_sub_epi32(_mm256_sub_epi32(events, events_before), e_eq), p);
        const __m256i nl0 = _mm256_add_epi32(_mm256_sub_epi32(events_before, ends_before), s_eq);
        const __m256i nr0 =
            _mm256_add_epi32(_mm256_add_epi32(_mm256_sub_epi32(np_total, ends), _mm256_sub_epi32(p_total, planars)), e_eq);
        /* key_float. */
        const __m256i negative = _mm256_srai_epi32(key, 31);
        const __m256 pos = _mm256_castsi256_ps(_mm256_or_si256(_mm256_and_si256(negative, _mm256_andnot_si256(sign, key)),
                                                               _mm256_andnot_si256(negative, _mm256_xor_si256(key, ones))));
        const __m256i signed_key = _mm256_xor_si256(key, sign);
        const __m256 inside = _mm256_castsi256_ps(
            _mm256_and_si256(_mm256_cmpgt_epi32(signed_key, key_lo), _mm256_cmpgt_epi32(key_hi, signed_key)));
        const __m256 cost = _mm256_permutevar8x32_ps(_mm256_blendv_ps(inf, price_planes8(pos, nl0, nr0, p, sp), inside), in_order);
        _mm256_storeu_ps(&g->cost[q], cost);
        low = _mm256_min_ps(low, cost);
    }
#undef LOW_HALVES8
#undef HIGH_HALVES8
    return lowest4(_mm_min_ps(_mm256_castps256_ps128(low), _mm256_extractf128_ps(low, 1)));
}
#endif

/* The lowest cost found so far and the plane of it. */
typedef struct sweep_best {
    double cost, threshold; /* groups priced above threshold in single precision cannot beat cost */
    float pos;
    int planar_left, found;
    uint32_t count[2];
} sweep_best;

/* What the exact price of a plane needs of its axis and node. */
typedef struct exact_prices {
    double face, rim, lo, hi, ct, ci;
} exact_prices;

/* Whether a plane of this cost at pos replaces the best: cheaper, or as
 * cheap and lower. The sweep meets planes in increasing order, so there a
 * plane replaces only a dearer one; the small nodes' chooser meets them in
 * any order, and the rule gives it the sweep's plane. */
static inline int plane_wins(const sweep_best *b, double cost, float pos)
{
    return cost < b->cost || (b->found && cost == b->cost && pos < b->pos);
}

/* b's threshold rounded up to a float, to test four single-precision costs
 * in one compare: a looser test, each cost that passes is tested again
 * exactly. */
static inline float threshold_float(const sweep_best *b)
{
    const float t = (float)b->threshold;
    return (double)t < b->threshold ? as_float_next_up(t) : t;
}

/* The exact cost, in double precision, of the plane at pos with nl0
 * references below, nr0 above and p_eq in it, those first below, then
 * above (without any, both cost the same and the second is never lower),
 * taken into b when it wins. */
static inline void price_plane_exactly(float pos, uint32_t nl0, uint32_t nr0, uint32_t p_eq, const exact_prices *ep,
                                       sweep_best *b)
{
    const double al = ep->face + ep->rim * ((double)pos - ep->lo), ar = ep->face + ep->rim * (ep->hi - (double)pos);
    const uint32_t nl = nl0 + p_eq;
    const double lambda = (nl == 0 || nr0 == 0) ? 0.8 : 1.0;
    const double cost = lambda * (ep->ct + ep->ci * (al * nl + ar * nr0));
    /* The counts priced are the children's sizes: kept for the driver,
     * which then need not count them. */
    if (plane_wins(b, cost, pos)) {
        b->cost = cost;
        b->pos = pos;
        b->planar_left = 1;
        b->count[0] = nl;
        b->count[1] = nr0;
        b->found = 1;
    }
    const uint32_t nr = nr0 + p_eq;
    const double lambda_r = (nl0 == 0 || nr == 0) ? 0.8 : 1.0;
    const double cost_r = lambda_r * (ep->ct + ep->ci * (al * nl0 + ar * nr));
    if (plane_wins(b, cost_r, pos)) {
        b->cost = cost_r;
        b->pos = pos;
        b->planar_left = 0;
        b->count[0] = nl0;
        b->count[1] = nr;
        b->found = 1;
    }
    if (b->cost * (1.0 + SWEEP_MARGIN) < b->threshold) b->threshold = b->cost * (1.0 + SWEEP_MARGIN);
}

/* The prices of planes on one axis of a node with half area `area`, in
 * single precision (sp; its counts are the caller's) and exactly (ep);
 * returns whether the single-precision price may filter the planes. */
static inline int axis_prices(const float box[6], int axis, double area, double ct, double ci, sweep_prices *sp,
                              exact_prices *ep)
{
    /* A side's half area is linear in the plane's position: the face across
     * the axis plus the perimeter of that face times the side's length
     * along it. */
    const int a1 = (axis + 1) % 3, a2 = (axis + 2) % 3;
    const double e1 = (double)box[a1 + 3] - box[a1], e2 = (double)box[a2 + 3] - box[a2];
    const double face = e1 * e2 / area, rim = (e1 + e2) / area;
    *ep = (exact_prices){face, rim, box[axis], box[axis + 3], ct, ci};
    sp->face = (float)face;
    sp->rim = (float)rim;
    sp->lo = box[axis];
    sp->hi = box[axis + 3];
    sp->ct = (float)ct;
    sp->ci = (float)ci;
    sp->key_lo = float_key(box[axis]);
    sp->key_hi = float_key(box[axis + 3]);
    /* The single-precision bound needs every term within float's normal
     * range: the costs near 1, and a box not so thin along the axis that
     * the perimeter term (1 / its width, at most) overflows. Each side's
     * area term is at most 2, and a traversal cost of at least 1e-12 keeps
     * a cost from being only a tiny area term (one side empty, the plane
     * near a face), whose relative error in single precision has no bound.
     * Otherwise every plane is priced exactly. */
    return ci >= 1e-12 && ci <= 1e12 && ct >= 1e-12 && ct <= 1e12 && rim < 1e30;
}

/* Pass 3 of sweep_range for group q: its exact cost, unless its
 * single-precision cost shows it cannot beat the best. */
static inline void price_group_exactly(const sweep_chunk *g, size_t q, const sweep_prices *sp, const exact_prices *ep,
                                       int filter, sweep_best *b)
{
    const uint32_t key = (uint32_t)(g->key_events[q] >> 32);
    if (!(key > sp->key_lo && key < sp->key_hi) || (filter && !((double)g->cost[q] <= b->threshold))) return;
    uint32_t nl0, nr0, p_eq;
    group_sides(g, q, sp->np_total, sp->p_total, &nl0, &nr0, &p_eq);
    price_plane_exactly(key_float(key), nl0, nr0, p_eq, ep, b);
}

/* Pass 1 of sweep_range over events [c, c_end): each group's last event
 * and counts into g from index k on, *counts running; returns the next k. */
static size_t sweep_groups(const uint64_t *ev, size_t c, size_t c_end, size_t k, uint64_t *counts_io, sweep_chunk *g)
{
    uint64_t counts = *counts_io;
    uint64_t e = ev[c];
    for (size_t i = c; i < c_end; ++i) {
        const uint64_t next = ev[i + 1]; /* the sentinel ends the last group */
        counts += sweep_count_step[event_kind(e)];
        g->key_events[k] = (e & 0xffffffff00000000u) | (uint32_t)(i + 1);
        g->counts[k] = counts;
        k += event_key(next) != event_key(e);
        e = next;
    }
    *counts_io = counts;
    return k;
}

#if defined(KD_AVX2)
/* sweep_groups four events at a time: the counts summed across the lanes,
 * and the lanes that end a group packed by a permutation (a group's last
 * event is the one the plain form leaves in its slot). */
__attribute__((target("avx2"))) static size_t sweep_groups_avx2(const uint64_t *ev, size_t c, size_t c_end, size_t k,
                                                                uint64_t *counts_io, sweep_chunk *g)
{
    const __m256i zero = _mm256_setzero_si256(), kind_mask = _mm256_set1_epi64x(3);
    const __m256i end_step = _mm256_set1_epi64x(1), planar_step = _mm256_set1_epi64x((int64_t)1 << 32);
    const __m256i key_mask = _mm256_set1_epi64x((int64_t)0xffffffff00000000u), lane = _mm256_setr_epi64x(1, 2, 3, 4);
    __m256i counts = _mm256_set1_epi64x((int64_t)*counts_io);
    size_t i = c;
    for (; i + 4 <= c_end; i += 4) {
        /* As in kept_runs_avx2: the list asked for ahead of the sweep. */
        _mm_prefetch((const char *)(ev + i + 96), _MM_HINT_T0);
        const __m256i e = _mm256_loadu_si256((const __m256i *)(ev + i));
        const __m256i next = _mm256_loadu_si256((const __m256i *)(ev + i + 1));
        const __m256i kind = _mm256_and_si256(_mm256_srli_epi64(e, EV_INDEX_BITS), kind_mask);
        __m256i step = _mm256_or_si256(_mm256_and_si256(_mm256_cmpeq_epi64(kind, zero), end_step),
                                       _mm256_and_si256(_mm256_cmpeq_epi64(kind, end_step), planar_step));
        /* Inclusive sums across the four lanes, then the running count. */
        step = _mm256_add_epi64(step, _mm256_blend_epi32(_mm256_permute4x64_epi64(step, _MM_SHUFFLE(2, 1, 0, 0)), zero, 0x03));
        step = _mm256_add_epi64(step, _mm256_blend_epi32(_mm256_permute4x64_epi64(step, _MM_SHUFFLE(1, 0, 0, 0)), zero, 0x0f));
        const __m256i sums = _mm256_add_epi64(step, counts);
        counts = _mm256_permute4x64_epi64(sums, _MM_SHUFFLE(3, 3, 3, 3));
        const __m256i key_events =
            _mm256_or_si256(_mm256_and_si256(e, key_mask), _mm256_add_epi64(lane, _mm256_set1_epi64x((int64_t)i)));
        const __m256i same = _mm256_cmpeq_epi64(_mm256_srli_epi64(_mm256_xor_si256(e, next), 32), zero);
        const int ends = ~_mm256_movemask_pd(_mm256_castsi256_pd(same)) & 0xf;
        const __m256i pack = _mm256_loadu_si256((const __m256i *)kept_pack4[ends]);
        _mm256_storeu_si256((__m256i *)&g->key_events[k], _mm256_permutevar8x32_epi32(key_events, pack));
        _mm256_storeu_si256((__m256i *)&g->counts[k], _mm256_permutevar8x32_epi32(sums, pack));
        k += (size_t)__builtin_popcount((unsigned)ends);
    }
    *counts_io = (uint64_t)_mm256_extract_epi64(counts, 0);
    return i < c_end ? sweep_groups(ev, i, c_end, k, counts_io, g) : k;
}
#endif

/* Sweeps events [begin, end) of the axis's list, which start a group and
 * end one, with `ends0` END and `planars0` PLANAR events before them, into
 * *b: the first plane of the lowest cost below the limit. */
static void sweep_range(const choose_job *cj, int axis, size_t begin, size_t end, uint32_t ends0, uint32_t planars0,
                        axis_best *b)
{
    const float *box = cj->box;
    const double ct = cj->ct, ci = cj->ci, area = cj->area;
    const uint64_t *ev = cj->e->list[axis];
    const size_t m = cj->e->count[axis];
    sweep_prices sp;
    exact_prices ep;
    const int filter = axis_prices(box, axis, area, ct, ci, &sp, &ep);
    sp.p_total = (uint32_t)(2 * (size_t)cj->e->n - m);
    sp.np_total = (uint32_t)(m - cj->e->n);
    sweep_best best = {cj->limit, cj->limit * (1.0 + SWEEP_MARGIN), 0.0f, 0, 0, {0, 0}};
    sweep_chunk g;
    uint64_t counts = ((uint64_t)planars0 << 32) | ends0;
#if defined(KD_AVX2)
    const int avx2 = as_cpu_has_avx2();
#endif
    g.key_events[0] = begin;
    g.counts[0] = counts;
    for (size_t c = begin; c < end; c += SWEEP_CHUNK) {
        const size_t c_end = end - c < SWEEP_CHUNK ? end : c + SWEEP_CHUNK;
#if defined(KD_AVX2)
        const size_t k = avx2 ? sweep_groups_avx2(ev, c, c_end, 1, &counts, &g) : sweep_groups(ev, c, c_end, 1, &counts, &g);
#else
        const size_t k = sweep_groups(ev, c, c_end, 1, &counts, &g);
#endif
        /* Only groups near the chunk's lowest can hold its best plane. */
#if defined(KD_AVX2)
        const float chunk_low = avx2 ? price_groups_avx2(&g, k, &sp) : price_groups(&g, k, &sp);
#else
        const float chunk_low = price_groups(&g, k, &sp);
#endif
        const double chunk_threshold = (double)chunk_low * (1.0 + SWEEP_MARGIN);
        if (chunk_threshold < best.threshold) best.threshold = chunk_threshold;
#if defined(__SSE2__)
        if (filter) {
            /* Four groups' single-precision costs against the threshold
             * (rounded up to a float: a looser test, each passing group is
             * tested again exactly) in one compare; most fail. */
            for (size_t q = 1; q < k; q += 4) {
                unsigned lanes =
                    (unsigned)_mm_movemask_ps(_mm_cmple_ps(_mm_loadu_ps(&g.cost[q]), _mm_set1_ps(threshold_float(&best))));
                if (k - q < 4) lanes &= (1u << (k - q)) - 1u;
                while (lanes) {
                    const size_t at = q + (size_t)__builtin_ctz(lanes);
                    lanes &= lanes - 1u;
                    price_group_exactly(&g, at, &sp, &ep, filter, &best);
                }
            }
        } else
#endif
            for (size_t q = 1; q < k; ++q) price_group_exactly(&g, q, &sp, &ep, filter, &best);
        g.key_events[0] = g.key_events[k - 1];
        g.counts[0] = g.counts[k - 1];
    }
    b->cost = best.cost;
    b->pos = best.pos;
    b->planar_left = best.planar_left;
    b->found = best.found;
    b->count[0] = best.count[0];
    b->count[1] = best.count[1];
}

static void sweep_axis(void *user, int axis)
{
    choose_job *cj = user;
    const float *box = cj->box;
    if (!(box[axis + 3] > box[axis])) {
        cj->best[axis].cost = cj->limit;
        cj->best[axis].found = 0;
        return;
    }
    sweep_range(cj, axis, 0, cj->e->count[axis], 0, 0, &cj->best[axis]);
}

/* A big node's sweep on many threads: each axis's list in pieces that
 * start at a group, each piece's END and PLANAR events counted, then every
 * piece swept from the counts before it. Taking the pieces' planes in order,
 * a later one only when strictly cheaper, gives the plane of one sweep over
 * the list, so the split does not depend on the number of pieces. */

typedef struct sweep_pieces {
    choose_job *cj;
    unsigned per_axis;
    size_t begin[3][PIECES_MAX + 1];
    uint32_t ends[3][PIECES_MAX], planars[3][PIECES_MAX];
    axis_best best[3][PIECES_MAX];
} sweep_pieces;

static void sweep_piece_count(void *user, unsigned i, unsigned n)
{
    sweep_pieces *sp = user;
    for (unsigned job = i; job < 3 * sp->per_axis; job += n) {
        const int axis = (int)(job % 3);
        const unsigned piece = job / 3;
        const uint64_t *ev = sp->cj->e->list[axis];
        uint32_t ends = 0, planars = 0;
        for (size_t k = sp->begin[axis][piece]; k < sp->begin[axis][piece + 1]; ++k) {
            const int kind = event_kind(ev[k]);
            ends += kind == EV_END;
            planars += kind == EV_PLANAR;
        }
        sp->ends[axis][piece] = ends;
        sp->planars[axis][piece] = planars;
    }
}

static void sweep_piece_run(void *user, unsigned i, unsigned n)
{
    sweep_pieces *sp = user;
    for (unsigned job = i; job < 3 * sp->per_axis; job += n) {
        const int axis = (int)(job % 3);
        const unsigned piece = job / 3;
        axis_best *b = &sp->best[axis][piece];
        if (!(sp->cj->box[axis + 3] > sp->cj->box[axis])) {
            b->cost = sp->cj->limit;
            b->found = 0;
            continue;
        }
        sweep_range(sp->cj, axis, sp->begin[axis][piece], sp->begin[axis][piece + 1], sp->ends[axis][piece],
                    sp->planars[axis][piece], b);
    }
}

static void sweep_in_pieces(choose_job *cj, unsigned threads, unsigned per_axis)
{
    sweep_pieces *sp = malloc(sizeof *sp);
    if (!sp) {
        for_each_axis(threads < 3 ? threads : 3, sweep_axis, cj);
        return;
    }
    sp->cj = cj;
    sp->per_axis = per_axis;
    for (int axis = 0; axis < 3; ++axis) {
        const uint64_t *ev = cj->e->list[axis];
        const size_t m = cj->e->count[axis];
        sp->begin[axis][0] = 0;
        for (unsigned piece = 1; piece < per_axis; ++piece) {
            size_t b = m * piece / per_axis;
            if (b < sp->begin[axis][piece - 1]) b = sp->begin[axis][piece - 1];
            while (b > 0 && b < m && event_key(ev[b]) == event_key(ev[b - 1])) ++b;
            sp->begin[axis][piece] = b;
        }
        sp->begin[axis][per_axis] = m;
    }
    as_parallel_run(threads, sweep_piece_count, sp);
    /* Each piece starts from the counts of the pieces before it. */
    for (int axis = 0; axis < 3; ++axis) {
        uint32_t ends = 0, planars = 0;
        for (unsigned piece = 0; piece < per_axis; ++piece) {
            const uint32_t e = sp->ends[axis][piece], p = sp->planars[axis][piece];
            sp->ends[axis][piece] = ends;
            sp->planars[axis][piece] = planars;
            ends += e;
            planars += p;
        }
    }
    as_parallel_run(threads, sweep_piece_run, sp);
    for (int axis = 0; axis < 3; ++axis) {
        axis_best *b = &cj->best[axis];
        b->cost = cj->limit;
        b->found = 0;
        for (unsigned piece = 0; piece < per_axis; ++piece) {
            const axis_best *q = &sp->best[axis][piece];
            if (q->found && q->cost < b->cost) *b = *q;
        }
    }
    free(sp);
}

/* A node of at most SMALL_NODE_REFS references gets no event lists from
 * its parent: its plane is chosen from its references themselves. Every
 * candidate (a bound of a reference strictly inside the box) is counted
 * against every reference, eight or four candidates in one vector compare,
 * which for so few references costs less than the lists that the sweep
 * would read and that the parent would have to make and sort. The plane is
 * the sweep's: the same counts and costs, and ties resolved as the sweep
 * resolves them (the lowest position, triangles in the plane below before
 * above, the lowest axis); the order in which candidates are priced does
 * not change it. */
#define SMALL_CANDIDATES (2 * SMALL_NODE_REFS)

/* A position's key as a signed integer: float_key with its top bit
 * flipped, so that signed integer compares, which the vector units have
 * for every width, order positions as the sweep's keys do (-0 as 0). */
static inline int32_t small_key(float f)
{
    const uint32_t b = as_float_as_uint(f), m = b & 0x7fffffffu;
    return (int32_t)((b >> 31) && m ? ~m : m);
}

static inline float small_key_float(int32_t k)
{
    return as_uint_as_float(k < 0 ? ~(uint32_t)k | 0x80000000u : (uint32_t)k);
}

/* One axis of a small node. Per reference, the keys of its bounds on the
 * axis; a flat one's (a PLANAR event) are moved one step apart, its low
 * key one above its position and its high key one below, so that for
 * every reference "below a plane at key c" is lo <= c, "above" is
 * hi >= c, and "in the plane" is lo > c and hi < c (which a reference with
 * extent never is). */
typedef struct small_axis {
    int32_t lo[SMALL_NODE_REFS], hi[SMALL_NODE_REFS];
    uint32_t n_flat;
    /* The candidates' keys; room for two vector blocks past the last. */
    int32_t cand[SMALL_CANDIDATES + 16];
    uint32_t n_cand;
    /* Per candidate: the counts the sweep's group gives (below, above, in
     * the plane), and its single-precision cost. */
    uint32_t nl0[SMALL_CANDIDATES + 16], nr0[SMALL_CANDIDATES + 16], in_plane[SMALL_CANDIDATES + 16];
    float cost[SMALL_CANDIDATES + 16];
} small_axis;

/* The three axes of a small node from its references: each reference's
 * keys, and those of its bounds strictly inside the box as candidates
 * (a flat reference's one position once). */
static void small_axes_fill(small_axis axes[3], const kd_ref *refs, uint32_t n, const float box[6])
{
    for (int a = 0; a < 3; ++a) {
        small_axis *s = &axes[a];
        const int32_t box_lo = small_key(box[a]), box_hi = small_key(box[a + 3]);
        uint32_t n_flat = 0, n_cand = 0;
        for (uint32_t i = 0; i < n; ++i) {
            const int32_t kl = small_key(refs[i].lo[a]), kh = small_key(refs[i].hi[a]);
            const int32_t flat = kl == kh;
            s->lo[i] = kl + flat;
            s->hi[i] = kh - flat;
            n_flat += (uint32_t)flat;
            s->cand[n_cand] = kl;
            n_cand += (uint32_t)((kl > box_lo) & (kl < box_hi));
            s->cand[n_cand] = kh;
            n_cand += (uint32_t)((flat ^ 1) & (kh > box_lo) & (kh < box_hi));
        }
        s->n_flat = n_flat;
        s->n_cand = n_cand;
    }
}

/* Counts and single-precision costs of every candidate of s against the
 * node's n references, the lowest returned; `sp` as for a sweep (key_lo,
 * key_hi unused). The plain form; the vector forms below take the same
 * steps in their lanes. */
static float price_small_axis_plain(small_axis *s, uint32_t n, const sweep_prices *sp)
{
    float low = INFINITY;
    for (uint32_t j = 0; j < s->n_cand; ++j) {
        const int32_t c = s->cand[j];
        uint32_t nl0 = 0, nr0 = 0, p_eq = 0;
        for (uint32_t k = 0; k < n; ++k) {
            nl0 += s->lo[k] <= c;
            nr0 += s->hi[k] >= c;
            p_eq += (s->lo[k] > c) & (s->hi[k] < c);
        }
        s->cost[j] = price_plane(small_key_float(c), nl0, nr0, p_eq, sp);
        s->nl0[j] = nl0;
        s->nr0[j] = nr0;
        s->in_plane[j] = p_eq;
        low = s->cost[j] < low ? s->cost[j] : low;
    }
    /* As the vector forms: whole blocks priced, those past the last
     * candidate infinite. */
    for (uint32_t j = s->n_cand; j < s->n_cand + 16; ++j) s->cost[j] = INFINITY;
    return low;
}

#if defined(__SSE2__)
/* small_key_float in every lane. */
static inline __m128 small_key_floats4(__m128i k)
{
    return _mm_castsi128_ps(_mm_xor_si128(k, _mm_and_si128(_mm_srai_epi32(k, 31), _mm_set1_epi32(0x7fffffff))));
}

/* The prices of four candidates with their counts, into s at j. */
static inline __m128 price_small_four(small_axis *s, uint32_t j, __m128i c, __m128i nl0, __m128i nr0, __m128i p_eq,
                                      const sweep_prices *sp)
{
    const __m128 inf = _mm_set1_ps(INFINITY);
    /* Lanes past the last candidate price as infinite. */
    const __m128 real = _mm_castsi128_ps(
        _mm_cmplt_epi32(_mm_add_epi32(_mm_set1_epi32((int)j), _mm_set_epi32(3, 2, 1, 0)), _mm_set1_epi32((int)s->n_cand)));
    const __m128 cost =
        _mm_or_ps(_mm_and_ps(real, price_planes4(small_key_floats4(c), nl0, nr0, p_eq, sp)), _mm_andnot_ps(real, inf));
    _mm_storeu_ps(&s->cost[j], cost);
    _mm_storeu_si128((__m128i *)&s->nl0[j], nl0);
    _mm_storeu_si128((__m128i *)&s->nr0[j], nr0);
    _mm_storeu_si128((__m128i *)&s->in_plane[j], p_eq);
    return cost;
}

static float price_small_axis_sse2(small_axis *s, uint32_t n, const sweep_prices *sp)
{
    const __m128i one = _mm_set1_epi32(1), count = _mm_set1_epi32((int)n);
    __m128 low = _mm_set1_ps(INFINITY);
    /* Eight candidates at a time; the masks are -1 where true. */
    for (uint32_t j = 0; j < s->n_cand; j += 8) {
        const __m128i c_a = _mm_loadu_si128((const __m128i *)&s->cand[j]);
        const __m128i c_b = _mm_loadu_si128((const __m128i *)&s->cand[j + 4]);
        const __m128i d_a = _mm_sub_epi32(c_a, one), d_b = _mm_sub_epi32(c_b, one);
        __m128i gt_a = _mm_setzero_si128(), gt_b = gt_a, ge_a = gt_a, ge_b = gt_a, eq_a = gt_a, eq_b = gt_a;
        for (uint32_t k = 0; k < n; ++k) {
            const __m128i lo = _mm_set1_epi32(s->lo[k]), hi = _mm_set1_epi32(s->hi[k]);
            const __m128i l_a = _mm_cmpgt_epi32(lo, c_a), l_b = _mm_cmpgt_epi32(lo, c_b);
            const __m128i h_a = _mm_cmpgt_epi32(hi, d_a), h_b = _mm_cmpgt_epi32(hi, d_b);
            gt_a = _mm_sub_epi32(gt_a, l_a);
            gt_b = _mm_sub_epi32(gt_b, l_b);
            ge_a = _mm_sub_epi32(ge_a, h_a);
            ge_b = _mm_sub_epi32(ge_b, h_b);
            eq_a = _mm_sub_epi32(eq_a, _mm_andnot_si128(h_a, l_a));
            eq_b = _mm_sub_epi32(eq_b, _mm_andnot_si128(h_b, l_b));
        }
        low = _mm_min_ps(low, price_small_four(s, j, c_a, _mm_sub_epi32(count, gt_a), ge_a, eq_a, sp));
        low = _mm_min_ps(low, price_small_four(s, j + 4, c_b, _mm_sub_epi32(count, gt_b), ge_b, eq_b, sp));
    }
    return lowest4(low);
}
#endif

#if defined(KD_AVX2)

/* For each 8-bit lane mask, the indices of its set lanes in order (one
 * byte each): a permutation that packs the lanes a mask keeps. */
static uint64_t small_pack_lanes[256];
static pthread_once_t small_pack_once = PTHREAD_ONCE_INIT;

static void small_pack_init(void)
{
    for (unsigned m = 0; m < 256; ++m) {
        uint64_t v = 0;
        unsigned at = 0;
        for (unsigned l = 0; l < 8; ++l)
            if (m & (1u << l)) v |= (uint64_t)l << (8 * at++);
        small_pack_lanes[m] = v;
    }
}

/* small_key in every lane. */
__attribute__((target("avx2"))) static inline __m256i small_keys8(__m256 f)
{
    const __m256i b = _mm256_castps_si256(f), m = _mm256_and_si256(b, _mm256_set1_epi32(0x7fffffff));
    const __m256i negative = _mm256_andnot_si256(_mm256_cmpeq_epi32(m, _mm256_setzero_si256()), _mm256_srai_epi32(b, 31));
    return _mm256_xor_si256(m, negative);
}

/* The lanes of v that mask keeps, packed, stored at out; returns how many. */
__attribute__((target("avx2"))) static inline uint32_t small_pack8(int32_t *out, __m256i v, __m256i keep)
{
    const unsigned m = (unsigned)_mm256_movemask_ps(_mm256_castsi256_ps(keep));
    const __m256i perm = _mm256_cvtepu8_epi32(_mm_cvtsi64_si128((long long)small_pack_lanes[m]));
    _mm256_storeu_si256((__m256i *)out, _mm256_permutevar8x32_epi32(v, perm));
    return (uint32_t)__builtin_popcount(m);
}

/* small_axes_fill eight references at a time, on processors with AVX2:
 * their bounds loaded as the rows of a matrix and transposed (gathers cost
 * more), the keys made in the lanes, and the candidates packed with a
 * permutation. The same keys and candidates, these in another order. */
__attribute__((target("avx2"))) static void small_axes_fill_avx2(small_axis axes[3], const kd_ref *refs, uint32_t n,
                                                                 const float box[6])
{
    pthread_once(&small_pack_once, small_pack_init);
    const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    uint32_t n_flat[3] = {0, 0, 0}, n_cand[3] = {0, 0, 0};
    __m256i box_lo[3], box_hi[3];
    for (int a = 0; a < 3; ++a) {
        box_lo[a] = _mm256_set1_epi32(small_key(box[a]));
        box_hi[a] = _mm256_set1_epi32(small_key(box[a + 3]));
    }
    for (uint32_t b = 0; b < n; b += 8) {
        /* Lanes past the last reference read nothing and keep nothing. */
        const __m256i real = _mm256_cmpgt_epi32(_mm256_set1_epi32((int)(n - b)), lane);
        /* Eight references' first seven floats as the rows of a matrix
         * (masked loads: nothing read past a reference), transposed. */
        const __m256i seven = _mm256_setr_epi32(-1, -1, -1, -1, -1, -1, -1, 0);
        __m256 row[8];
        for (int j = 0; j < 8; ++j)
            row[j] = b + (uint32_t)j < n ? _mm256_maskload_ps(refs[b + (uint32_t)j].lo, seven) : _mm256_setzero_ps();
        const __m256 t0 = _mm256_unpacklo_ps(row[0], row[1]), t1 = _mm256_unpackhi_ps(row[0], row[1]);
        const __m256 t2 = _mm256_unpacklo_ps(row[2], row[3]), t3 = _mm256_unpackhi_ps(row[2], row[3]);
        const __m256 t4 = _mm256_unpacklo_ps(row[4], row[5]), t5 = _mm256_unpackhi_ps(row[4], row[5]);
        const __m256 t6 = _mm256_unpacklo_ps(row[6], row[7]), t7 = _mm256_unpackhi_ps(row[6], row[7]);
        const __m256 u0 = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(1, 0, 1, 0)), u1 = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(3, 2, 3, 2));
        const __m256 u2 = _mm256_shuffle_ps(t1, t3, _MM_SHUFFLE(1, 0, 1, 0)), u3 = _mm256_shuffle_ps(t1, t3, _MM_SHUFFLE(3, 2, 3, 2));
        const __m256 u4 = _mm256_shuffle_ps(t4, t6, _MM_SHUFFLE(1, 0, 1, 0)), u5 = _mm256_shuffle_ps(t4, t6, _MM_SHUFFLE(3, 2, 3, 2));
        const __m256 u6 = _mm256_shuffle_ps(t5, t7, _MM_SHUFFLE(1, 0, 1, 0)), u7 = _mm256_shuffle_ps(t5, t7, _MM_SHUFFLE(3, 2, 3, 2));
        __m256 col[6];
        col[0] = _mm256_permute2f128_ps(u0, u4, 0x20); /* lo x */
        col[1] = _mm256_permute2f128_ps(u1, u5, 0x20); /* lo y */
        col[2] = _mm256_permute2f128_ps(u2, u6, 0x20); /* lo z */
        col[3] = _mm256_permute2f128_ps(u3, u7, 0x20); /* hi x */
        col[4] = _mm256_permute2f128_ps(u0, u4, 0x31); /* hi y */
        col[5] = _mm256_permute2f128_ps(u1, u5, 0x31); /* hi z */
        for (int a = 0; a < 3; ++a) {
            small_axis *s = &axes[a];
            const __m256 lo = col[a], hi = col[a + 3];
            const __m256i kl = small_keys8(lo), kh = small_keys8(hi);
            const __m256i flat = _mm256_and_si256(_mm256_cmpeq_epi32(kl, kh), real);
            _mm256_storeu_si256((__m256i *)&s->lo[b], _mm256_sub_epi32(kl, flat));
            _mm256_storeu_si256((__m256i *)&s->hi[b], _mm256_add_epi32(kh, flat));
            n_flat[a] += (uint32_t)__builtin_popcount((unsigned)_mm256_movemask_ps(_mm256_castsi256_ps(flat)));
            const __m256i l_in = _mm256_and_si256(
                real, _mm256_and_si256(_mm256_cmpgt_epi32(kl, box_lo[a]), _mm256_cmpgt_epi32(box_hi[a], kl)));
            const __m256i h_in = _mm256_andnot_si256(
                flat, _mm256_and_si256(real, _mm256_and_si256(_mm256_cmpgt_epi32(kh, box_lo[a]), _mm256_cmpgt_epi32(box_hi[a], kh))));
            n_cand[a] += small_pack8(&s->cand[n_cand[a]], kl, l_in);
            n_cand[a] += small_pack8(&s->cand[n_cand[a]], kh, h_in);
        }
    }
    for (int a = 0; a < 3; ++a) {
        axes[a].n_flat = n_flat[a];
        axes[a].n_cand = n_cand[a];
    }
}

/* The prices of eight candidates with their counts, into s at j. */
__attribute__((target("avx2"))) static inline __m256 price_small_eight(small_axis *s, uint32_t j, __m256i c, __m256i nl0,
                                                                       __m256i nr0, __m256i p_eq, const sweep_prices *sp)
{
    const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    const __m256 pos = _mm256_castsi256_ps(
        _mm256_xor_si256(c, _mm256_and_si256(_mm256_srai_epi32(c, 31), _mm256_set1_epi32(0x7fffffff))));
    /* Lanes past the last candidate price as infinite. */
    const __m256 real =
        _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32((int)s->n_cand), _mm256_add_epi32(_mm256_set1_epi32((int)j), lane)));
    const __m256 cost = _mm256_blendv_ps(_mm256_set1_ps(INFINITY), price_planes8(pos, nl0, nr0, p_eq, sp), real);
    _mm256_storeu_ps(&s->cost[j], cost);
    _mm256_storeu_si256((__m256i *)&s->nl0[j], nl0);
    _mm256_storeu_si256((__m256i *)&s->nr0[j], nr0);
    _mm256_storeu_si256((__m256i *)&s->in_plane[j], p_eq);
    return cost;
}

/* The counts of one block of eight candidates against every reference
 * (the flat ones' third count only where the axis has some). */
__attribute__((target("avx2"))) static inline void count_small_eight(const small_axis *s, uint32_t n, __m256i c,
                                                                     __m256i *nl0, __m256i *nr0, __m256i *p_eq)
{
    const __m256i d = _mm256_sub_epi32(c, _mm256_set1_epi32(1));
    __m256i gt = _mm256_setzero_si256(), ge = gt, eq = gt;
    if (s->n_flat) {
        for (uint32_t k = 0; k < n; ++k) {
            const __m256i l = _mm256_cmpgt_epi32(_mm256_set1_epi32(s->lo[k]), c);
            const __m256i h = _mm256_cmpgt_epi32(_mm256_set1_epi32(s->hi[k]), d);
            gt = _mm256_sub_epi32(gt, l);
            ge = _mm256_sub_epi32(ge, h);
            eq = _mm256_sub_epi32(eq, _mm256_andnot_si256(h, l));
        }
    } else {
        for (uint32_t k = 0; k < n; ++k) {
            gt = _mm256_sub_epi32(gt, _mm256_cmpgt_epi32(_mm256_set1_epi32(s->lo[k]), c));
            ge = _mm256_sub_epi32(ge, _mm256_cmpgt_epi32(_mm256_set1_epi32(s->hi[k]), d));
        }
    }
    *nl0 = _mm256_sub_epi32(_mm256_set1_epi32((int)n), gt);
    *nr0 = ge;
    *p_eq = eq;
}

/* The counts of sixteen candidates against every reference, each key
 * broadcast once for both blocks; without flat references nothing lies in
 * a plane, and the loop takes two compares a reference. A last block of
 * eight or fewer goes alone. */
__attribute__((target("avx2"))) static float price_small_axis_avx2(small_axis *s, uint32_t n, const sweep_prices *sp)
{
    const __m256i one = _mm256_set1_epi32(1), count = _mm256_set1_epi32((int)n), zero = _mm256_setzero_si256();
    __m256 low = _mm256_set1_ps(INFINITY);
    uint32_t j = 0;
    for (; j + 8 < s->n_cand; j += 16) {
        const __m256i c_a = _mm256_loadu_si256((const __m256i *)&s->cand[j]);
        const __m256i c_b = _mm256_loadu_si256((const __m256i *)&s->cand[j + 8]);
        const __m256i d_a = _mm256_sub_epi32(c_a, one), d_b = _mm256_sub_epi32(c_b, one);
        __m256i gt_a = zero, gt_b = zero, ge_a = zero, ge_b = zero, eq_a = zero, eq_b = zero;
        if (s->n_flat) {
            for (uint32_t k = 0; k < n; ++k) {
                const __m256i lo = _mm256_set1_epi32(s->lo[k]), hi = _mm256_set1_epi32(s->hi[k]);
                const __m256i l_a = _mm256_cmpgt_epi32(lo, c_a), l_b = _mm256_cmpgt_epi32(lo, c_b);
                const __m256i h_a = _mm256_cmpgt_epi32(hi, d_a), h_b = _mm256_cmpgt_epi32(hi, d_b);
                gt_a = _mm256_sub_epi32(gt_a, l_a);
                gt_b = _mm256_sub_epi32(gt_b, l_b);
                ge_a = _mm256_sub_epi32(ge_a, h_a);
                ge_b = _mm256_sub_epi32(ge_b, h_b);
                eq_a = _mm256_sub_epi32(eq_a, _mm256_andnot_si256(h_a, l_a));
                eq_b = _mm256_sub_epi32(eq_b, _mm256_andnot_si256(h_b, l_b));
            }
        } else {
            for (uint32_t k = 0; k < n; ++k) {
                const __m256i lo = _mm256_set1_epi32(s->lo[k]), hi = _mm256_set1_epi32(s->hi[k]);
                gt_a = _mm256_sub_epi32(gt_a, _mm256_cmpgt_epi32(lo, c_a));
                gt_b = _mm256_sub_epi32(gt_b, _mm256_cmpgt_epi32(lo, c_b));
                ge_a = _mm256_sub_epi32(ge_a, _mm256_cmpgt_epi32(hi, d_a));
                ge_b = _mm256_sub_epi32(ge_b, _mm256_cmpgt_epi32(hi, d_b));
            }
        }
        low = _mm256_min_ps(low, price_small_eight(s, j, c_a, _mm256_sub_epi32(count, gt_a), ge_a, eq_a, sp));
        low = _mm256_min_ps(low, price_small_eight(s, j + 8, c_b, _mm256_sub_epi32(count, gt_b), ge_b, eq_b, sp));
    }
    if (j < s->n_cand) {
        const __m256i c = _mm256_loadu_si256((const __m256i *)&s->cand[j]);
        __m256i nl0, nr0, p_eq;
        count_small_eight(s, n, c, &nl0, &nr0, &p_eq);
        low = _mm256_min_ps(low, price_small_eight(s, j, c, nl0, nr0, p_eq, sp));
    }
    const __m128 four = _mm_min_ps(_mm256_castps256_ps128(low), _mm256_extractf128_ps(low, 1));
    return lowest4(four);
}
#endif

/* The form a small node's chooser takes: the fastest this processor has
 * (KD_CHOOSE_SMALL), or the SSE2 or the plain one (their tests). */
static float price_small_axis(small_axis *s, uint32_t n, const sweep_prices *sp, int form)
{
#if defined(KD_AVX2)
    if (form == KD_CHOOSE_SMALL && as_cpu_has_avx2()) return price_small_axis_avx2(s, n, sp);
#endif
#if defined(__SSE2__)
    if (form != KD_CHOOSE_SMALL_PLAIN) return price_small_axis_sse2(s, n, sp);
#endif
    (void)form;
    return price_small_axis_plain(s, n, sp);
}

static int sah_choose_small(const kd_ctx *c, const kd_ref *refs, uint32_t n, const float box[6], kd_split *out)
{
    const double ct = c->args->cost_traversal, ci = c->args->cost_intersection, area = half_area(box);
    /* A bigger node without lists is one whose lists ran out of memory:
     * the build stops, and the node becomes a leaf. */
    if ((n <= 1 && ct >= ci) || n > SMALL_NODE_REFS) return 0;
    if (!(area > 0.0)) return 0;
    const double limit = ci * (double)n;
    double best = limit;
    int found = 0;
    small_axis axes[3];
#if defined(KD_AVX2)
    if (c->small_form == KD_CHOOSE_SMALL && as_cpu_has_avx2()) small_axes_fill_avx2(axes, refs, n, box);
    else
#endif
        small_axes_fill(axes, refs, n, box);
    exact_prices ep[3];
    int filter[3];
    /* Every axis priced in single precision first: only planes near the
     * lowest of all three can be the node's (the sweep's argument, across
     * the axes), so only those are priced exactly. */
    double threshold = limit * (1.0 + SWEEP_MARGIN);
    for (int axis = 0; axis < 3; ++axis) {
        small_axis *const sa = &axes[axis];
        filter[axis] = 1;
        if (!(box[axis + 3] > box[axis])) {
            sa->n_cand = 0;
            continue;
        }
        sweep_prices sp;
        filter[axis] = axis_prices(box, axis, area, ct, ci, &sp, &ep[axis]);
        /* The vector loops' lanes past the last candidate hold a position
         * in the box: a NaN there would raise the invalid flag in the
         * caller's floating-point environment. */
        const int32_t inside = small_key(box[axis]);
#if defined(__SSE2__)
        for (uint32_t j = 0; j < 16; j += 4) _mm_storeu_si128((__m128i *)&sa->cand[sa->n_cand + j], _mm_set1_epi32(inside));
#else
        for (uint32_t j = sa->n_cand; j < sa->n_cand + 16; ++j) sa->cand[j] = inside;
#endif
        const double low = (double)price_small_axis(sa, n, &sp, c->small_form) * (1.0 + SWEEP_MARGIN);
        if (filter[axis] && low < threshold) threshold = low;
    }
    for (int axis = 0; axis < 3; ++axis) {
        small_axis *const sa = &axes[axis];
        sweep_best b = {limit, filter[axis] ? threshold : limit * (1.0 + SWEEP_MARGIN), 0.0f, 0, 0, {0, 0}};
#if defined(__SSE2__)
        if (filter[axis] && c->small_form != KD_CHOOSE_SMALL_PLAIN) {
            /* As the sweep's filter: four single-precision costs against
             * the threshold rounded up to a float in one compare, the few
             * that pass tested again exactly. The costs past the last
             * candidate are infinite (the pricing writes whole blocks). */
            /* Which of 64 candidates pass, gathered in a register (a
             * mask kept in memory would make each step wait for the one
             * before), then the few that pass. */
            const __m128 t = _mm_set1_ps(threshold_float(&b));
            for (uint32_t w = 0; w < sa->n_cand; w += 64) {
                const uint32_t end = sa->n_cand - w < 64 ? sa->n_cand - w : 64;
                uint64_t lanes = 0;
                for (uint32_t q = 0; q < end; q += 4)
                    lanes |= (uint64_t)_mm_movemask_ps(_mm_cmple_ps(_mm_loadu_ps(&sa->cost[w + q]), t)) << q;
                for (; lanes; lanes &= lanes - 1u) {
                    const uint32_t j = w + (uint32_t)__builtin_ctzll(lanes);
                    if (!((double)sa->cost[j] <= b.threshold)) continue;
                    price_plane_exactly(small_key_float(sa->cand[j]), sa->nl0[j], sa->nr0[j], sa->in_plane[j], &ep[axis], &b);
                }
            }
        } else
#endif
            for (uint32_t j = 0; j < sa->n_cand; ++j) {
                if (filter[axis] && !((double)sa->cost[j] <= b.threshold)) continue;
                price_plane_exactly(small_key_float(sa->cand[j]), sa->nl0[j], sa->nr0[j], sa->in_plane[j], &ep[axis], &b);
            }
        if (b.found && b.cost < best) {
            best = b.cost;
            out->axis = axis;
            out->pos = b.pos;
            out->planar_left = b.planar_left;
            out->counted = 1;
            out->count[0] = b.count[0];
            out->count[1] = b.count[1];
            found = 1;
        }
    }
    return found;
}

static int sah_choose(const kd_ctx *c, void *state, const kd_ref *refs, uint32_t n, const float box[6],
                      uint32_t depth, kd_split *out)
{
    (void)depth;
    if (!state) return sah_choose_small(c, refs, n, box, out);
    choose_job cj;
    cj.e = state;
    cj.box = box;
    cj.ct = c->args->cost_traversal;
    cj.ci = c->args->cost_intersection;
    cj.area = half_area(box);
    if (n <= 1 && cj.ct >= cj.ci) return 0;
    if (!(cj.area > 0.0)) return 0;
    cj.limit = cj.ci * (double)n;
    const unsigned threads = axis_threads(c, cj.e, n);
    const unsigned per_axis = pieces_per_axis(c, cj.e, n);
    if (per_axis > 1) sweep_in_pieces(&cj, as_thread_count(c->args->thread_count), per_axis);
    else for_each_axis(threads, sweep_axis, &cj);
    /* The axes in order, a later one only when strictly cheaper: the plane
     * one sweep over all three would keep. */
    double best = cj.limit;
    int found = 0;
    for (int axis = 0; axis < 3; ++axis) {
        const axis_best *b = &cj.best[axis];
        if (b->found && b->cost < best) {
            best = b->cost;
            out->axis = axis;
            out->pos = b->pos;
            out->planar_left = b->planar_left;
            out->counted = 1;
            out->count[0] = b->count[0];
            out->count[1] = b->count[1];
            found = 1;
        }
    }
    return found;
}

int kd_sah_choose_plane(const as_build_args_t *args, const kd_ref *refs, uint32_t n, const float box[6], int how,
                        kd_split *out)
{
    as_mesh_t mesh;
    memset(&mesh, 0, sizeof mesh);
    mesh.triangle_count = n ? refs[n - 1].id + 1 : 0;
    kd_ctx c;
    memset(&c, 0, sizeof c);
    c.args = args;
    c.mesh = &mesh;
    c.small_form = how;
    if (how != KD_CHOOSE_SWEEP) return n <= SMALL_NODE_REFS ? sah_choose(&c, NULL, refs, n, box, 0, out) : -1;
    sah_events *e = sah_root_events(&c, refs, n);
    if (!e) return -1;
    const int chosen = sah_choose(&c, e, refs, n, box, 0, out);
    events_free(e);
    return chosen;
}

as_error_t as_kd_build_sah(const as_mesh_t *mesh, const as_build_args_t *args, as_structure_t *s)
{
    static const kd_builder_ops ops = {AS_BUILDER_KD_SAH, sah_choose, sah_root_events, sah_child_events, events_free};
    return kd_build(mesh, args, &ops, s);
}
