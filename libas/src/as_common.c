/* Common layer: version, memory, clocks, threads, hashing. */
#define _POSIX_C_SOURCE 200809L
#include "as_internal.h"
#include "thread_crew.h"

#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <time.h>
#include <unistd.h>

#define XXH_INLINE_ALL
#include <xxhash.h>

unsigned as_version_number(void) { return AS_VERSION_NUMBER; }
const char *as_version_string(void) { return AS_VERSION_STRING; }

int as_cpu_has_avx2(void)
{
#if defined(__x86_64__) && defined(__GNUC__)
    static atomic_int known = 0; /* 0: not asked, 1: no, 2: yes */
    int k = atomic_load_explicit(&known, memory_order_relaxed);
    if (!k) {
        __builtin_cpu_init();
        k = __builtin_cpu_supports("avx2") ? 2 : 1;
        atomic_store_explicit(&known, k, memory_order_relaxed);
    }
    return k == 2;
#else
    return 0;
#endif
}

void *as_malloc(size_t bytes, const char *what)
{
    void *p = malloc(bytes ? bytes : 1);
    if (!p) as_set_error(AS_ERROR_OUT_OF_MEMORY, "out of memory allocating %zu bytes for %s", bytes, what);
    return p;
}

void *as_calloc(size_t count, size_t size, const char *what)
{
    void *p = calloc(count ? count : 1, size ? size : 1);
    if (!p) as_set_error(AS_ERROR_OUT_OF_MEMORY, "out of memory allocating %zu x %zu bytes for %s", count, size, what);
    return p;
}

double as_now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec * 1e-6;
}

unsigned as_thread_count(unsigned requested)
{
    if (requested) return requested;
    /* Asked once: glibc answers by reading /sys on every call, and builders
     * ask per node. */
    static atomic_uint cores;
    unsigned n = atomic_load_explicit(&cores, memory_order_relaxed);
    if (!n) {
        const long online = sysconf(_SC_NPROCESSORS_ONLN);
        n = online > 0 ? (unsigned)online : 1u;
        atomic_store_explicit(&cores, n, memory_order_relaxed);
    }
    return n;
}

typedef struct parallel_job {
    as_parallel_fn fn;
    void *user;
    size_t count;
    atomic_size_t next;
} parallel_job;

static void parallel_worker(void *user, unsigned thread)
{
    (void)thread;
    parallel_job *job = user;
    for (;;) {
        const size_t i = atomic_fetch_add(&job->next, 1);
        if (i >= job->count) break;
        job->fn(job->user, i);
    }
}

void as_parallel_for(unsigned threads, size_t count, as_parallel_fn fn, void *user)
{
    parallel_job job = {fn, user, count, 0};
    if (threads > count) threads = (unsigned)count;
    if (threads > 256) threads = 256; /* as as_parallel_run: no core count comes near */
    if (threads <= 1) {
        parallel_worker(&job, 0);
        return;
    }
    as_crew_batch crew;
    as_crew_start(&crew, threads - 1, parallel_worker, &job);
    parallel_worker(&job, 0); /* the caller works too */
    as_crew_wait(&crew);
}

uint64_t as_hash64(const void *data, size_t bytes) { return XXH3_64bits(data, bytes); }

uint64_t as_hash64_seeded(const void *data, size_t bytes, uint64_t seed)
{
    return XXH3_64bits_withSeed(data, bytes, seed);
}
