/*
 * cull_pool.c — a persistent job pool: threads-1 workers that wait on a
 * generation counter, plus the caller as thread 0. A job is "run fn(arg, t)
 * on every thread and wait"; work inside a job is split by the job itself
 * (an atomic counter over blocks). No thread is created per query.
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
    uint32_t tid;
} worker;

struct cull_pool {
    uint32_t nthreads;
    pthread_t *threads;
    worker *workers;
    pthread_mutex_t mu;
    pthread_cond_t cv;
    _Atomic uint32_t gen;
    _Atomic uint32_t pending;
    _Atomic int stop;
    cull_job_fn fn;
    void *arg;
    uint32_t n;
};

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
        if (wk->tid < p->n) p->fn(p->arg, wk->tid);
        atomic_fetch_sub_explicit(&p->pending, 1, memory_order_acq_rel);
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
            p->workers[i] = (worker){p, i + 1};
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
    p->fn = fn;
    p->arg = arg;
    p->n = n;
    atomic_store_explicit(&p->pending, p->nthreads - 1, memory_order_relaxed);
    pthread_mutex_lock(&p->mu);
    atomic_fetch_add_explicit(&p->gen, 1, memory_order_release);
    pthread_cond_broadcast(&p->cv);
    pthread_mutex_unlock(&p->mu);
    fn(arg, 0);
    while (atomic_load_explicit(&p->pending, memory_order_acquire) != 0) cpu_relax();
}
