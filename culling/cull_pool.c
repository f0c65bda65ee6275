/*
 * cull_pool.c — a persistent job pool: threads-1 workers that wait on a
 * generation counter, plus the caller. A job is "run fn(arg, t) for every
 * t in 0..n-1 and wait". The n slots are claimed, not assigned: the caller
 * and every worker that wakes take the next unclaimed slot until none is
 * left. So a worker the scheduler has not run yet (a loaded machine: the
 * daemon's loop, other workers, other processes) delays nothing: the caller
 * runs that slot itself, and the worker, when it does wake, finds the job
 * taken and sleeps again. The caller waits only for slots being run.
 *
 * The claim word packs the job's sequence number, n and the next slot, so
 * a worker still looking at an old job cannot take a slot of the next one
 * with the old job's n: a claim is one compare-and-swap on all three. A
 * job cannot end, so fn and arg cannot change, while a slot of it is
 * claimed and not done.
 *
 * Waking: workers spin briefly (a query arrives right after another under
 * load), then sleep on a condition variable, so an idle daemon costs no CPU.
 * A dispatch costs ~1-3 µs when workers are spinning, ~10-30 µs from sleep.
 */
#include "cull_internal.h"

#include <pthread.h>
#include <stdlib.h>
#include <unistd.h>
#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define cpu_relax() _mm_pause()
#else
#define cpu_relax() ((void)0)
#endif

#define POOL_SPIN 4000 /* ~30-60 µs of pause instructions */

typedef struct worker {
    struct cull_pool *pool;
} worker;

struct cull_pool {
    uint32_t nthreads;
    pthread_t *threads;
    worker *workers;
    pthread_mutex_t mu;
    pthread_cond_t cv;
    _Atomic uint32_t gen;   /* moves once per job: wakes the workers */
    _Atomic uint64_t claim; /* job sequence << 32 | n << 16 | next slot */
    _Atomic uint32_t done;  /* slots of the current job finished */
    _Atomic int stop;
    cull_job_fn fn;
    void *arg;
};

/* Takes slots of the current job and runs them until none is left. */
static void run_slots(struct cull_pool *p)
{
    uint64_t c = atomic_load_explicit(&p->claim, memory_order_acquire);
    for (;;) {
        uint32_t next = (uint32_t)(c & 0xffff), n = (uint32_t)((c >> 16) & 0xffff);
        if (next >= n) return;
        if (!atomic_compare_exchange_weak_explicit(&p->claim, &c, c + 1, memory_order_acq_rel,
                                                   memory_order_acquire))
            continue; /* c now holds the current word */
        p->fn(p->arg, next);
        atomic_fetch_add_explicit(&p->done, 1, memory_order_release);
        c = atomic_load_explicit(&p->claim, memory_order_acquire);
    }
}

static void *worker_main(void *p_)
{
    worker *wk = p_;
    struct cull_pool *p = wk->pool;
    uint32_t seen = 0;
    for (;;) {
        uint32_t g = atomic_load_explicit(&p->gen, memory_order_acquire);
        for (int i = 0; i < POOL_SPIN && g == seen && !atomic_load(&p->stop); i++) {
            cpu_relax();
            g = atomic_load_explicit(&p->gen, memory_order_acquire);
        }
        if (g == seen) {
            pthread_mutex_lock(&p->mu);
            while ((g = atomic_load_explicit(&p->gen, memory_order_acquire)) == seen &&
                   !atomic_load(&p->stop))
                pthread_cond_wait(&p->cv, &p->mu);
            pthread_mutex_unlock(&p->mu);
        }
        if (atomic_load(&p->stop)) return NULL;
        seen = g;
        run_slots(p);
    }
}

int cull_pool_create(uint32_t threads, cull_pool **out)
{
    if (!out) return CULL_ERR_INVALID;
    *out = NULL;
    if (threads == 0) {
        long n = sysconf(_SC_NPROCESSORS_ONLN);
        threads = n > 0 ? (uint32_t)n : 1;
    }
    if (threads > 256) threads = 256;
    struct cull_pool *p = calloc(1, sizeof *p);
    if (!p) return CULL_ERR_NOMEM;
    p->nthreads = threads;
    pthread_mutex_init(&p->mu, NULL);
    pthread_cond_init(&p->cv, NULL);
    if (threads > 1) {
        p->threads = calloc(threads - 1, sizeof *p->threads);
        p->workers = calloc(threads - 1, sizeof *p->workers);
        if (!p->threads || !p->workers) {
            p->nthreads = 1; /* no worker started: nothing to join */
            cull_pool_destroy(p);
            return CULL_ERR_NOMEM;
        }
        for (uint32_t i = 0; i + 1 < threads; i++) {
            p->workers[i] = (worker){p};
            if (pthread_create(&p->threads[i], NULL, worker_main, &p->workers[i])) {
                p->nthreads = i + 1; /* join what started */
                cull_pool_destroy(p);
                return CULL_ERR_THREADS;
            }
        }
    }
    *out = p;
    return CULL_OK;
}

void cull_pool_destroy(cull_pool *p)
{
    if (!p) return;
    pthread_mutex_lock(&p->mu);
    atomic_store(&p->stop, 1);
    pthread_cond_broadcast(&p->cv);
    pthread_mutex_unlock(&p->mu);
    if (p->threads)
        for (uint32_t i = 0; i + 1 < p->nthreads; i++) pthread_join(p->threads[i], NULL);
    pthread_mutex_destroy(&p->mu);
    pthread_cond_destroy(&p->cv);
    free(p->threads);
    free(p->workers);
    free(p);
}

uint32_t cull_pool_threads(const cull_pool *p)
{
    return p ? p->nthreads : 1;
}

void cull_pool_run(cull_pool *p, cull_job_fn fn, void *arg, uint32_t n)
{
    if (!p || p->nthreads <= 1 || n <= 1) {
        fn(arg, 0);
        return;
    }
    if (n > p->nthreads) n = p->nthreads;
    /* the last job is over (its slots all done): nobody reads fn, arg or
       done until the new claim word is seen */
    p->fn = fn;
    p->arg = arg;
    atomic_store_explicit(&p->done, 0, memory_order_relaxed);
    uint64_t seq = (atomic_load_explicit(&p->claim, memory_order_relaxed) >> 32) + 1;
    atomic_store_explicit(&p->claim, (seq & 0xffffffffu) << 32 | (uint64_t)n << 16, memory_order_release);
    pthread_mutex_lock(&p->mu);
    atomic_fetch_add_explicit(&p->gen, 1, memory_order_release);
    pthread_cond_broadcast(&p->cv);
    pthread_mutex_unlock(&p->mu);
    run_slots(p);
    /* every slot is claimed: what is left are slots other threads are running */
    while (atomic_load_explicit(&p->done, memory_order_acquire) != n) cpu_relax();
}

/* cull_pool_each's job: the items' next index, claimed one at a time;
 * the side job, taken by the first slot to start. */
typedef struct each_job {
    cull_each_fn fn;
    void *arg;
    uint32_t n;
    _Atomic uint32_t next;
    cull_side_fn side;
    void *side_arg;
    _Atomic int side_taken;
} each_job;

static void each_run(void *arg, uint32_t t)
{
    each_job *j = arg;
    (void)t;
    if (j->side && !atomic_exchange_explicit(&j->side_taken, 1, memory_order_relaxed)) j->side(j->side_arg);
    for (uint32_t k; (k = atomic_fetch_add_explicit(&j->next, 1, memory_order_relaxed)) < j->n;) j->fn(j->arg, k);
}

void cull_pool_each_side(cull_pool *p, uint32_t threads, uint32_t n, cull_each_fn fn, void *arg, cull_side_fn side,
                         void *side_arg)
{
    each_job j = {.fn = fn, .arg = arg, .n = n, .side = side, .side_arg = side_arg};
    atomic_init(&j.next, 0);
    atomic_init(&j.side_taken, 0);
    uint32_t nt = p ? p->nthreads : 1;
    if (threads && threads < nt) nt = threads;
    if (nt > n) nt = n;
    if (!nt) nt = 1; /* no items: the side job still runs */
    cull_pool_run(p, each_run, &j, nt); /* every slot claims items until none is left */
}

void cull_pool_each(cull_pool *p, uint32_t threads, uint32_t n, cull_each_fn fn, void *arg)
{
    cull_pool_each_side(p, threads, n, fn, arg, NULL, NULL);
}
