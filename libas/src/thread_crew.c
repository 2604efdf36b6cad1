/* Threads kept between parallel steps (see thread_crew.h). */
#include "thread_crew.h"

#include <pthread.h>
#include <stdlib.h>

typedef struct crew_thread {
    pthread_cond_t wake;
    as_crew_batch *batch; /* NULL while waiting */
    unsigned index;
    struct crew_thread *next_idle;
} crew_thread;

static pthread_mutex_t crew_lock = PTHREAD_MUTEX_INITIALIZER;
static pthread_cond_t crew_done = PTHREAD_COND_INITIALIZER;
static crew_thread *crew_idle;    /* under crew_lock */
static int crew_quit;             /* under crew_lock: the library is being unloaded */
static unsigned crew_parked;      /* under crew_lock: threads on crew_idle */
static pthread_once_t crew_once = PTHREAD_ONCE_INIT;

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
    pthread_mutex_lock(&crew_lock);
    for (;;) {
        while (!t->batch && !crew_quit) pthread_cond_wait(&t->wake, &crew_lock);
        if (!t->batch) break; /* quitting, and parked: leave the idle list */
        as_crew_batch *b = t->batch;
        const unsigned i = t->index;
        pthread_mutex_unlock(&crew_lock);
        b->fn(b->user, i);
        pthread_mutex_lock(&crew_lock);
        t->batch = NULL;
        t->next_idle = crew_idle;
        crew_idle = t;
        crew_parked++;
        /* b may be gone once its owner sees it finished: nothing of it is
         * read after this. */
        if (++b->finished == b->n - b->unstarted) pthread_cond_broadcast(&crew_done);
    }
    /* Unloading: off the idle list, and the unloader told. */
    crew_thread **at = &crew_idle;
    while (*at && *at != t) at = &(*at)->next_idle;
    if (*at) {
        *at = t->next_idle;
        crew_parked--;
    }
    pthread_cond_broadcast(&crew_done);
    pthread_mutex_unlock(&crew_lock);
    pthread_cond_destroy(&t->wake);
    free(t);
    return NULL;
}

/* When the library is unloaded (dlclose, or the process ending), the parked
 * threads leave, so that none waits in code that is no longer there;
 * threads still running a step (a build on another thread) are not waited
 * for. */
__attribute__((destructor)) static void crew_release(void)
{
    pthread_mutex_lock(&crew_lock);
    crew_quit = 1;
    for (crew_thread *t = crew_idle; t; t = t->next_idle) pthread_cond_signal(&t->wake);
    while (crew_parked > 0) pthread_cond_wait(&crew_done, &crew_lock);
    pthread_mutex_unlock(&crew_lock);
}

/* A new thread, waiting (not on the idle list); NULL when none could be
 * started. Called with crew_lock held. */
static crew_thread *crew_new_thread(void)
{
    crew_thread *t = calloc(1, sizeof *t);
    if (!t) return NULL;
    if (pthread_cond_init(&t->wake, NULL) != 0) {
        free(t);
        return NULL;
    }
    pthread_attr_t attr;
    pthread_t tid;
    int ok = pthread_attr_init(&attr) == 0;
    if (ok) {
        pthread_attr_setdetachstate(&attr, PTHREAD_CREATE_DETACHED);
        ok = pthread_create(&tid, &attr, crew_main, t) == 0;
        pthread_attr_destroy(&attr);
    }
    if (!ok) {
        pthread_cond_destroy(&t->wake);
        free(t);
        return NULL;
    }
    return t;
}

void as_crew_start(as_crew_batch *b, unsigned n, void (*fn)(void *user, unsigned i), void *user)
{
    pthread_once(&crew_once, crew_init);
    b->fn = fn;
    b->user = user;
    b->n = n;
    b->finished = 0;
    b->unstarted = 0;
    pthread_mutex_lock(&crew_lock);
    for (unsigned i = 0; i < n; ++i) {
        crew_thread *t = crew_idle;
        if (t) {
            crew_idle = t->next_idle;
            crew_parked--;
        } else {
            t = crew_new_thread();
        }
        if (!t) {
            b->unstarted = n - i;
            break;
        }
        t->batch = b;
        t->index = i;
        pthread_cond_signal(&t->wake);
    }
    pthread_mutex_unlock(&crew_lock);
}

void as_crew_wait(as_crew_batch *b)
{
    for (unsigned i = b->n - b->unstarted; i < b->n; ++i) b->fn(b->user, i);
    pthread_mutex_lock(&crew_lock);
    while (b->finished < b->n - b->unstarted) pthread_cond_wait(&crew_done, &crew_lock);
    pthread_mutex_unlock(&crew_lock);
}
