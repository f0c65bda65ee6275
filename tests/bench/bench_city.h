/*
 * bench_city.h — bench_render's demo city frames (issue 20's budget):
 * the daemon's city and day environment built in process, two cameras,
 * the software path's passes, tone map and JPEG timed apart, the GL path
 * on the same frames. bench_city.c.
 */
#ifndef VANTAGE_BENCH_CITY_H
#define VANTAGE_BENCH_CITY_H

#include "culling.h"
#include "vt_gldraw.h"

#include <stdbool.h>
#include <stdint.h>

typedef struct bench_city_opts {
    cull_pool *pool;        /* 2 threads */
    uint32_t width, height;
    int reps;
    bool json;
    vt_gldraw *gl;          /* NULL: no GL path */
    const char *gl_name;
    unsigned lp_threads;
    const char *png_dir;    /* non-NULL: the last frame of each view as city-VIEW.png there (and .jpg) */
    const char *view;       /* non-NULL: that view only (street, aerial) */
    uint32_t max_lights;    /* non-zero: that many of the city's lights, spread evenly over its
                               list (issue 20's budget names 64; the city has 288) */
} bench_city_opts;

/* 0, or -1 with a line on stderr. */
int bench_city(const bench_city_opts *o);

/* The demo city alone, for the other benchmarks (bench_h264.c): the scene
 * bench_city builds (quiet: no line on stdout), and the software frame of
 * a camera from eye to at (60 degrees, as `vantage render`) into rgba and
 * depth (W x H, rows bottom-up, vt_soft's layout) with sr. 0, or -1 with a
 * line on stderr. */
typedef struct city_run bench_city_scene;
struct vt_soft;
int bench_city_open(cull_pool *pool, bool quiet, bench_city_scene **out);
int bench_city_draw(bench_city_scene *c, struct vt_soft *sr, const double eye[3], const double at[3], uint32_t W,
                    uint32_t H, float *rgba, float *depth);
void bench_city_close(bench_city_scene *c);

#endif
