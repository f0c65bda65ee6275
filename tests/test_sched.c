/*
 * test_sched.c — the daemon's workers serve queries before frames: a
 * query waits at most for the frame a worker is drawing, not behind every
 * frame due. Six viewers keep one worker drawing 640x360 frames of the demo
 * city (an editor keeps the scene changing); a client asks 40 queries.
 * With one FIFO (before the fix) a query waited behind up to six frames;
 * the test holds the queries' median latency under 3 frames' median
 * render + encode time, both measured in the same run, so it does not
 * depend on how fast this machine is.
 */
#include "test_daemon.h"
#include "test_util.h"

#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

enum { VIEWERS = 6, QUERIES = 40, MAX_FRAMES = 4096 };

typedef struct sched_run {
    const daemon_proc *d;
    _Atomic int stop;
    pthread_mutex_t mu;
    double frame_ms[MAX_FRAMES]; /* the daemon's render + encode time per frame */
    int nframes;
} sched_run;

static double now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec / 1e6;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double median(double *v, int n)
{
    qsort(v, (size_t)n, sizeof *v, cmp_double);
    return n ? v[n / 2] : 0;
}

static void *viewer_main(void *arg)
{
    sched_run *r = arg;
    vtc_client *v = connect_role(r->d, VP_ROLE_VIEWER, true);
    vp_frame_sub sub = {.r = {.format = VP_FRAME_JPEG, .quality = 80}, .max_fps = VP_FRAME_SUB_MAX_FPS};
    const double eye[3] = {-150, 60, -150}, at[3] = {0, 0, 0};
    assert_true(vtc_view_perspective(&sub.r.view, eye, at, NULL, 60, 320, 180, 0.5, 2000));
    assert_int_equal(vtc_frame_subscribe(v, &sub), VP_OK);
    while (!atomic_load(&r->stop)) {
        vp_frame f;
        int rc = vtc_wait_frame(v, &f, 200);
        if (rc == VTC_ERR_IO) continue; /* none in 200 ms */
        assert_int_equal(rc, VP_OK);
        pthread_mutex_lock(&r->mu);
        if (r->nframes < MAX_FRAMES) r->frame_ms[r->nframes++] = (f.render_ns + (double)f.encode_ns) / 1e6;
        pthread_mutex_unlock(&r->mu);
    }
    vtc_close(v);
    return NULL;
}

static void *editor_main(void *arg)
{
    sched_run *r = arg;
    vtc_client *ed = connect_role(r->d, VP_ROLE_EDITOR, true);
    vp_entity e = {.id = 1u << 30, .sphere = {0, 5, 0, 2}};
    assert_int_equal(vtc_add(ed, &e, 1, NULL, NULL), VP_OK);
    for (int i = 0; !atomic_load(&r->stop); i++) {
        e.sphere[0] = i % 50;
        assert_int_equal(vtc_update(ed, &e, 1, NULL), VP_OK);
        usleep(5000);
    }
    vtc_close(ed);
    return NULL;
}

static void test_queries_before_frames(void **state)
{
    (void)state;
    daemon_proc d;
    /* small frames without the costliest effects: the test is about the
       order work is taken in, not about pictures (issue 20's frames made
       it 32 s under ASan) */
    const char *extra[] = {"--scene", "demo", "--threads", "1", "--fx-off", "shadows,ssao", NULL};
    daemon_start_args(&d, extra);
    sched_run *r = calloc(1, sizeof *r);
    r->d = &d;
    pthread_mutex_init(&r->mu, NULL);
    pthread_t th[VIEWERS + 1];
    for (int i = 0; i < VIEWERS; i++) assert_int_equal(pthread_create(&th[i], NULL, viewer_main, r), 0);
    assert_int_equal(pthread_create(&th[VIEWERS], NULL, editor_main, r), 0);
    /* the worker is busy with frames before the first query */
    for (int i = 0; i < 500; i++) {
        pthread_mutex_lock(&r->mu);
        int n = r->nframes;
        pthread_mutex_unlock(&r->mu);
        if (n >= 2 * VIEWERS) break;
        usleep(10000);
    }
    vtc_client *q = connect_role(&d, VP_ROLE_VIEWER, true);
    vp_view view;
    const double eye[3] = {0, 30, -200}, at[3] = {0, 0, 0};
    assert_true(vtc_view_perspective(&view, eye, at, NULL, 60, 1280, 720, 0.5, 2000));
    double lat[QUERIES];
    for (int i = 0; i < QUERIES; i++) {
        vp_vis_result res;
        double t0 = now_ms();
        assert_int_equal(vtc_query(q, &view, 1, VP_Q_COUNT_ONLY, 0, &res), VP_OK);
        lat[i] = now_ms() - t0;
        usleep(20000);
    }
    vtc_close(q);
    atomic_store(&r->stop, 1);
    for (int i = 0; i <= VIEWERS; i++) pthread_join(th[i], NULL);
    int nf = r->nframes;
    double fm = median(r->frame_ms, nf), qm = median(lat, QUERIES); /* both now sorted */
    printf("sched: %d frames while querying (median %.2f ms to render + encode), query median %.2f ms "
           "(%.2f frames), p90 %.2f ms\n",
           nf, fm, qm, qm / fm, lat[QUERIES * 9 / 10]);
    /* a query waits for the one frame being drawn (about half of one on
       average) plus its own time: 0.1-0.9 frames seen, the high end on a
       loaded machine; behind a FIFO it waited for most of the 6 (5.6-5.8
       seen) */
    assert_true(nf >= 4 * VIEWERS);
    assert_true(qm < 3.0 * fm);
    pthread_mutex_destroy(&r->mu);
    free(r);
    daemon_stop(&d);
}

const struct CMUnitTest sched_tests[] = {
    cmocka_unit_test(test_queries_before_frames),
};
const size_t sched_tests_count = sizeof sched_tests / sizeof sched_tests[0];
