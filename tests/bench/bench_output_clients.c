/*
 * bench_output_clients.c — the clients of tests/bench/bench_output.sh
 * (issue 25, the output path), built by that script against libvantage.a:
 *
 *   stream SOCK W H V SECS   V viewers on RAW W x H frame streams while an
 *                            editor moves an entity every millisecond;
 *                            prints "frames seconds"
 *   idle SOCK N SECS         N clients connected (HELLO done) doing nothing;
 *                            prints "ready" once they all are
 */
#include "vantage.h"

#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

static const char *sock;
static unsigned W, H;
static atomic_bool stop;
static atomic_ulong frames;

static vtc_client *connect_as(int role)
{
    vtc_client *c;
    char err[256];
    if (vtc_connect(&(vtc_connect_opts){.unix_path = sock, .role = role}, &c, err, sizeof err)) {
        fprintf(stderr, "connect: %s\n", err);
        exit(1);
    }
    return c;
}

static void *viewer(void *arg)
{
    (void)arg;
    vtc_client *c = connect_as(VP_ROLE_VIEWER);
    vp_frame_sub sub = {.r = {.format = VP_FRAME_RAW}, .max_fps = VP_FRAME_SUB_MAX_FPS};
    vtc_view_perspective(&sub.r.view, (double[]){150, 200, 150}, (double[]){0, 0, 0}, NULL, 60, (uint16_t)W,
                         (uint16_t)H, 0.1, 10000);
    if (vtc_frame_subscribe(c, &sub)) {
        fprintf(stderr, "subscribe: %s\n", vtc_last_error(c)->msg);
        exit(1);
    }
    vp_frame f;
    while (!stop)
        if (vtc_wait_frame(c, &f, 200) == VP_OK) frames++;
    vtc_close(c);
    return NULL;
}

static double since(const struct timespec *a)
{
    struct timespec b;
    clock_gettime(CLOCK_MONOTONIC, &b);
    return (double)(b.tv_sec - a->tv_sec) + (double)(b.tv_nsec - a->tv_nsec) / 1e9;
}

int main(int argc, char **argv)
{
    if (argc == 5 && !strcmp(argv[1], "idle")) {
        sock = argv[2];
        for (int i = 0, n = atoi(argv[3]); i < n; i++) connect_as(VP_ROLE_VIEWER);
        printf("ready\n");
        fflush(stdout);
        sleep((unsigned)atoi(argv[4]));
        return 0;
    }
    if (argc != 7 || strcmp(argv[1], "stream")) {
        fprintf(stderr, "usage: %s stream SOCK W H VIEWERS SECS | idle SOCK N SECS\n", argv[0]);
        return 2;
    }
    sock = argv[2];
    W = (unsigned)atoi(argv[3]);
    H = (unsigned)atoi(argv[4]);
    int nv = atoi(argv[5]);
    double secs = atof(argv[6]);
    if (nv < 1 || nv > 64) return 2;
    vtc_client *ed = connect_as(VP_ROLE_EDITOR);
    vp_entity e = {.id = 0xBE7C00000001ull, .class_id = 7, .aabb = {0, 0, 0, 4, 4, 4}};
    vtc_add(ed, &e, 1, NULL, NULL);
    pthread_t t[64];
    for (int i = 0; i < nv; i++) pthread_create(&t[i], NULL, viewer, NULL);
    usleep(300000); /* subscribed: count from here */
    frames = 0;
    struct timespec t0;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    double el;
    int k = 0;
    do { /* the scene changes every millisecond: every stream always has a new frame due */
        e.aabb[1] = 0.01 * (k++ % 100);
        e.aabb[4] = e.aabb[1] + 4;
        vtc_update(ed, &e, 1, NULL);
        usleep(1000);
    } while ((el = since(&t0)) < secs);
    unsigned long n = frames;
    stop = true;
    for (int i = 0; i < nv; i++) pthread_join(t[i], NULL);
    printf("%lu %.3f\n", n, el);
    vtc_close(ed);
    return 0;
}
