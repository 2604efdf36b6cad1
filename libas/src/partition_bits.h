/* A node's partition from a bit mask of its items' sides, shared by the
 * BVH and BIH builders: one pass writes each item's side (1: left) into
 * the mask, on any number of threads, and the misplaced items trade places
 * in pairs. The result is Hoare's permutation (the k-th item that goes
 * right, counted from the start, trades places with the k-th that goes
 * left, counted from the end), so a node partitioned on one thread by
 * Hoare's loop and one partitioned this way on many come out the same. */
#ifndef AS_PARTITION_BITS_H
#define AS_PARTITION_BITS_H

#include <stdint.h>

/* The items are references of 32 bytes (bvh_ref, bih_ref). */
#define AS_PARTITION_ITEM_BYTES 32

/* How many pairs trade places: the items below nl whose bit is 0. */
uint32_t as_partition_misplaced(const uint64_t *bits, uint32_t nl);
/* Swaps the misplaced pairs k0 <= k < k1 of the AS_PARTITION_ITEM_BYTES
 * items (nwords words of bits, nl of them set); pairs are disjoint, so
 * ranges of them may run on different threads. */
void as_partition_swap(void *items, const uint64_t *bits, uint32_t nl, uint32_t nwords, uint32_t k0, uint32_t k1);

#endif
