/* Threads kept between parallel steps (see thread_crew.h). */
#define _POSIX_C_SOURCE 200809L /* pthread_sigmask */
#include "thread_crew.h"
#include "as_internal.h"

#include <pthread.h>
#include <signal.h>
#include <stdatomic.h>
#include <time.h>
#include <stdlib.h>

typedef struct crew_thread {
    pthread_t tid;
    pthread_cond_t wake;
    _Atomic(as_crew_batch *) batch; /* NULL while waiting; set under crew_lock */
    int asleep;                     /* under crew_lock: in pthread_cond_wait, to be signalled */
    unsigned index;
    struct crew_thread *next_idle;
} crew_thread;

static double now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e9 + (double)ts.tv_nsec;
}

int as_spin_until(int (*ready)(const void *arg), const void *arg)
{
    const double end = now_ns() + AS_SPIN_NS;
    for (;;) {
        /* The clock is read once every 64 looks. */
        for (int k = 0; k < 64; ++k) {
            if (ready(arg)) return 1;
#if defined(__x86_64__) || defined(__i386__)
            __builtin_ia32_pause();
#endif
        }
        if (now_ns() > end) return 0;
    }
}

static int batch_given(const void *arg)
{
    const crew_thread *t = arg;
    return atomic_load_explicit(&t->batch, memory_order_acquire) != NULL;
}

static int batch_finished(const void *arg)
{
    const as_crew_batch *b = arg;
    return atomic_load_explicit(&b->finished, memory_order_acquire) >= b->n - b->unstarted;
}

static pthread_mutex_t crew_lock = PTHREAD_MUTEX_INITIALIZER;
static pthread_cond_t crew_done = PTHREAD_COND_INITIALIZER;
static crew_thread *crew_idle;    /* under crew_lock */
static unsigned crew_parked;      /* under crew_lock: threads on crew_idle */
static int crew_quit;             /* under crew_lock: the library is being unloaded */
static pthread_once_t crew_once = PTHREAD_ONCE_INIT;

/* At most this many threads wait for work; a thread that finishes when as
 * many wait leaves instead (a caller that asked for thousands of threads
 * once does not keep them). */
static unsigned crew_parked_max(void)
{
    const unsigned cores = as_thread_count(0);
    return cores > 16 ? 2 * cores : 32;
}

/* In a child after fork() the parent's threads do not exist: forget them
 * (their records stay allocated) and start afresh. */
static void crew_after_fork_in_child(void)
{
    pthread_mutex_init(&crew_lock, NULL);
    pthread_cond_init(&crew_done, NULL);
    crew_idle = NULL;
    crew_parked = 0;
}

static void crew_init(void) { pthread_atfork(NULL, NULL, crew_after_fork_in_child); }

static void *crew_main(void *arg)
{
    crew_thread *t = arg;
    const unsigned parked_max = crew_parked_max();
    pthread_mutex_lock(&crew_lock);
    for (;;) {
        as_crew_batch *b = atomic_load_explicit(&t->batch, memory_order_acquire);
        if (!b && !crew_quit) {
            pthread_mutex_unlock(&crew_lock);
            as_spin_until(batch_given, t);
            pthread_mutex_lock(&crew_lock);
            b = atomic_load_explicit(&t->batch, memory_order_acquire);
            while (!b && !crew_quit) {
                t->asleep = 1;
                pthread_cond_wait(&t->wake, &crew_lock);
                t->asleep = 0;
                b = atomic_load_explicit(&t->batch, memory_order_acquire);
            }
        }
        if (!b) break; /* unloading: crew_release took it off the idle list and joins it */
        const unsigned i = t->index;
        pthread_mutex_unlock(&crew_lock);
        b->fn(b->user, i);
        pthread_mutex_lock(&crew_lock);
        atomic_store_explicit(&t->batch, NULL, memory_order_relaxed);
        const int leave = crew_quit || crew_parked >= parked_max;
        if (!leave) {
            t->next_idle = crew_idle;
            crew_idle = t;
            crew_parked++;
        }
        /* b may be gone as soon as its owner sees the count complete (it
         * watches it without the lock): its fields are read first, and
         * nothing of it after. */
        const unsigned started = b->n - b->unstarted;
        if (atomic_fetch_add_explicit(&b->finished, 1, memory_order_release) + 1 == started)
            pthread_cond_broadcast(&crew_done);
        if (leave) {
            pthread_mutex_unlock(&crew_lock);
            pthread_detach(pthread_self());
            pthread_cond_destroy(&t->wake);
            free(t);
            return NULL;
        }
    }
    pthread_mutex_unlock(&crew_lock);
    return NULL;
}

/* A new thread, waiting (not on the idle list); NULL when none could be
 * started. Called with crew_lock held. The thread blocks every signal, so
 * that signals go to the application's own threads. */
static crew_thread *crew_new_thread(void)
{
    crew_thread *t = calloc(1, sizeof *t);
    if (!t) return NULL;
    if (pthread_cond_init(&t->wake, NULL) != 0) {
        free(t);
        return NULL;
    }
    sigset_t all, old;
    sigfillset(&all);
    pthread_sigmask(SIG_SETMASK, &all, &old);
    const int ok = pthread_create(&t->tid, NULL, crew_main, t) == 0;
    pthread_sigmask(SIG_SETMASK, &old, NULL);
    if (!ok) {
        pthread_cond_destroy(&t->wake);
        free(t);
        return NULL;
    }
    return t;
}

/* When the library is unloaded (dlclose, or the process ending), the
 * waiting threads are told to leave and joined, so that none is left in
 * code that is no longer there. Threads still running a step (a build on
 * another thread) are not waited for: they leave when they finish. */
__attribute__((destructor)) static void crew_release(void)
{
    pthread_mutex_lock(&crew_lock);
    crew_quit = 1;
    crew_thread *leaving = crew_idle;
    crew_idle = NULL;
    crew_parked = 0;
    for (crew_thread *t = leaving; t; t = t->next_idle) pthread_cond_signal(&t->wake);
    pthread_mutex_unlock(&crew_lock);
    while (leaving) {
        crew_thread *t = leaving;
        leaving = t->next_idle;
        pthread_join(t->tid, NULL);
        pthread_cond_destroy(&t->wake);
        free(t);
    }
}

void as_crew_start(as_crew_batch *b, unsigned n, void (*fn)(void *user, unsigned i), void *user)
{
    pthread_once(&crew_once, crew_init);
    b->fn = fn;
    b->user = user;
    b->n = n;
    atomic_init(&b->finished, 0);
    b->unstarted = 0;
    pthread_mutex_lock(&crew_lock);
    for (unsigned i = 0; i < n; ++i) {
        crew_thread *t = crew_idle;
        if (t) {
            crew_idle = t->next_idle;
            crew_parked--;
        } else {
            t = crew_quit ? NULL : crew_new_thread();
        }
        if (!t) {
            b->unstarted = n - i;
            break;
        }
        t->index = i;
        atomic_store_explicit(&t->batch, b, memory_order_release);
        if (t->asleep) pthread_cond_signal(&t->wake);
    }
    pthread_mutex_unlock(&crew_lock);
}

void as_crew_wait(as_crew_batch *b)
{
    for (unsigned i = b->n - b->unstarted; i < b->n; ++i) b->fn(b->user, i);
    if (as_spin_until(batch_finished, b)) return;
    pthread_mutex_lock(&crew_lock);
    while (!batch_finished(b)) pthread_cond_wait(&crew_done, &crew_lock);
    pthread_mutex_unlock(&crew_lock);
}
