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

typedef struct as_crew_batch {
    void (*fn)(void *user, unsigned i);
    void *user;
    unsigned n;
    unsigned finished;  /* under the crew's lock */
    unsigned unstarted; /* indices [n - unstarted, n) no thread took: as_crew_wait runs them */
} as_crew_batch;

/* Starts fn(user, i) for each i in [0, n) on threads of the crew, which
 * grows when none waits; returns at once. */
void as_crew_start(as_crew_batch *b, unsigned n, void (*fn)(void *user, unsigned i), void *user);

/* Returns when every index of b has run (those no thread could be started
 * for run here, on the caller's thread). */
void as_crew_wait(as_crew_batch *b);

#endif
