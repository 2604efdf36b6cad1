/* See task_pool.h. */
#define _GNU_SOURCE /* PTHREAD_MUTEX_ADAPTIVE_NP */
#include "task_pool.h"
#include "thread_crew.h"

#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* A parallel step (as_parallel_run) that a thread of the pool publishes so
 * that the pool's idle threads can take some of its indices. */
typedef struct help_job {
    void (*fn)(void *user, unsigned i, unsigned n);
    void *user;
    unsigned n;
    atomic_uint next;       /* the next index not yet taken */
    atomic_uint helpers;    /* pool threads inside the job */
    int published;
    struct as_task_pool *pool;
} help_job;

/* Steps published at once: the first levels of a tree have a few big nodes
 * split at the same time, each with steps for the idle threads (with one
 * at a time, 16 threads had the others' steps run on their callers alone
 * while most of them waited: the binned build's first millisecond). */
#define HELP_MAX 16

/* Threads out of work watch three counts without the lock (tasks queued,
 * published steps with indices left, whether everything is done) and take
 * the lock only when one says there is something to take: 16 threads that
 * took it whenever anything changed had spent a fifth of a build's first
 * millisecond waiting for it. */
struct as_task_pool {
    pthread_mutex_t lock;
    pthread_cond_t wake;
    pthread_cond_t help_done;   /* a published job's last helper left it */
    help_job *help[HELP_MAX];   /* the published steps (NULL: a free slot); under the lock */
    size_t task_size;
    unsigned char *stack;
    size_t depth, capacity;
    size_t active;              /* tasks queued or running; under the lock */
    atomic_int waiting;         /* threads watching for work or asleep on `wake` */
    atomic_int queued;          /* depth, readable without the lock */
    atomic_int help_open;       /* published steps whose indices are not all taken */
    atomic_int done;            /* nothing queued, nothing running */
    atomic_int owners_asleep;   /* owners of steps asleep on help_done */
    as_task_fn run;
    void *user;
};

int as_task_pool_push(as_task_pool *p, const void *task)
{
    pthread_mutex_lock(&p->lock);
    if (p->depth == p->capacity) {
        const size_t cap = p->capacity ? 2 * p->capacity : 16;
        unsigned char *grown = realloc(p->stack, cap * p->task_size);
        if (!grown) {
            pthread_mutex_unlock(&p->lock);
            return 0;
        }
        p->stack = grown;
        p->capacity = cap;
    }
    memcpy(p->stack + p->depth * p->task_size, task, p->task_size);
    p->depth++;
    atomic_store_explicit(&p->queued, (int)p->depth, memory_order_release);
    p->active++;
    pthread_cond_signal(&p->wake);
    pthread_mutex_unlock(&p->lock);
    return 1;
}

/* A thread woken for a task still counts as waiting until it has taken
 * it: a thread is hungry only while the waiting outnumber the queued. */
unsigned as_task_pool_idle(as_task_pool *p)
{
    const int d = atomic_load_explicit(&p->waiting, memory_order_relaxed) -
                  atomic_load_explicit(&p->queued, memory_order_relaxed);
    return d > 0 ? (unsigned)d : 0u;
}

int as_task_pool_hungry(as_task_pool *p) { return as_task_pool_idle(p) > 0; }

/* The pool the calling thread works for, if any: as_parallel_run inside a
 * task shares its indices with that pool's idle threads instead of
 * starting threads of its own, which would outnumber the cores. */
static _Thread_local as_task_pool *current_pool;

/* Takes indices until none is left; the thread that takes the last one
 * takes the job off the count of open steps before it runs it, so that
 * threads out of work do not take the pool's lock again and again for a
 * job whose indices are all running. */
static void help_run(help_job *h)
{
    for (;;) {
        const unsigned i = atomic_fetch_add_explicit(&h->next, 1, memory_order_relaxed);
        if (i >= h->n) return;
        if (i == h->n - 1 && h->published) atomic_fetch_sub(&h->pool->help_open, 1);
        h->fn(h->user, i, h->n);
    }
}

/* Helps the published step with indices left that has the fewest helpers;
 * returns 0 when there is none. Called and returns without the lock. */
static int help_if_asked(as_task_pool *p)
{
    pthread_mutex_lock(&p->lock);
    help_job *h = NULL;
    for (unsigned k = 0; k < HELP_MAX; ++k) {
        help_job *c = p->help[k];
        if (c && atomic_load_explicit(&c->next, memory_order_relaxed) < c->n &&
            (!h || atomic_load_explicit(&c->helpers, memory_order_relaxed) <
                       atomic_load_explicit(&h->helpers, memory_order_relaxed)))
            h = c;
    }
    /* Joined under the lock: its owner takes it off the list under the lock
     * before it waits for the helpers to leave. */
    if (h) atomic_fetch_add(&h->helpers, 1);
    pthread_mutex_unlock(&p->lock);
    if (!h) return 0;
    help_run(h);
    /* h may be gone once the count is 0 (its owner watches it): nothing of
     * it is read after, and an owner asleep is woken through the pool. */
    if (atomic_fetch_sub(&h->helpers, 1) == 1 && atomic_load(&p->owners_asleep) > 0) {
        pthread_mutex_lock(&p->lock);
        pthread_cond_broadcast(&p->help_done);
        pthread_mutex_unlock(&p->lock);
    }
    return 1;
}

static int work_hint(const void *arg)
{
    const as_task_pool *p = arg;
    return atomic_load_explicit(&p->queued, memory_order_acquire) > 0 ||
           atomic_load_explicit(&p->help_open, memory_order_acquire) > 0 ||
           atomic_load_explicit(&p->done, memory_order_acquire);
}

static void *worker(void *arg)
{
    as_task_pool *p = arg;
    as_task_pool *outer = current_pool;
    current_pool = p;
    _Alignas(16) unsigned char task[AS_TASK_MAX_SIZE];
    for (;;) {
        if (atomic_load_explicit(&p->help_open, memory_order_acquire) > 0 && help_if_asked(p)) continue;
        if (atomic_load_explicit(&p->queued, memory_order_acquire) > 0) {
            pthread_mutex_lock(&p->lock);
            if (p->depth > 0) {
                p->depth--;
                atomic_store_explicit(&p->queued, (int)p->depth, memory_order_release);
                memcpy(task, p->stack + p->depth * p->task_size, p->task_size);
                pthread_mutex_unlock(&p->lock);
                p->run(p, task, p->user);
                pthread_mutex_lock(&p->lock);
                if (--p->active == 0) {
                    atomic_store_explicit(&p->done, 1, memory_order_release);
                    pthread_cond_broadcast(&p->wake);
                }
                pthread_mutex_unlock(&p->lock);
                continue;
            }
            pthread_mutex_unlock(&p->lock);
        }
        if (atomic_load_explicit(&p->done, memory_order_acquire)) break;
        /* Watch first (as_spin_until), then sleep; what wakes a sleeper is
         * changed under the lock before the signal, and looked at here
         * under the lock before sleeping. */
        atomic_fetch_add(&p->waiting, 1);
        if (!as_spin_until(work_hint, p)) {
            pthread_mutex_lock(&p->lock);
            while (!work_hint(p)) pthread_cond_wait(&p->wake, &p->lock);
            pthread_mutex_unlock(&p->lock);
        }
        atomic_fetch_sub(&p->waiting, 1);
    }
    current_pool = outer;
    return NULL;
}

static void crew_worker(void *user, unsigned i)
{
    (void)i;
    worker(user);
}

int as_task_pool_run(unsigned threads, size_t task_size, const void *first, as_task_fn run, void *user)
{
    if (task_size == 0 || task_size > AS_TASK_MAX_SIZE) return 0;
    as_task_pool p;
    memset(&p, 0, sizeof p);
    p.task_size = task_size;
    p.run = run;
    p.user = user;
    atomic_init(&p.waiting, 0);
    atomic_init(&p.queued, 0);
    atomic_init(&p.help_open, 0);
    atomic_init(&p.done, 0);
    atomic_init(&p.owners_asleep, 0);
    /* The lock is held for a few stores at a time, and the threads that
     * join a new step take it at once: an adaptive mutex spins a while
     * before it sleeps, where a plain one made each of them sleep in the
     * kernel and its holder wake them there. */
    pthread_mutexattr_t attr;
    if (pthread_mutexattr_init(&attr) != 0) return 0;
#if defined(PTHREAD_ADAPTIVE_MUTEX_INITIALIZER_NP)
    pthread_mutexattr_settype(&attr, PTHREAD_MUTEX_ADAPTIVE_NP);
#endif
    const int lock_made = pthread_mutex_init(&p.lock, &attr) == 0;
    pthread_mutexattr_destroy(&attr);
    if (!lock_made) return 0;
    if (pthread_cond_init(&p.wake, NULL) != 0) {
        pthread_mutex_destroy(&p.lock);
        return 0;
    }
    if (pthread_cond_init(&p.help_done, NULL) != 0 || !as_task_pool_push(&p, first)) {
        pthread_cond_destroy(&p.help_done);
        pthread_cond_destroy(&p.wake);
        pthread_mutex_destroy(&p.lock);
        return 0;
    }
    if (threads < 1) threads = 1;
    if (threads > 256) threads = 256;
    as_crew_batch crew;
    as_crew_start(&crew, threads - 1, crew_worker, &p);
    worker(&p);
    as_crew_wait(&crew);
    free(p.stack);
    pthread_cond_destroy(&p.help_done);
    pthread_cond_destroy(&p.wake);
    pthread_mutex_destroy(&p.lock);
    return 1;
}

typedef struct parallel_job {
    void (*fn)(void *user, unsigned i, unsigned n);
    void *user;
    unsigned n;
} parallel_job;

/* Index i of the crew's batch is the step's index i + 1 (the caller runs 0). */
static void parallel_crew(void *user, unsigned i)
{
    const parallel_job *j = user;
    j->fn(j->user, i + 1, j->n);
}

static int helpers_left(const void *arg)
{
    const help_job *h = arg;
    return atomic_load(&h->helpers) == 0;
}

/* Inside a pool's task: the indices are taken one at a time by this thread
 * and by whichever of the pool's threads are idle or become idle before
 * they are all taken; with none, this thread runs them all. Up to HELP_MAX
 * steps are published at a time; another thread's step meanwhile runs on
 * its caller alone. */
static void parallel_in_pool(as_task_pool *p, unsigned n, void (*fn)(void *user, unsigned i, unsigned n), void *user)
{
    help_job h;
    h.fn = fn;
    h.user = user;
    h.n = n;
    atomic_init(&h.next, 0);
    atomic_init(&h.helpers, 0);
    h.pool = p;
    pthread_mutex_lock(&p->lock);
    unsigned slot = 0;
    while (slot < HELP_MAX && p->help[slot]) ++slot;
    h.published = slot < HELP_MAX;
    if (h.published) {
        p->help[slot] = &h;
        atomic_fetch_add(&p->help_open, 1);
        if (atomic_load_explicit(&p->waiting, memory_order_relaxed) > 0) pthread_cond_broadcast(&p->wake);
    }
    pthread_mutex_unlock(&p->lock);
    help_run(&h);
    if (!h.published) return;
    /* Every index is taken; the job lives in this frame until the helpers
     * that joined it have left. */
    pthread_mutex_lock(&p->lock);
    p->help[slot] = NULL;
    pthread_mutex_unlock(&p->lock);
    if (as_spin_until(helpers_left, &h)) return;
    pthread_mutex_lock(&p->lock);
    atomic_fetch_add(&p->owners_asleep, 1);
    while (atomic_load(&h.helpers) != 0) pthread_cond_wait(&p->help_done, &p->lock);
    atomic_fetch_sub(&p->owners_asleep, 1);
    pthread_mutex_unlock(&p->lock);
}

void as_parallel_run(unsigned n, void (*fn)(void *user, unsigned i, unsigned n), void *user)
{
    if (n < 1) n = 1;
    if (n > 256) n = 256;
    if (n > 1 && current_pool) {
        parallel_in_pool(current_pool, n, fn, user);
        return;
    }
    parallel_job job = {fn, user, n};
    as_crew_batch crew;
    as_crew_start(&crew, n - 1, parallel_crew, &job);
    fn(user, 0, n);
    as_crew_wait(&crew);
}
