/* A small pool for the builders' divide-and-conquer: tasks are plain structs
 * copied onto a shared stack; every thread (the caller's included) pops one,
 * runs it, and may push the subtasks it wants shared. Builders push only
 * large subtrees and recurse into the rest themselves, so the lock is taken
 * a few hundred times per build at most.
 *
 * The order in which tasks run depends on scheduling; builders keep their
 * output deterministic by deciding everything from a task's own data. */
#ifndef AS_TASK_POOL_H
#define AS_TASK_POOL_H

#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>

/* The largest task struct. */
#define AS_TASK_MAX_SIZE 512

typedef struct as_task_pool as_task_pool;
typedef void (*as_task_fn)(as_task_pool *pool, void *task, void *user);

/* Runs `first` and every task pushed from it on up to `threads` threads,
 * returning when all are done. Returns 0 when the pool could not be set up
 * (then nothing ran). */
int as_task_pool_run(unsigned threads, size_t task_size, const void *first, as_task_fn run, void *user);

/* Slots of an array that the pool's tasks fill (a builder's nodes), taken
 * by each task in runs of up to `chunk` from one shared counter: a counter
 * every thread bumped for every node was what kept the builders from
 * scaling, its cache line passed from thread to thread. Sets the task's
 * run [*first, *end) of at least `need` slots and returns 1, or returns 0
 * when fewer than `need` are left; the last runs shrink, so no slot past
 * `capacity` is ever handed out. */
static inline int as_slots_take(atomic_uint_fast64_t *counter, uint64_t capacity, uint64_t chunk, uint64_t need,
                                uint64_t *first, uint64_t *end)
{
    uint64_t cur = atomic_load_explicit(counter, memory_order_relaxed), take;
    do {
        if (cur + need > capacity) return 0;
        take = capacity - cur < chunk ? capacity - cur : chunk;
    } while (!atomic_compare_exchange_weak(counter, &cur, cur + take));
    *first = cur;
    *end = cur + take;
    return 1;
}

/* Shares a task with the other threads; returns 0 when it could not (no
 * memory), in which case the caller runs it itself. */
int as_task_pool_push(as_task_pool *pool, const void *task);

/* Whether more threads wait for work than tasks are queued for them: a
 * hint for when to push, read without the lock. */
int as_task_pool_hungry(as_task_pool *pool);
/* How many more threads wait for work than tasks are queued (0 or more),
 * read without the lock: a hint. */
unsigned as_task_pool_idle(as_task_pool *pool);

/* The large right children a task has split off and not started yet, on
 * its path from its root, oldest (highest in the tree, so largest) first.
 * Whenever a thread of the pool waits for work, the task hands it the
 * oldest of them at its next node (as_pending_next_offer). Offering only
 * the child of the node being split at that moment left the waiting thread
 * idle until the task's depth-first walk reached a new node big enough to
 * share: bathroom, binned SAH, two threads, a thread waited 2-4 ms at a
 * time, 15-25 ms per build; a KD build on 16 threads ended on a few of them
 * for its last millisecond. The stack is the task's own (no lock); a given
 * child is built by the task that takes it. */
typedef struct as_pending {
    const void *task;   /* the child's task struct, in the caller's frame */
    int given;          /* 1 once pushed to the pool */
} as_pending;

/* The deepest builder's depth cap, plus one. */
#define AS_PENDING_MAX 65

typedef struct as_pending_stack {
    as_pending *e[AS_PENDING_MAX];
    uint32_t n;      /* entries */
    uint32_t next;   /* entries below it are given (or were refused) */
} as_pending_stack;

static inline void as_pending_init(as_pending_stack *s) { s->n = s->next = 0; }
/* Records p (not given); 0 when the stack is full (then p is the caller's). */
static inline int as_pending_push(as_pending_stack *s, as_pending *p)
{
    p->given = 0;
    if (s->n == AS_PENDING_MAX) return 0;
    s->e[s->n++] = p;
    return 1;
}
/* Removes the newest entry, before its owner builds it (unless given). */
static inline void as_pending_pop(as_pending_stack *s)
{
    s->n--;
    if (s->next > s->n) s->next = s->n;
}
/* The oldest entry not offered yet when a thread of the pool waits for
 * work, else NULL; the caller shares its task and sets `given`. */
static inline as_pending *as_pending_next_offer(as_task_pool *pool, as_pending_stack *s)
{
    if (s->next == s->n || !pool || !as_task_pool_hungry(pool)) return NULL;
    return s->e[s->next++];
}

/* Runs fn(user, i, n) once for each i in [0, n) and returns when all are
 * done; n is clamped to [1, 256]. Outside a pool: on n threads, the
 * caller's included (a thread that cannot be started runs on the caller's).
 * Inside a task of as_task_pool_run: on the caller's thread and the pool's
 * idle threads, which take the indices one at a time, so any thread may run
 * any number of them, in any order. Either way fn must not wait on another
 * index, and its results must not depend on which thread ran which. */
void as_parallel_run(unsigned n, void (*fn)(void *user, unsigned i, unsigned n), void *user);

#endif
