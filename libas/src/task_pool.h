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

#include <stddef.h>

/* The largest task struct. */
#define AS_TASK_MAX_SIZE 512

typedef struct as_task_pool as_task_pool;
typedef void (*as_task_fn)(as_task_pool *pool, void *task, void *user);

/* Runs `first` and every task pushed from it on up to `threads` threads,
 * returning when all are done. Returns 0 when the pool could not be set up
 * (then nothing ran). */
int as_task_pool_run(unsigned threads, size_t task_size, const void *first, as_task_fn run, void *user);

/* Shares a task with the other threads; returns 0 when it could not (no
 * memory), in which case the caller runs it itself. */
int as_task_pool_push(as_task_pool *pool, const void *task);

/* Whether more threads wait for work than tasks are queued for them: a
 * hint for when to push, read without the lock. */
int as_task_pool_hungry(as_task_pool *pool);
/* How many more threads wait for work than tasks are queued (0 or more),
 * read without the lock: a hint. */
unsigned as_task_pool_idle(as_task_pool *pool);

/* Runs fn(user, i, n) once for each i in [0, n) and returns when all are
 * done; n is clamped to [1, 256]. Outside a pool: on n threads, the
 * caller's included (a thread that cannot be started runs on the caller's).
 * Inside a task of as_task_pool_run: on the caller's thread and the pool's
 * idle threads, which take the indices one at a time, so any thread may run
 * any number of them, in any order. Either way fn must not wait on another
 * index, and its results must not depend on which thread ran which. */
void as_parallel_run(unsigned n, void (*fn)(void *user, unsigned i, unsigned n), void *user);

#endif
