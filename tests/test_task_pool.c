/* The builders' threads: as_parallel_run runs every index exactly once,
 * outside a pool on threads of its own and inside a task of
 * as_task_pool_run on the pool's idle threads, which do take part; steps of
 * two tasks that overlap both finish, and the pool ends when every task is
 * done. The threads are kept from one step to the next (a second step runs
 * on the first one's threads), steps started from inside a step finish, and
 * a child process after fork() runs steps on threads of its own. */
#include "as/as.h"
#include "task_pool.h"
#include "test_util.h"

#include <pthread.h>
#include <signal.h>
#include <stdatomic.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#define MAX_INDICES 256

typedef struct step {
    atomic_uint runs[MAX_INDICES];
    atomic_uint total;
    unsigned n;
    pthread_t owner[MAX_INDICES];
} step;

static void count_index(void *user, unsigned i, unsigned n)
{
    step *s = user;
    if (n != s->n) return; /* counted as missing below */
    atomic_fetch_add(&s->runs[i], 1);
    atomic_fetch_add(&s->total, 1);
    s->owner[i] = pthread_self();
    /* A little work, so that idle threads have time to join. */
    volatile unsigned x = 0;
    for (unsigned k = 0; k < 20000; ++k) x += k;
}

static int each_index_once(step *s)
{
    int bad = 0;
    for (unsigned i = 0; i < s->n; ++i) bad += atomic_load(&s->runs[i]) != 1;
    return bad == 0 && atomic_load(&s->total) == s->n;
}

static void step_init(step *s, unsigned n)
{
    memset(s, 0, sizeof *s);
    s->n = n;
}

static void outside_a_pool_every_index_runs_once(void)
{
    const unsigned ns[] = {1, 2, 3, 16, 256};
    for (size_t k = 0; k < sizeof ns / sizeof ns[0]; ++k) {
        step s;
        step_init(&s, ns[k]);
        as_parallel_run(ns[k], count_index, &s);
        CHECK(each_index_once(&s));
    }
}

/* Tasks: a tree of depth 3, each task pushing two children and running a
 * parallel step of its own, so that steps overlap and meet idle threads. */
typedef struct tree_task {
    unsigned depth;
    unsigned id;
} tree_task;

static step steps[15];
static atomic_uint tasks_run;

static void tree_run(as_task_pool *pool, void *task, void *user)
{
    (void)user;
    tree_task t;
    memcpy(&t, task, sizeof t);
    atomic_fetch_add(&tasks_run, 1);
    if (t.depth < 3) {
        const tree_task l = {t.depth + 1, 2 * t.id + 1}, r = {t.depth + 1, 2 * t.id + 2};
        if (!as_task_pool_push(pool, &l)) tree_run(pool, (void *)&l, user);
        if (!as_task_pool_push(pool, &r)) tree_run(pool, (void *)&r, user);
    }
    if (t.id < 15) as_parallel_run(steps[t.id].n, count_index, &steps[t.id]);
}

static void inside_a_pool_every_index_runs_once(void)
{
    const unsigned threads[] = {1, 2, 3, 8};
    for (size_t k = 0; k < sizeof threads / sizeof threads[0]; ++k) {
        for (unsigned i = 0; i < 15; ++i) step_init(&steps[i], 1 + (i * 37) % 64);
        atomic_store(&tasks_run, 0);
        const tree_task root = {0, 0};
        CHECK(as_task_pool_run(threads[k], sizeof root, &root, tree_run, NULL));
        CHECK_EQ_INT(atomic_load(&tasks_run), 15);
        int bad = 0;
        for (unsigned i = 0; i < 15; ++i) bad += !each_index_once(&steps[i]);
        if (bad) fprintf(stderr, "     %u threads: %d steps ran an index other than once\n", threads[k], bad);
        CHECK_EQ_INT(bad, 0);
    }
}

/* One task with a long step and nothing else to do: the pool's other
 * threads, idle, take part of it. */
static step lone;
static void lone_run(as_task_pool *pool, void *task, void *user)
{
    (void)pool;
    (void)task;
    (void)user;
    as_parallel_run(lone.n, count_index, &lone);
}

static void idle_pool_threads_take_part_in_a_step(void)
{
    int helped = 0;
    /* On a loaded machine the other threads may get no core during a step
     * of a few milliseconds: up to 200 tries (a second), until one helps. */
    for (int attempt = 0; attempt < 200 && !helped; ++attempt) {
        step_init(&lone, 256);
        const char dummy = 0;
        CHECK(as_task_pool_run(4, 1, &dummy, lone_run, NULL));
        CHECK(each_index_once(&lone));
        for (unsigned i = 1; i < lone.n; ++i) helped |= !pthread_equal(lone.owner[i], lone.owner[0]);
    }
    CHECK(helped);
}

/* Two tasks' steps, one published after the other's owner has stopped
 * publishing but still waits for its helper: each owner must wake when its
 * own helpers are done, whichever finishes first. A hang fails the test by
 * the watchdog below. */
static void sleep_ms(unsigned ms)
{
    const struct timespec t = {(time_t)(ms / 1000), (long)(ms % 1000) * 1000000L};
    nanosleep(&t, NULL);
}

static void long_second_index(void *user, unsigned i, unsigned n)
{
    (void)user;
    (void)n;
    sleep_ms(i == 0 ? 5 : 120);
}

static void short_second_index(void *user, unsigned i, unsigned n)
{
    (void)user;
    (void)n;
    sleep_ms(i == 0 ? 5 : 20);
}

static void overlap_run(as_task_pool *pool, void *task, void *user)
{
    (void)user;
    const int kind = *(const int *)task;
    if (kind == 0) {
        const int a = 1, b = 2;
        if (!as_task_pool_push(pool, &a)) overlap_run(pool, (void *)&a, user);
        if (!as_task_pool_push(pool, &b)) overlap_run(pool, (void *)&b, user);
        return;
    }
    if (kind == 1) {
        as_parallel_run(2, long_second_index, NULL);
        return;
    }
    sleep_ms(20);
    as_parallel_run(2, short_second_index, NULL);
}

static atomic_int overlap_done;

static void *overlap_watchdog(void *arg)
{
    (void)arg;
    for (int i = 0; i < 300 && !atomic_load(&overlap_done); ++i) sleep_ms(100);
    if (!atomic_load(&overlap_done)) {
        fprintf(stderr, "%s: two overlapping steps did not finish within 30 s (a lost wake-up)\n", __FILE__);
        fprintf(stderr, "FAIL two_overlapping_steps_both_finish\n");
        _exit(1);
    }
    return NULL;
}

static void two_overlapping_steps_both_finish(void)
{
    atomic_store(&overlap_done, 0);
    pthread_t w;
    const int watching = pthread_create(&w, NULL, overlap_watchdog, NULL) == 0;
    for (int round = 0; round < 8; ++round) {
        const int root = 0;
        CHECK(as_task_pool_run(4, sizeof root, &root, overlap_run, NULL));
    }
    atomic_store(&overlap_done, 1);
    if (watching) pthread_join(w, NULL);
}

/* How many indices this thread ran before, in any step: a thread started
 * for a step has run none. */
static _Thread_local unsigned indices_run_here;
static unsigned ran_before[8];

static void note_thread(void *user, unsigned i, unsigned n)
{
    (void)user;
    (void)n;
    ran_before[i] = indices_run_here++;
    volatile unsigned x = 0; /* a little work, so that no thread takes two */
    for (unsigned k = 0; k < 200000; ++k) x += k;
}

static void a_second_step_runs_on_the_first_steps_threads(void)
{
    as_parallel_run(8, note_thread, NULL);
    as_parallel_run(8, note_thread, NULL);
    /* Index 0 is the caller's; the others ran on kept threads. */
    unsigned kept = 0;
    for (unsigned i = 1; i < 8; ++i) kept += ran_before[i] > 0;
    if (kept != 7) fprintf(stderr, "  %u of 7 indices of the second step on threads that ran one before\n", kept);
    CHECK_EQ_INT((int)kept, 7);
}

static step inner_steps[4];

static void start_inner_step(void *user, unsigned i, unsigned n)
{
    (void)user;
    (void)n;
    step_init(&inner_steps[i], 16);
    as_parallel_run(16, count_index, &inner_steps[i]);
}

static void steps_started_inside_a_step_finish(void)
{
    as_parallel_run(4, start_inner_step, NULL);
    for (int i = 0; i < 4; ++i) CHECK(each_index_once(&inner_steps[i]));
}

static void a_forked_child_runs_steps_on_threads_of_its_own(void)
{
    step s;
    step_init(&s, 8);
    as_parallel_run(8, count_index, &s); /* the parent now keeps threads */
    const pid_t pid = fork();
    if (pid == 0) {
        step c;
        step_init(&c, 8);
        as_parallel_run(8, count_index, &c);
        _exit(each_index_once(&c) ? 0 : 1);
    }
    CHECK(pid > 0);
    int status = 0;
    if (pid > 0) {
        /* A child waiting on its parent's threads would wait for ever. */
        int waited = 0;
        for (int i = 0; i < 300 && !waited; ++i) {
            waited = waitpid(pid, &status, WNOHANG) == pid;
            if (!waited) sleep_ms(100);
        }
        if (!waited) {
            kill(pid, SIGKILL);
            waitpid(pid, &status, 0);
            fprintf(stderr, "  the child did not finish within 30 s\n");
        }
        CHECK(waited && WIFEXITED(status) && WEXITSTATUS(status) == 0);
    }
}

int main(void)
{
    RUN_TEST(outside_a_pool_every_index_runs_once);
    RUN_TEST(inside_a_pool_every_index_runs_once);
    RUN_TEST(idle_pool_threads_take_part_in_a_step);
    RUN_TEST(two_overlapping_steps_both_finish);
    RUN_TEST(a_second_step_runs_on_the_first_steps_threads);
    RUN_TEST(steps_started_inside_a_step_finish);
    RUN_TEST(a_forked_child_runs_steps_on_threads_of_its_own);
    TEST_EXIT();
}
