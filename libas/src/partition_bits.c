/* Partition by bit masks (partition_bits.h). */
#include "partition_bits.h"
#include "as_internal.h"

#include <string.h>

/* Misplaced items in word w: a zero bit below nl (goes right, sits left),
 * a one bit from nl on. */
static inline uint64_t left_misplaced(const uint64_t *bits, uint32_t nl, uint32_t w)
{
    if (64 * w >= nl) return 0;
    return 64 * w + 64 <= nl ? ~bits[w] : ~bits[w] & (((uint64_t)1 << (nl - 64 * w)) - 1);
}

static inline uint64_t right_misplaced(const uint64_t *bits, uint32_t nl, uint32_t w)
{
    if (64 * w >= nl) return bits[w];
    return nl - 64 * w >= 64 ? 0 : bits[w] & ~(((uint64_t)1 << (nl - 64 * w)) - 1);
}

void as_partition_swap(void *items, const uint64_t *bits, uint32_t nl, uint32_t nwords, uint32_t k0, uint32_t k1)
{
    if (k0 >= k1) return;
    unsigned char *base = items;
    uint32_t wl = 0, wr = nwords - 1, skip = k0;
    uint64_t lm, rm;
    for (;; ++wl) {
        lm = left_misplaced(bits, nl, wl);
        const uint32_t pc = (uint32_t)as_popcount64(lm);
        if (skip < pc) break;
        skip -= pc;
    }
    for (; skip; --skip) lm &= lm - 1;
    skip = k0;
    for (;; --wr) {
        rm = right_misplaced(bits, nl, wr);
        const uint32_t pc = (uint32_t)as_popcount64(rm);
        if (skip < pc) break;
        skip -= pc;
    }
    for (; skip; --skip) rm &= ~((uint64_t)1 << (63 - __builtin_clzll(rm)));
    for (uint32_t k = k0;;) {
        while (!lm) lm = left_misplaced(bits, nl, ++wl);
        while (!rm) rm = right_misplaced(bits, nl, --wr);
        const uint32_t p = 64 * wl + (uint32_t)__builtin_ctzll(lm), hb = 63 - (uint32_t)__builtin_clzll(rm);
        const uint32_t q = 64 * wr + hb;
        unsigned char t[AS_PARTITION_ITEM_BYTES];
        memcpy(t, base + (size_t)p * AS_PARTITION_ITEM_BYTES, AS_PARTITION_ITEM_BYTES);
        memcpy(base + (size_t)p * AS_PARTITION_ITEM_BYTES, base + (size_t)q * AS_PARTITION_ITEM_BYTES, AS_PARTITION_ITEM_BYTES);
        memcpy(base + (size_t)q * AS_PARTITION_ITEM_BYTES, t, AS_PARTITION_ITEM_BYTES);
        if (++k == k1) return;
        lm &= lm - 1;
        rm &= ~((uint64_t)1 << hb);
    }
}

uint32_t as_partition_misplaced(const uint64_t *bits, uint32_t nl)
{
    uint32_t m = 0;
    for (uint32_t w = 0; 64 * w < nl; ++w) m += (uint32_t)as_popcount64(left_misplaced(bits, nl, w));
    return m;
}
