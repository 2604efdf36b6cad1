/* Small subtrees of the in-place builders, built whole by the exact SAH
 * sweep over presorted centroid orders (Wald 2007 section 3; MacDonald &
 * Booth 1990), see bvh_build_common.h.
 *
 * Why: most nodes of a tree whose leaves hold a few triangles are small.
 * Binning a node of 17 to 64 references cost about as much as its bins did,
 * and the exact split of up to 16 (bvh_find_small_split) ranked every
 * reference against every other on each axis at every level. Here the
 * references are loaded once into local arrays, each axis's order is found
 * once at the top of the subtree, and a split only partitions the three
 * orders stably, so every level costs a few passes over the node's
 * references and no bins. The split is the exact one. Bathroom, one thread:
 * 0.88x the build time with subtrees of up to 32 references; 64 and 128
 * were slower than 32 (their sweeps cost more than binning, and their sorts
 * more than the ranks counted here).
 *
 * Determinism: orders are by (doubled centroid, position at the top of the
 * subtree), a total order; ties between candidates go to the lower axis,
 * then the earlier position; nothing depends on the thread. */
#include "bvh_build_common.h"

#include <math.h>
#include <string.h>

_Static_assert(BVH_EXACT_MAX <= 255, "local indices are 8-bit");

typedef struct exact_state {
    bvh_builder *b;
    bvh_local *loc;
    bvh_ref *refs;                      /* the subtree's references */
    float ci, ct;
    v4f lo[BVH_EXACT_MAX], hi[BVH_EXACT_MAX];
    float area[BVH_EXACT_MAX];          /* each reference's half area */
    uint8_t ord[3][BVH_EXACT_MAX];      /* per axis, each node's references in a segment, sorted */
    uint8_t side[BVH_EXACT_MAX];        /* 1: left, for the split being made */
    uint8_t leaf_order[BVH_EXACT_MAX];  /* the references by final position */
    float right_area[BVH_EXACT_MAX];
    bvh_ref copy[BVH_EXACT_MAX];
} exact_state;

static void exact_leaf(exact_state *st, int32_t node, uint32_t s, uint32_t n)
{
    memcpy(st->leaf_order + s, st->ord[0] + s, n);
    bvh_local_leaf(st->loc, node, st->refs + s, n);
}

/* The best exact split of segment [s, s + n) over all axes; the axis, or -1
 * when every centroid coincides. */
typedef struct exact_split {
    int axis;
    uint32_t mid;        /* the left side's count */
    double cost;
    v4f llo, lhi, rlo, rhi;
} exact_split;

/* (double)k for the sweeps' counts, without a conversion per candidate. */
static const double count_as_double[BVH_EXACT_MAX + 1] = {
    0,  1,  2,  3,  4,  5,  6,  7,  8,  9,  10, 11, 12, 13, 14, 15, 16,
    17, 18, 19, 20, 21, 22, 23, 24, 25, 26, 27, 28, 29, 30, 31, 32};
_Static_assert(BVH_EXACT_MAX == 32, "count_as_double lists 0..BVH_EXACT_MAX");

static exact_split exact_find(exact_state *st, uint32_t s, uint32_t n, const float keys[3][BVH_EXACT_MAX])
{
    exact_split best;
    best.axis = -1;
    best.mid = 0;
    best.cost = INFINITY;
    const v4f inf = v4f_set1(INFINITY), ninf = v4f_set1(-INFINITY);
    /* Every box here is a union of triangles' boxes, so valid. */
    for (int axis = 0; axis < 3; ++axis) {
        const uint8_t *o = st->ord[axis] + s;
        if (!(keys[axis][o[n - 1]] > keys[axis][o[0]])) continue; /* every centroid on one plane */
        v4f a = inf, z = ninf;
        for (uint32_t i = n; i-- > 1;) {
            a = v4f_min(a, st->lo[o[i]]);
            z = v4f_max(z, st->hi[o[i]]);
            st->right_area[i] = v4f_half_area_valid(a, z);
        }
        a = inf;
        z = ninf;
        for (uint32_t i = 0; i + 1 < n; ++i) {
            a = v4f_min(a, st->lo[o[i]]);
            z = v4f_max(z, st->hi[o[i]]);
            const double c = (double)v4f_half_area_valid(a, z) * count_as_double[i + 1] +
                             (double)st->right_area[i + 1] * count_as_double[n - i - 1];
            if (c < best.cost) {
                best.cost = c;
                best.axis = axis;
                best.mid = i + 1;
                best.llo = a;
                best.lhi = z;
            }
        }
    }
    if (best.axis >= 0) {
        /* The right side's box, once for the chosen split rather than at
         * every candidate. */
        const uint8_t *o = st->ord[best.axis] + s;
        v4f a = inf, z = ninf;
        for (uint32_t i = n; i-- > best.mid;) {
            a = v4f_min(a, st->lo[o[i]]);
            z = v4f_max(z, st->hi[o[i]]);
        }
        best.rlo = a;
        best.rhi = z;
    }
    return best;
}

/* Splits segment [s, s + n) into its first `mid` references along `axis`
 * and the rest, keeping the other axes' orders sorted within each side. */
static void exact_partition(exact_state *st, uint32_t s, uint32_t n, int axis, uint32_t mid)
{
    const uint8_t *o = st->ord[axis] + s;
    for (uint32_t i = 0; i < n; ++i) st->side[o[i]] = i < mid;
    for (int a = 0; a < 3; ++a) {
        if (a == axis) continue;
        uint8_t *p = st->ord[a] + s;
        uint8_t right[BVH_EXACT_MAX];
        uint32_t nl = 0, nr = 0;
        for (uint32_t i = 0; i < n; ++i) {
            const uint8_t x = p[i], f = st->side[x];
            p[nl] = x;
            right[nr] = x;
            nl += f;
            nr += 1u - f;
        }
        memcpy(p + nl, right, nr);
    }
}

static void exact_node(exact_state *st, int32_t node, uint32_t s, uint32_t n, uint32_t depth, v4f blo, v4f bhi,
                       const float keys[3][BVH_EXACT_MAX])
{
    bvh_builder *b = st->b;
    b->nodes[node].box = bvh_box_from_v4f(blo, bhi);
    if (n <= 1 || depth + 1 >= b->depth_limit) {
        exact_leaf(st, node, s, n);
        return;
    }
    const double area = (double)bvh_box_half_area(&b->nodes[node].box);
    const double leaf_cost = st->ci * (double)n;
    const uint32_t max_leaf = b->args->max_leaf_size;
    if (n <= max_leaf && area > 0) {
        /* Each side's box holds each of its references' boxes, so no split
         * costs less than the sum of their areas: a node that this bound
         * already makes a leaf needs no sweep. The bound must clear the
         * leaf cost by a margin far above the sums' rounding, so that the
         * decision is the sweep's. */
        double sum = 0.0;
        for (uint32_t i = 0; i < n; ++i) sum += (double)st->area[st->ord[0][s + i]];
        if (st->ct + st->ci * sum / area > leaf_cost * (1.0 + 1e-9)) {
            exact_leaf(st, node, s, n);
            return;
        }
    }
    exact_split sp = exact_find(st, s, n, keys);
    int32_t ln, rn;
    if (sp.axis >= 0) {
        const double split_cost = area > 0 ? st->ct + st->ci * sp.cost / area : st->ct + st->ci * (double)n;
        if (!(split_cost < leaf_cost) && n <= max_leaf) {
            exact_leaf(st, node, s, n);
            return;
        }
    } else {
        if (n <= max_leaf) {
            exact_leaf(st, node, s, n);
            return;
        }
        /* All centroids coincide (copies of one triangle): split the list
         * in half, which keeps the depth logarithmic. */
        sp.axis = 0;
        sp.mid = n / 2;
        const uint8_t *o = st->ord[0] + s;
        v4f a = v4f_set1(INFINITY), z = v4f_set1(-INFINITY), c = a, d = z;
        for (uint32_t i = 0; i < n; ++i) {
            if (i < sp.mid) {
                a = v4f_min(a, st->lo[o[i]]);
                z = v4f_max(z, st->hi[o[i]]);
            } else {
                c = v4f_min(c, st->lo[o[i]]);
                d = v4f_max(d, st->hi[o[i]]);
            }
        }
        sp.llo = a;
        sp.lhi = z;
        sp.rlo = c;
        sp.rhi = d;
    }
    if (!bvh_local_pair(st->loc, &ln, &rn)) {
        exact_leaf(st, node, s, n);
        return;
    }
    exact_partition(st, s, n, sp.axis, sp.mid);
    bvh_make_inner(b, node, ln, rn);
    exact_node(st, ln, s, sp.mid, depth + 1, sp.llo, sp.lhi, keys);
    exact_node(st, rn, s + sp.mid, n - sp.mid, depth + 1, sp.rlo, sp.rhi, keys);
    bvh_node_complete(b, node, 0);
}

#if defined(__x86_64__) && defined(__GNUC__)
#define EXACT_SORT_AVX2 1
#include <immintrin.h>
/* sort_axis's ranks on processors with AVX2 (chosen at run time), eight
 * comparisons per instruction: the same ranks, so the same order. It was
 * four fifths of the subtrees' set-up (about 80 M instructions in a build
 * of staircase). The keys are held in four vectors, the lanes past the
 * last padded with NaN, which compares neither below nor equal (quiet
 * comparisons: no floating-point flag is raised). */
__attribute__((target("avx2"))) static void sort_axis_avx2(const float *k, uint32_t n, uint8_t *order)
{
    _Static_assert(BVH_EXACT_MAX <= 32, "four vectors of keys");
    float padded[32];
    for (uint32_t j = 0; j < 32; ++j) padded[j] = j < n ? k[j] : __builtin_nanf("");
    const __m256 k0 = _mm256_loadu_ps(padded), k1 = _mm256_loadu_ps(padded + 8), k2 = _mm256_loadu_ps(padded + 16),
                 k3 = _mm256_loadu_ps(padded + 24);
    const __m256i j0 = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7), eight = _mm256_set1_epi32(8);
    const __m256i j1 = _mm256_add_epi32(j0, eight), j2 = _mm256_add_epi32(j1, eight), j3 = _mm256_add_epi32(j2, eight);
    for (uint32_t i = 0; i < n; ++i) {
        const __m256 ki = _mm256_set1_ps(k[i]);
        const __m256i iv = _mm256_set1_epi32((int)i);
        /* Lanes j where (k[j], j) < (k[i], i): -1 each. */
#define EXACT_BEFORE(kj, jv)                                                                                          \
    _mm256_or_si256(_mm256_castps_si256(_mm256_cmp_ps(kj, ki, _CMP_LT_OQ)),                                          \
                    _mm256_and_si256(_mm256_castps_si256(_mm256_cmp_ps(kj, ki, _CMP_EQ_OQ)), _mm256_cmpgt_epi32(iv, jv)))
        __m256i acc = _mm256_add_epi32(EXACT_BEFORE(k0, j0), EXACT_BEFORE(k1, j1));
        if (n > 16) acc = _mm256_add_epi32(acc, _mm256_add_epi32(EXACT_BEFORE(k2, j2), EXACT_BEFORE(k3, j3)));
#undef EXACT_BEFORE
        __m128i s = _mm_add_epi32(_mm256_castsi256_si128(acc), _mm256_extracti128_si256(acc, 1));
        s = _mm_add_epi32(s, _mm_shuffle_epi32(s, _MM_SHUFFLE(1, 0, 3, 2)));
        s = _mm_add_epi32(s, _mm_shuffle_epi32(s, _MM_SHUFFLE(2, 3, 0, 1)));
        order[(uint32_t)-_mm_cvtsi128_si32(s)] = (uint8_t)i;
    }
}
#endif

/* order[0, n) = 0..n-1 sorted by (k[i], i): each one's rank is counted,
 * without branches on the data, which at these sizes costs less than a
 * sort's mispredicted branches. */
static void sort_axis(const float *k, uint32_t n, uint8_t *order, int plain_only)
{
#if defined(EXACT_SORT_AVX2)
    if (!plain_only && as_cpu_has_avx2()) {
        sort_axis_avx2(k, n, order);
        return;
    }
#endif
    (void)plain_only;
    for (uint32_t i = 0; i < n; ++i) {
        const float ki = k[i];
        uint32_t rank = 0;
        for (uint32_t j = 0; j < n; ++j) rank += (k[j] < ki) | ((k[j] == ki) & (j < i));
        order[rank] = (uint8_t)i;
    }
}

void bvh_build_exact_subtree(bvh_builder *b, bvh_local *loc, int32_t node, bvh_ref *refs, uint32_t count,
                             const bvh_box *box, uint32_t depth)
{
    exact_state st;
    float keys[3][BVH_EXACT_MAX];
    const uint32_t n = count;
    st.b = b;
    st.loc = loc;
    st.refs = refs;
    st.ci = b->args->cost_intersection;
    st.ct = b->args->cost_traversal;
    memcpy(st.copy, refs, sizeof(bvh_ref) * n);
    for (uint32_t i = 0; i < n; ++i) {
        st.lo[i] = v4f_load3(st.copy[i].lo);
        st.hi[i] = bvh_ref_load_hi(st.copy[i].hi);
        st.area[i] = v4f_box_half_area(st.lo[i], st.hi[i]);
        float c[4];
        v4f_store(c, v4f_add(st.lo[i], st.hi[i]));
        for (int axis = 0; axis < 3; ++axis) keys[axis][i] = c[axis];
    }
    for (int axis = 0; axis < 3; ++axis) sort_axis(keys[axis], n, st.ord[axis], 0);
    const v4f blo = v4f_set3(box->lo), bhi = v4f_set3(box->hi);
    exact_node(&st, node, 0, n, depth, blo, bhi, (const float(*)[BVH_EXACT_MAX])keys);
    for (uint32_t i = 0; i < n; ++i) refs[i] = st.copy[st.leaf_order[i]];
}

int bvh_exact_order(const float *keys, uint32_t n, uint8_t *order, int plain_only)
{
    if (n > BVH_EXACT_MAX) return 0;
    sort_axis(keys, n, order, plain_only);
    return 1;
}
