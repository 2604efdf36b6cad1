/* The compressed wide BVH from a binary one (Ylitie, Karras & Laine 2017,
 * section 3): a cost-optimal collapse of the binary tree into nodes of at
 * most eight children by dynamic programming over the SAH, children placed
 * in slots by the octant of their centroid, boxes quantized outwards.
 *
 * The binary tree is the child-bounds BVH2 that the builders write. A leaf
 * of more triangles than a wide leaf holds (the depth cap, or a BVH2 built
 * with larger leaves) is halved by TRI4 order into smaller ones first, each
 * half's box the union of its triangles' boxes within the leaf's box, so
 * that it still bounds what an SBVH leaf clipped. Everything runs on one
 * thread in a fixed order: the same binary tree gives the same bytes. */
#include "structure.h"
#include "cwbvh_layout.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* A node of the binary tree being collapsed. Children come before their
 * parent, so one pass in index order solves the recurrences bottom up. */
typedef struct cw_bnode {
    float lo[3], hi[3];
    int32_t left, right;          /* -1 for a leaf */
    uint32_t first, count;        /* a leaf's TRI4 range */
    uint32_t tris;                /* TRI4 entries below */
} cw_bnode;

/* What the dynamic program decided for a node, per number i = 1..8 of wide
 * children its subtree may become:
 *   pick[0]: as one child, a leaf (CW_LEAF) or an inner node (CW_INNER);
 *   pick[i - 1], i >= 2: 0 when i - 1 children do as well, else k: k of
 *   them from the left subtree and i - k from the right;
 *   pick[8]: the k of the best split into eight, the children of this node
 *   when it is an inner wide node. */
enum { CW_LEAF = 0, CW_INNER = 1 };
#define CW_PICKS 9

typedef struct cw_state {
    const as_tri4_t *tris_in;
    cw_bnode *b;
    uint64_t bn;
    float *cost;                  /* 8 per node: cost[i - 1], at most i children */
    uint8_t *pick;                /* CW_PICKS per node */
    uint32_t leaf_max;
    double ct, ci;
    as_cwbvh_node_t *out;
    uint64_t out_n, out_cap;
    as_tri4_t *tout;
    uint64_t tout_n;
    uint64_t leaves;
    uint32_t max_leaf_depth;
} cw_state;

typedef struct cw_child {
    int32_t node;
    int leaf;
} cw_child;

static double half_area(const float lo[3], const float hi[3])
{
    return as_half_area6(lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]);
}

static void box_empty(float lo[3], float hi[3])
{
    for (int a = 0; a < 3; ++a) { lo[a] = INFINITY; hi[a] = -INFINITY; }
}

static void box_grow(float lo[3], float hi[3], const float l[3], const float h[3])
{
    for (int a = 0; a < 3; ++a) {
        lo[a] = fminf(lo[a], l[a]);
        hi[a] = fmaxf(hi[a], h[a]);
    }
}

static int32_t new_node(cw_state *st)
{
    const int32_t id = (int32_t)st->bn++;
    cw_bnode *n = &st->b[id];
    memset(n, 0, sizeof *n);
    n->left = n->right = -1;
    return id;
}

/* A leaf of `count` TRI4 entries from `first`, halved until each part fits
 * a wide leaf; `box` is the binary leaf's. */
static int32_t from_leaf(cw_state *st, uint32_t first, uint32_t count, const float lo[3], const float hi[3],
                         int whole)
{
    if (count <= st->leaf_max) {
        const int32_t id = new_node(st);
        cw_bnode *n = &st->b[id];
        n->first = first;
        n->count = n->tris = count;
        if (whole) {
            memcpy(n->lo, lo, sizeof n->lo);
            memcpy(n->hi, hi, sizeof n->hi);
            return id;
        }
        box_empty(n->lo, n->hi);
        for (uint32_t t = first; t < first + count; ++t) {
            const as_tri4_t *tri = &st->tris_in[t];
            const float v[3][3] = {{tri->v0.x, tri->v0.y, tri->v0.z}, {tri->v1.x, tri->v1.y, tri->v1.z},
                                   {tri->v2.x, tri->v2.y, tri->v2.z}};
            for (int k = 0; k < 3; ++k) box_grow(n->lo, n->hi, v[k], v[k]);
        }
        for (int a = 0; a < 3; ++a) {
            n->lo[a] = fmaxf(n->lo[a], lo[a]);
            n->hi[a] = fminf(n->hi[a], hi[a]);
            /* A clipped reference may touch the leaf's box only on a face. */
            if (n->lo[a] > n->hi[a]) n->lo[a] = n->hi[a];
        }
        return id;
    }
    const uint32_t half = count / 2;
    const int32_t l = from_leaf(st, first, half, lo, hi, 0);
    const int32_t r = from_leaf(st, first + half, count - half, lo, hi, 0);
    const int32_t id = new_node(st);
    cw_bnode *n = &st->b[id];
    n->left = l;
    n->right = r;
    n->tris = count;
    box_empty(n->lo, n->hi);
    box_grow(n->lo, n->hi, st->b[l].lo, st->b[l].hi);
    box_grow(n->lo, n->hi, st->b[r].lo, st->b[r].hi);
    return id;
}

static void bvh2_child_box(const as_bvh2_node_t *n, int k, float lo[3], float hi[3])
{
    if (k == 0) { lo[0] = n->xy0.x; hi[0] = n->xy0.y; lo[1] = n->xy0.z; hi[1] = n->xy0.w; lo[2] = n->z01.x; hi[2] = n->z01.y; }
    else        { lo[0] = n->xy1.x; hi[0] = n->xy1.y; lo[1] = n->xy1.z; hi[1] = n->xy1.w; lo[2] = n->z01.z; hi[2] = n->z01.w; }
}

/* The binary tree under BVH2 node `index`; an empty child (the sibling of
 * a one-leaf root) leaves its parent out. -1 when nothing is below. */
static int32_t from_bvh2(cw_state *st, const as_bvh2_node_t *nodes, int32_t index)
{
    const as_bvh2_node_t *n = &nodes[index];
    int32_t c[2];
    for (int k = 0; k < 2; ++k) {
        float lo[3], hi[3];
        bvh2_child_box(n, k, lo, hi);
        if (n->child[k] >= 0) c[k] = from_bvh2(st, nodes, n->child[k]);
        else c[k] = n->count[k] ? from_leaf(st, (uint32_t)~n->child[k], n->count[k], lo, hi, 1) : -1;
    }
    if (c[0] < 0) return c[1];
    if (c[1] < 0) return c[0];
    const int32_t id = new_node(st);
    cw_bnode *o = &st->b[id];
    o->left = c[0];
    o->right = c[1];
    o->tris = st->b[c[0]].tris + st->b[c[1]].tris;
    box_empty(o->lo, o->hi);
    box_grow(o->lo, o->hi, st->b[c[0]].lo, st->b[c[0]].hi);
    box_grow(o->lo, o->hi, st->b[c[1]].lo, st->b[c[1]].hi);
    return id;
}

/* The recurrences of the paper: for a node n and i = 1..8,
 *   cost(n, 1) = min(leaf: ci x tris x A(n) when tris <= leaf_max,
 *                    inner: ct x A(n) + split(n, 8)),
 *   cost(n, i) = min(cost(n, i - 1), split(n, i)) for i >= 2,
 *   split(n, i) = min over k of cost(left, k) + cost(right, i - k);
 * a binary leaf is a wide leaf whatever i. */
static void solve(cw_state *st)
{
    for (uint64_t id = 0; id < st->bn; ++id) {
        const cw_bnode *n = &st->b[id];
        float *c = st->cost + 8 * id;
        uint8_t *p = st->pick + CW_PICKS * id;
        memset(p, 0, CW_PICKS);
        const double area = half_area(n->lo, n->hi);
        if (n->left < 0) {
            for (int i = 0; i < 8; ++i) c[i] = (float)(st->ci * n->count * area);
            p[0] = CW_LEAF;
            continue;
        }
        const float *cl = st->cost + 8 * (uint64_t)n->left, *cr = st->cost + 8 * (uint64_t)n->right;
        double split[9];
        uint8_t split_k[9];
        for (int i = 2; i <= 8; ++i) {
            split[i] = INFINITY;
            split_k[i] = 1;
            for (int k = 1; k < i; ++k) {
                const double v = (double)cl[k - 1] + (double)cr[i - k - 1];
                if (v < split[i]) { split[i] = v; split_k[i] = (uint8_t)k; }
            }
        }
        const double inner = st->ct * area + split[8];
        const double leaf = n->tris <= st->leaf_max ? st->ci * n->tris * area : INFINITY;
        c[0] = (float)(leaf <= inner ? leaf : inner);
        p[0] = leaf <= inner ? CW_LEAF : CW_INNER;
        for (int i = 2; i <= 8; ++i) {
            if (split[i] < (double)c[i - 2]) {
                c[i - 1] = (float)split[i];
                p[i - 1] = split_k[i];
            } else {
                c[i - 1] = c[i - 2];
                p[i - 1] = 0;
            }
        }
        p[8] = split_k[8];
    }
}

/* The wide children that node m's subtree becomes when it may give i. */
static void gather(const cw_state *st, int32_t m, int i, cw_child *out, int *n)
{
    const cw_bnode *b = &st->b[m];
    const uint8_t *p = st->pick + CW_PICKS * (uint64_t)m;
    while (i > 1 && b->left >= 0 && p[i - 1] == 0) --i;
    if (i == 1 || b->left < 0) {
        out[*n].node = m;
        out[*n].leaf = b->left < 0 || p[0] == CW_LEAF;
        ++*n;
        return;
    }
    const int k = p[i - 1];
    gather(st, b->left, k, out, n);
    gather(st, b->right, i - k, out, n);
}

/* The children of m as an inner wide node. */
static int inner_children(const cw_state *st, int32_t m, cw_child *out)
{
    const cw_bnode *b = &st->b[m];
    int n = 0;
    if (b->left < 0) {
        /* Only a root that is one small leaf gets here. */
        out[n].node = m;
        out[n].leaf = 1;
        return 1;
    }
    const int k = st->pick[CW_PICKS * (uint64_t)m + 8];
    gather(st, b->left, k, out, &n);
    gather(st, b->right, 8 - k, out, &n);
    return n;
}

static void copy_tris(cw_state *st, int32_t m)
{
    const cw_bnode *b = &st->b[m];
    if (b->left >= 0) {
        copy_tris(st, b->left);
        copy_tris(st, b->right);
        return;
    }
    memcpy(&st->tout[st->tout_n], &st->tris_in[b->first], sizeof(as_tri4_t) * b->count);
    st->tout_n += b->count;
}

/* Slots by octant: slot s wants the child whose centroid lies farthest
 * towards the corner high on axis a when bit a of s is set. Greedy on the
 * largest remaining preference, ties to the lower child, then slot. */
static void assign_slots(const cw_state *st, const cw_child *kids, int nk, const float lo[3], const float hi[3],
                         int slot_of[8])
{
    double pref[8][8];
    for (int k = 0; k < nk; ++k) {
        const cw_bnode *b = &st->b[kids[k].node];
        double d[3];
        for (int a = 0; a < 3; ++a)
            d[a] = 0.5 * ((double)b->lo[a] + b->hi[a]) - 0.5 * ((double)lo[a] + hi[a]);
        for (int s = 0; s < 8; ++s)
            pref[k][s] = (s & 1 ? d[0] : -d[0]) + (s & 2 ? d[1] : -d[1]) + (s & 4 ? d[2] : -d[2]);
    }
    int slot_used[8] = {0}, kid_done[8] = {0};
    for (int round = 0; round < nk; ++round) {
        int bk = -1, bs = -1;
        for (int k = 0; k < nk; ++k) {
            if (kid_done[k]) continue;
            for (int s = 0; s < 8; ++s)
                if (!slot_used[s] && (bk < 0 || pref[k][s] > pref[bk][bs])) { bk = k; bs = s; }
        }
        kid_done[bk] = slot_used[bs] = 1;
        slot_of[bk] = bs;
    }
}

/* The smallest grid on one axis over which every child box quantizes
 * outwards into 8 bits; 0 when even the largest step overflows. */
static int quantize_axis(const float *clo, const float *chi, int nk, float p, float hi, uint8_t *e_out,
                         uint8_t *qlo, uint8_t *qhi)
{
    const double ext = (double)hi - p;
    int e = -126;
    if (ext > 0) {
        e = (int)ceil(log2(ext / 255.0));
        if (e < -126) e = -126;
    }
    for (; e <= 127; ++e) {
        const float scale = as_cwbvh_scale((uint32_t)(e + 127));
        int ok = 1;
        for (int k = 0; k < nk && ok; ++k) {
            double ql = floor(((double)clo[k] - p) / scale);
            if (ql < 0) ql = 0;
            if (ql > 255) ql = 255;
            uint32_t l = (uint32_t)ql;
            while (l > 0 && as_cwbvh_decode(p, scale, l) > clo[k]) --l;
            double qh = ceil(((double)chi[k] - p) / scale);
            if (qh < 0) qh = 0;
            if (qh > 255) { ok = 0; break; }
            uint32_t h = (uint32_t)qh;
            while (h <= 255 && !(as_cwbvh_decode(p, scale, h) >= chi[k])) ++h;
            if (h > 255 || !isfinite(as_cwbvh_decode(p, scale, h))) { ok = 0; break; }
            qlo[k] = (uint8_t)l;
            qhi[k] = (uint8_t)h;
        }
        if (ok) {
            *e_out = (uint8_t)(e + 127);
            return 1;
        }
    }
    return 0;
}

/* Writes wide node `index` over `kids` and, depth first, the nodes below. */
static as_error_t emit(cw_state *st, uint64_t index, const cw_child *kids, int nk, uint32_t depth)
{
    if (depth > AS_CWBVH_MAX_DEPTH)
        return as_set_error(AS_ERROR_UNSUPPORTED, "the compressed wide BVH would be deeper than its traversal stack "
                            "(%d levels)", AS_CWBVH_MAX_DEPTH);
    as_cwbvh_node_t *o = &st->out[index];
    memset(o, 0, sizeof *o);
    float lo[3], hi[3];
    box_empty(lo, hi);
    for (int k = 0; k < nk; ++k) box_grow(lo, hi, st->b[kids[k].node].lo, st->b[kids[k].node].hi);
    int slot_of[8];
    assign_slots(st, kids, nk, lo, hi, slot_of);
    cw_child by_slot[8];
    int used[8] = {0};
    for (int k = 0; k < nk; ++k) {
        by_slot[slot_of[k]] = kids[k];
        used[slot_of[k]] = 1;
    }
    for (int a = 0; a < 3; ++a) {
        float clo[8], chi[8];
        uint8_t ql[8], qh[8];
        int n = 0;
        for (int s = 0; s < 8; ++s)
            if (used[s]) {
                clo[n] = st->b[by_slot[s].node].lo[a];
                chi[n] = st->b[by_slot[s].node].hi[a];
                ++n;
            }
        o->p[a] = nk ? lo[a] : 0.0f;
        if (!nk) { o->e[a] = 127; continue; }
        if (!quantize_axis(clo, chi, n, lo[a], hi[a], &o->e[a], ql, qh))
            return as_set_error(AS_ERROR_UNSUPPORTED, "a node's box [%g, %g] on axis %d cannot be quantized in float",
                                (double)lo[a], (double)hi[a], a);
        n = 0;
        for (int s = 0; s < 8; ++s)
            if (used[s]) {
                o->qlo[a][s] = ql[n];
                o->qhi[a][s] = qh[n];
                ++n;
            }
    }
    o->tri_base = (uint32_t)st->tout_n;
    o->child_base = (uint32_t)st->out_n;
    uint32_t inner = 0;
    for (int s = 0; s < 8; ++s) {
        if (!used[s]) continue;
        if (by_slot[s].leaf) {
            const uint32_t offset = (uint32_t)(st->tout_n - o->tri_base);
            const uint32_t count = st->b[by_slot[s].node].tris;
            copy_tris(st, by_slot[s].node);
            o->meta[s] = (uint8_t)((((1u << count) - 1u) << 5) | offset);
            st->leaves++;
            if (depth + 1 > st->max_leaf_depth) st->max_leaf_depth = depth + 1;
        } else {
            o->meta[s] = AS_CWBVH_META_INNER(s);
            o->imask |= (uint8_t)(1u << s);
            ++inner;
        }
    }
    st->out_n += inner;
    uint64_t next = o->child_base;
    for (int s = 0; s < 8; ++s) {
        if (!used[s] || by_slot[s].leaf) continue;
        cw_child sub[8];
        const int ns = inner_children(st, by_slot[s].node, sub);
        const as_error_t err = emit(st, next++, sub, ns, depth + 1);
        if (err != AS_OK) return err;
    }
    return AS_OK;
}

as_error_t as_bvh2_to_cwbvh(const as_structure_t *src, uint32_t leaf_max, as_structure_t *dst)
{
    const as_section_t *ns = as_structure_find(src, ASF_TAG_BVH2), *ts = as_structure_find(src, ASF_TAG_TRI4);
    if (!ns || !ts || ns->count == 0)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "as_bvh2_to_cwbvh: no BVH2 tree to collapse");
    if (leaf_max < 1) leaf_max = 1;
    if (leaf_max > AS_CWBVH_MAX_LEAF) leaf_max = AS_CWBVH_MAX_LEAF;
    cw_state st;
    memset(&st, 0, sizeof st);
    st.tris_in = ts->data;
    st.leaf_max = leaf_max;
    st.ct = src->meta.cost_traversal;
    st.ci = src->meta.cost_intersection;
    /* Binary nodes: the BVH2's, plus at most two per TRI4 entry for halved
     * leaves. Wide nodes: every one but a lone root has two children or
     * more, and leaves hold one triangle or more. */
    const uint64_t bcap = 2 * ns->count + 2 * ts->count + 2;
    st.out_cap = ts->count + 1;
    st.b = malloc(sizeof(cw_bnode) * bcap);
    st.cost = malloc(sizeof(float) * 8 * bcap);
    st.pick = malloc(CW_PICKS * bcap);
    st.out = as_aligned_alloc(sizeof(as_cwbvh_node_t) * st.out_cap, "CWBV nodes");
    st.tout = as_aligned_alloc(sizeof(as_tri4_t) * (ts->count ? ts->count : 1), "TRI4 triangles");
    as_error_t err = AS_OK;
    if (!st.b || !st.cost || !st.pick || !st.out || !st.tout) {
        err = as_set_error(AS_ERROR_OUT_OF_MEMORY, "out of memory collapsing %llu BVH2 nodes into a wide BVH",
                           (unsigned long long)ns->count);
        goto fail;
    }
    const int32_t root = from_bvh2(&st, ns->data, 0);
    solve(&st);
    st.out_n = 1;
    cw_child kids[8];
    const int nk = root >= 0 ? inner_children(&st, root, kids) : 0;
    err = emit(&st, 0, kids, nk, 0);
    if (err != AS_OK) goto fail;
    if (st.tout_n != ts->count) {
        err = as_set_error(AS_ERROR_UNKNOWN, "wide BVH collapse bookkeeping: %llu of %llu triangles placed",
                           (unsigned long long)st.tout_n, (unsigned long long)ts->count);
        goto fail;
    }
    free(st.b);
    free(st.cost);
    free(st.pick);
    dst->meta = src->meta;
    dst->meta.layout = AS_LAYOUT_BVH_CWBVH;
    dst->meta.layout_version = AS_CWBVH_LAYOUT_VERSION;
    dst->meta.max_leaf_size = leaf_max;
    dst->meta.node_count = st.out_n;
    dst->meta.leaf_count = st.leaves;
    dst->meta.empty_leaf_count = 0;
    dst->meta.max_depth = st.max_leaf_depth;
    dst->meta.reference_count = st.tout_n;
    as_structure_add_section(dst, ASF_TAG_CWBV, st.out, st.out_n, sizeof(as_cwbvh_node_t));
    as_structure_add_section(dst, ASF_TAG_TRI4, st.tout, ts->count, sizeof(as_tri4_t));
    dst->meta.sah_cost = as_cwbvh_sah_cost(dst);
    return AS_OK;
fail:
    free(st.b);
    free(st.cost);
    free(st.pick);
    free(st.out);
    free(st.tout);
    return err;
}

as_error_t as_cwbvh_build(const as_mesh_t *mesh, const as_build_args_t *args,
                          as_error_t (*build)(const as_mesh_t *, const as_build_args_t *, as_structure_t *),
                          as_structure_t *s)
{
    /* One triangle per binary leaf, as in the paper: the collapse then
     * chooses the wide leaves' sizes itself. */
    as_build_args_t bin = *args;
    bin.layout = AS_LAYOUT_BVH2_CHILD_BOUNDS;
    bin.max_leaf_size = 1;
    if (args->max_leaf_size < 1) return as_set_error(AS_ERROR_INVALID_ARGUMENT, "max leaf size must be at least 1");
    as_structure_t tmp;
    memset(&tmp, 0, sizeof tmp);
    as_error_t err = build(mesh, &bin, &tmp);
    if (err == AS_OK) {
        const double t0 = as_now_ms();
        err = as_bvh2_to_cwbvh(&tmp, args->max_leaf_size, s);
        s->build_ms = tmp.build_ms + (as_now_ms() - t0);
    }
    for (uint32_t i = 0; i < tmp.section_count; ++i) free(tmp.sections[i].owned);
    return err;
}
