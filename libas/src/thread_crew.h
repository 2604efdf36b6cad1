/* Threads kept from one parallel step to the next, and from build to build.
 *
 * Starting a thread costs tens of microseconds and a fresh stack; a build on
 * 16 threads started about 45 of them (the task pool's and each parallel
 * step's), which on small scenes was a large part of the build. Threads that
 * finish their work here wait for the next instead of exiting. Each index of
 * a batch goes to a thread of its own, as a started thread did before: a
 * batch never waits on another batch's threads, so nested batches cannot
 * deadlock. A child process after fork() starts its own threads. */
#ifndef AS_THREAD_CREW_H
#define AS_THREAD_CREW_H

#include <stdatomic.h>

typedef struct as_crew_batch {
    void (*fn)(void *user, unsigned i);
    void *user;
    unsigned n;
    atomic_uint finished; /* incremented under the crew's lock */
    unsigned unstarted; /* indices [n - unstarted, n) no thread took: as_crew_wait runs them */
} as_crew_batch;

/* A thread that runs out of work here (a crew thread after its index, a
 * caller waiting for its batch, a task pool's thread with no task) first
 * watches for more for this long before it sleeps: waking a sleeping thread
 * took 30 to 70 us a parallel step on the 2-core VM (a step of two indices
 * of 13 us took 82 us, and 9 us with the watch), and a build takes tens of
 * steps, most of them with little serial work between them. */
#define AS_SPIN_NS 100000
/* Watches for ready(arg) for up to AS_SPIN_NS; returns whether it held. */
int as_spin_until(int (*ready)(const void *arg), const void *arg);

/* Starts fn(user, i) for each i in [0, n) on threads of the crew, which
 * grows when none waits; returns at once. */
void as_crew_start(as_crew_batch *b, unsigned n, void (*fn)(void *user, unsigned i), void *user);

/* Returns when every index of b has run (those no thread could be started
 * for run here, on the caller's thread). */
void as_crew_wait(as_crew_batch *b);

#endif
