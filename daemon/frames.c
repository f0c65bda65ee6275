/*
 * frames.c — vantaged's pictures: RENDER (one frame) and FRAME_SUBSCRIBE
 * (a stream of them), drawn on the query workers by the software renderer
 * (one per worker) or by the daemon's one OpenGL context (shared, taken in
 * turn under gl_mu; opened at start with --render gl, else on the first
 * request that names it).
 *
 * Streams are latest-frame-wins without a queue: a subscriber's next frame
 * is rendered only when its previous one has left the connection's output
 * and the kernel's (SIOCOUTQ: on TCP, what the peer has not acknowledged;
 * on a Unix socket, what it has not read), the scene or its view has changed
 * since, and its rate cap allows; the frame then shows the scene as it is
 * at that moment. A slow viewer thus gets fewer frames and costs no render
 * time while it is stalled; the others do not wait for it. (A stalled TCP
 * peer's own receive buffer still holds the few frames sent before it
 * filled; nothing here can reach into it.)
 */
#include "server_internal.h"
#include "errmap.h"
#include "frame_marks.h"
#include "frame_scene.h"
#include "vt_gldraw.h"
#include "vt_image.h"
#include "vt_shadow.h"
#include "video.h"
#include "vt_soft.h"
#include "web.h"

#include <linux/sockios.h>
#include <math.h>
#include <stdio.h>
#include <sys/ioctl.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* A class's colour: a hash to a pleasant, not too dark, linear albedo. */
static void class_albedo(uint16_t cls, float out[3])
{
    uint32_t hsh = (uint32_t)cls * 2654435761u;
    for (int a = 0; a < 3; a++) out[a] = 0.25f + 0.55f * (float)((hsh >> (8 * a)) & 255) / 255.0f;
}

const char *renderer_name(int r)
{
    return r == VP_RENDERER_GL ? "gl" : "soft";
}

/* ---- the shared OpenGL renderer ------------------------------------------------- */

/* Opens the context and the renderer on this thread and leaves them current
 * nowhere. Caller holds gl_mu. */
static int gl_open_locked(server *s)
{
    if (s->gldraw) return 0;
    if (s->gl_failed) return -1;
    char err[300];
    if (vt_gl_open(&s->gl, NULL, err, sizeof err) || vt_gldraw_create(s->gl, &s->gldraw, err, sizeof err)) {
        vt_gl_close(s->gl);
        s->gl = NULL;
        s->gl_failed = true;
        snprintf(s->gl_err, sizeof s->gl_err, "no OpenGL renderer here: %s", err);
        if (s->cfg.renderer != VP_RENDERER_GL) LOGW("%s", s->gl_err); /* else frames_init says it */
        return -1;
    }
    LOGI("OpenGL renderer: %s (%s)", vt_gl_get_info(s->gl)->renderer, vt_gl_get_info(s->gl)->version);
    vt_gl_release(s->gl);
    return 0;
}

int frames_init(server *s)
{
    pthread_mutex_init(&s->gl_mu, NULL);
    mark_store_init(&s->marks);
    if (s->cfg.renderer != VP_RENDERER_GL) return 0;
    pthread_mutex_lock(&s->gl_mu);
    int rc = gl_open_locked(s);
    pthread_mutex_unlock(&s->gl_mu);
    if (rc) LOGE("--render gl: %s", s->gl_err);
    else LOGI("frames are drawn with OpenGL unless a request names the software renderer");
    return rc;
}

void frames_fini(server *s)
{
    if (s->gl) {
        char err[64];
        if (!vt_gl_make_current(s->gl, err, sizeof err)) vt_gldraw_destroy(s->gldraw);
        vt_gl_close(s->gl);
    }
    s->gl = NULL;
    s->gldraw = NULL;
    pthread_mutex_destroy(&s->gl_mu);
    mark_store_fini(&s->marks);
}

/* ---- one frame, on a worker -------------------------------------------------------- */

/* What a frame draws: the visible entities as instances of their class
 * meshes (the unit box for a class without one), and the scene's lights. */
typedef struct frame_in {
    vt_instance *inst;
    vt_mesh *meshes;
    uint32_t ninst, nmesh;
    vt_instance *casters;   /* what may cast the sun's shadows into the view (NULL: inst) */
    uint32_t ncasters;
    vt_light *lights;
    uint64_t *light_ids;
    uint32_t nl;
    frame_scene fs;         /* materials, textures, the environment */
    vt_adapt *adapt;        /* a stream's eye adaptation, NULL: a single picture */
    float dt;
    frame_overlay ov;       /* outline and icons (frame_marks.h) */
    const uint64_t *subs;   /* the sub-levels shown (scene_visible, in the worker's vis; NULL: all) */
    uint32_t fx_off;        /* VT_FX_* off: --fx-off and the request's VP_RENDER_NO_* */
} frame_in;

static void frame_in_free(frame_in *fi)
{
    free(fi->inst);
    free(fi->casters);
    free(fi->meshes);
    free(fi->lights);
    free(fi->light_ids);
    frame_scene_free(&fi->fs);
}

/* The picture fi draws from v into rgba and depth (the view's size). */
static vt_frame frame_of(const cull_view *v, const frame_in *fi, float *rgba, float *depth)
{
    return (vt_frame){.view = v, .width = v->viewport_w, .height = v->viewport_h, .meshes = fi->meshes,
                      .nmesh = fi->nmesh, .inst = fi->inst, .ninst = fi->ninst, .lights = fi->lights, .nl = fi->nl,
                      .env = fi->fs.env_ok ? &fi->fs.env : NULL, .rgba = rgba, .depth = depth,
                      .stride = v->viewport_w, .adapt = fi->adapt, .dt = fi->dt, .casters = fi->casters,
                      .ncasters = fi->ncasters, .overlay = frame_overlay_get(&fi->ov), .fx_off = fi->fx_off};
}

/* An entity's transform as the renderers take it (vt_frame_check's
 * limits; the daemon's own are the culling core's: an entity past them is
 * drawn by its bounds instead). */
static bool trs_drawable(const scene_xform *x)
{
    double q2 = 0;
    for (int a = 0; a < 4; a++) q2 += (double)x->rot[a] * x->rot[a];
    for (int a = 0; a < 3; a++)
        if (!(fabs(x->pos[a]) <= 1e15) || !(fabsf(x->scale[a]) <= 1e6f)) return false;
    return fabs(q2 - 1) <= 1e-3;
}

static int gather_lights(const scene *sc, const uint64_t *subs, frame_in *fi);

/* Entity r as the renderers take it (its class's mesh numbered into fi
 * as met: the worker's class -> mesh index + 1 table, mcls the way back). */
static void entity_instance(const scene *sc, worker *wk, const cull_result *r, uint16_t *mcls, frame_in *fi,
                            vt_instance *out)
{
    uint32_t *mesh_of = wk->mesh_of;
    cull_entity_desc e;
    cull_entity_get(sc->world, r->handle, &e);
    uint16_t cls = r->class_id;
    const scene_mesh *sm = &sc->meshes[cls];
    uint32_t mi = 0;
    if (sm->pos && sm->ni) {
        if (!mesh_of[cls]) {
            fi->meshes[fi->nmesh] = (vt_mesh){.pos = sm->pos, .nrm = sm->nrm, .idx = sm->idx, .nv = sm->nv,
                                              .ni = sm->ni, .uv = sm->uv, .tan = sm->tan};
            mcls[fi->nmesh] = cls;
            mesh_of[cls] = ++fi->nmesh;
        }
        mi = mesh_of[cls] - 1;
    }
    *out = (vt_instance){.mesh = mi};
    memcpy(out->bmin, e.aabb_min, sizeof e.aabb_min);
    memcpy(out->bmax, e.aabb_max, sizeof e.aabb_max);
    class_albedo(cls, out->albedo);
    /* the scene model: an entity with a transform is its mesh under
       it (others stretch the mesh onto their box), with its material */
    uint32_t slot = r->handle & (CULL_MAX_ENTITIES - 1);
    const scene_xform *x = sc->xf && slot < sc->id_cap ? &sc->xf[slot] : NULL;
    if (x) {
        out->mat = frame_scene_material(&fi->fs, sc, x->material);
        if ((x->flags & VP_ENT_TRANSFORM) && trs_drawable(x)) {
            out->place = VT_PLACE_TRS;
            memcpy(out->pos, x->pos, sizeof x->pos);
            memcpy(out->rot, x->rot, sizeof x->rot);
            memcpy(out->scale, x->scale, sizeof x->scale);
        }
    }
    /* damaged: drawn with its destruction mask (the volume is read
       under the shared scene lock the frame is rendered in) */
    if (sc->destruct.count) {
        const scene_destruct *sd = scene_destruct_of(sc, scene_id_of(sc, r->handle));
        out->dvol = sd ? &sd->v : NULL;
    }
}

/* The sun's shadow casters of a frame whose visible instances fi holds:
 * a building outside the view can shadow the ground inside it. The
 * renderers' own cascade fit (vt_shadow_fit_make) gives the volume; one
 * orthographic query along the sun over it, extended VT_SHADOW_MAX_DIST
 * towards the sun, frustum only (what hides a caster from the camera does
 * not stop its shadow). No environment or no sun: none (the instances
 * stand in). 0, or -1 out of memory. */
static int gather_casters(const scene *sc, worker *wk, const cull_view *v, const uint64_t *subs, uint16_t **mcls,
                          frame_in *fi)
{
    if (!fi->fs.env_ok) return 0;
    vt_frame f = frame_of(v, fi, NULL, NULL);
    vt_shadow_fit fit;
    cull_view cv;
    bool ok = vt_shadow_fit_frame(&f, &fit) && vt_shadow_caster_view(&fit, v->origin, VT_SHADOW_MAX_DIST, &cv);
    if (!ok) return 0;
    size_t n = 0;
    cull_query_desc q = {.views = &cv, .view_count = 1, .flags = CULL_Q_NO_OCCLUSION, .sublevels = subs};
    if (cull_query(sc->world, wk->ctx, &q, wk->res, wk->res_cap, &n, NULL) != CULL_OK) return 0;
    size_t cap = (size_t)fi->nmesh + n + 1;
    vt_mesh *nm = realloc(fi->meshes, cap * sizeof *nm);
    if (!nm) return -1;
    fi->meshes = nm;
    uint16_t *nc = realloc(*mcls, cap * sizeof *nc);
    if (!nc) return -1;
    *mcls = nc;
    if (!(fi->casters = malloc((n + 1) * sizeof *fi->casters))) return -1;
    for (size_t i = 0; i < n; i++) entity_instance(sc, wk, &wk->res[i], *mcls, fi, &fi->casters[i]);
    fi->ncasters = (uint32_t)n;
    return 0;
}

/* Culls (with occlusion unless no_occlusion) and collects the frame's
 * instances and lights. VP_OK, or an error code with msg. */
static int gather(const scene *sc, worker *wk, const cull_view *v, bool no_occlusion, frame_in *fi, char *msg,
                  size_t msglen)
{
    memset(fi, 0, sizeof *fi);
    size_t n = 0;
    uint16_t *mcls = NULL; /* per mesh of the frame: its class (mesh_of is emptied by it) */
    if (!worker_res_reserve(wk, cull_query_bound(sc->world))) goto nomem;
    if (!wk->mesh_of && !(wk->mesh_of = calloc(65536, sizeof *wk->mesh_of))) goto nomem;
    const uint64_t *subs = fi->subs = scene_visible(sc, NULL, wk->vis);
    cull_query_desc q = {.views = v, .view_count = 1, .flags = no_occlusion ? CULL_Q_NO_OCCLUSION : 0,
                         .sublevels = subs};
    int rc = cull_query(sc->world, wk->ctx, &q, wk->res, wk->res_cap, &n, NULL);
    if (rc) {
        snprintf(msg, msglen, "%s", cull_strerror(rc));
        return vp_code_from_cull(rc);
    }
    /* meshes numbered as they are met: the worker's class -> mesh index + 1
       table, emptied again below */
    uint32_t *mesh_of = wk->mesh_of;
    fi->inst = malloc((n + 1) * sizeof *fi->inst);
    fi->meshes = malloc((n + 1) * sizeof *fi->meshes);
    mcls = malloc((n + 1) * sizeof *mcls);
    if (!fi->inst || !fi->meshes || !mcls) goto nomem;
    fi->meshes[0] = vt_mesh_box;
    fi->nmesh = 1;
    if (!frame_scene_init(&fi->fs, sc)) goto nomem;
    for (size_t i = 0; i < n; i++) entity_instance(sc, wk, &wk->res[i], mcls, fi, &fi->inst[i]);
    fi->ninst = (uint32_t)n;
    if (gather_casters(sc, wk, v, subs, &mcls, fi)) goto nomem;
    for (uint32_t m = 1; m < fi->nmesh; m++) mesh_of[mcls[m]] = 0;
    free(mcls);
    mcls = NULL;
    if (gather_lights(sc, subs, fi)) goto nomem;
    return VP_OK;
nomem:
    if (wk->mesh_of && mcls)
        for (uint32_t m = 1; m < fi->nmesh; m++) wk->mesh_of[mcls[m]] = 0;
    free(mcls);
    frame_in_free(fi);
    memset(fi, 0, sizeof *fi);
    snprintf(msg, msglen, "out of memory for a frame");
    return VP_ERR_BUSY;
}

/* The lights of the sub-levels subs (NULL: all), as the renderers take
 * them, and their ids. */
static int gather_lights(const scene *sc, const uint64_t *subs, frame_in *fi)
{
    fi->lights = malloc((sc->lights.count + 1) * sizeof *fi->lights);
    fi->light_ids = malloc((sc->lights.count + 1) * sizeof *fi->light_ids);
    if (!fi->lights || !fi->light_ids) return -1;
    for (size_t i = 0; i < sc->lights.cap; i++) {
        if (!sc->lights.used[i]) continue;
        const scene_light *sl = (const scene_light *)(uintptr_t)sc->lights.vals[i];
        if (!cull_sublevel_in(subs, sl->sublevel)) continue;
        const vp_light *l = &sl->l;
        /* LIGHT_PUT refused what the renderers refuse; a light replayed
           from an older journal (or snapshot) may still fail: skipped, so
           one bad light never breaks every frame */
        if (!scene_light_drawable(l)) continue;
        fi->light_ids[fi->nl] = l->id;
        vt_light *o = &fi->lights[fi->nl++];
        memset(o, 0, sizeof *o);
        double rad[3];
        scene_light_cull(l, &o->l, rad);
        o->cos_inner = l->inner_cos;
        for (int a = 0; a < 3; a++) o->color[a] = (float)rad[a];
    }
    return 0;
}

/* The worker's software renderer, on first use: it uses every core (one
 * frame's latency is what a viewer feels; two frames at once share them). */
static vt_soft *worker_soft(worker *wk)
{
    if (!wk->soft) {
        long ncpu = sysconf(_SC_NPROCESSORS_ONLN);
        if (ncpu > 1 && cull_pool_create((uint32_t)(ncpu < 64 ? ncpu : 64), &wk->pool)) wk->pool = NULL;
        if (vt_soft_create(wk->pool, 0, &wk->soft)) wk->soft = NULL;
    }
    return wk->soft;
}

/* The tone map and the JPEG encode in bands of rows over the worker's pool
 * (vt_jpeg_encode_par, vt_tonemap_frame), two bands a thread taken in turn
 * so a band of sky (fast) and one of street (slow) do not leave a core
 * waiting: a JPEG band tone-maps the rows it then encodes, on its own
 * thread, while they are in that core's cache. The tone map is per pixel,
 * so the bands' bytes are those of one call; the spliced JPEG decodes to
 * the pixels of one encode. A 1280x720 city frame: tone map 1.3 ms on 2
 * threads + encode 2.7 ms on one before. */
static void pool_run(void *pool, vt_jpeg_job_fn fn, void *arg, uint32_t n)
{
    cull_pool_run(pool, fn, arg, n);
}

/* soft_draw's answer for a picture stopped through cancel (VP codes are <= 0) */
#define FRAME_STOPPED 1

/* The software renderer's picture of fi from v into rgba and depth (the
 * view's size), on this worker: the one soft-draw path RENDER and
 * LIGHT_QUERY share. cancel: vt_frame.cancel (NULL: never). VP_OK,
 * FRAME_STOPPED, or a code with msg. */
static int soft_draw(worker *wk, const cull_view *v, const frame_in *fi, float *rgba, float *depth, const int *cancel,
                     char *msg, size_t msglen)
{
    char err[256];
    vt_frame f = frame_of(v, fi, rgba, depth);
    f.cancel = cancel;
    int rc = vt_soft_draw(wk->soft, &f, NULL, err, sizeof err);
    if (!rc) return VP_OK;
    if (rc == VT_ERR_CANCELLED) return FRAME_STOPPED;
    snprintf(msg, msglen, "render: %s", err);
    return vp_code_from_vt(rc);
}

/* A picture job's end, RENDER's or LIGHT_QUERY's: its reply as drawn, or
 * the ERROR for code (out of memory when code is VP_ERR_BUSY and msg is
 * empty: what names what could not be had), or nothing for a stream's
 * frame stopped through its cancel (FRAME_STOPPED). */
static void job_finish(job *j, int code, char *msg, size_t msglen, const char *what)
{
    if (code == VP_OK) {
        j->ok = true;
        return;
    }
    if (code == FRAME_STOPPED) { /* a stream's frame no longer wanted: no reply (frames_done) */
        j->cancelled = true;
        return;
    }
    if (code == VP_ERR_BUSY && !*msg) snprintf(msg, msglen, "out of memory for %s", what);
    job_error(j, code, UINT32_MAX, msg);
}

/* What RENDER and FRAME_SUBSCRIBE refuse before drawing anything: the
 * view (view_from: cull_view_init, the validation every request carrying
 * a view and both renderers share) and a RAW frame larger than the output
 * limit. FRAME_SUBSCRIBE runs it before its ACK, so a stream that is
 * acknowledged never ends for its view. VP_OK and *v, or a code and msg. */
static int render_check(const server *s, const vp_render *m, cull_view *v, char *msg, size_t msglen)
{
    int code = view_from(&m->view, UINT32_MAX, v, msg, msglen);
    if (code) return code;
    size_t np = (size_t)v->viewport_w * v->viewport_h;
    size_t bytes = vp_size_frame((uint32_t)(np * 20));
    if (m->format == VP_FRAME_RAW && bytes > s->cfg.out_limit) {
        /* the reply alone would get the client dropped */
        snprintf(msg, msglen, "a raw %ux%u frame is %zu bytes, over this daemon's output limit of %u (--out-limit)",
                 v->viewport_w, v->viewport_h, bytes, s->cfg.out_limit);
        return VP_ERR_LIMIT;
    }
    if (m->format == VP_FRAME_RAW && s->cfg.out_limit_total && bytes > s->cfg.out_limit_total / 2) {
        /* queued, it would leave the daemon-wide limit no room for a second one */
        snprintf(msg, msglen,
                 "a raw %ux%u frame is %zu bytes, over half this daemon's output limit for all clients, %llu "
                 "(--out-limit-total)",
                 v->viewport_w, v->viewport_h, bytes, (unsigned long long)s->cfg.out_limit_total);
        return VP_ERR_LIMIT;
    }
    return VP_OK;
}

/* Dynamic resolution (VP_RENDER_MOTION): the smallest and the first scale
 * of a moving stream's sides, and how far one frame's measure may move it */
#define MOTION_MIN_SCALE 0.25f
#define MOTION_FIRST_SCALE 0.5f
#define MOTION_STEP 1.3f
/* a stream drawn smaller while it moved gets its full-size frame once the
   view has rested this long (no re-aim) */
#define MOTION_SETTLE_NS 100000000ull

/* m's view (W x H, checked) drawn at scale of each side (at least 16
 * pixels): *dv, or false when that is not smaller. */
static bool scaled_view(const vp_render *m, uint32_t W, uint32_t H, float scale, cull_view *dv)
{
    vp_view sv = m->view;
    uint32_t w = (uint32_t)lrintf((float)W * scale), h = (uint32_t)lrintf((float)H * scale);
    if (w < 16) w = 16;
    if (h < 16) h = 16;
    if (w >= W || h >= H) return false;
    sv.viewport_w = (uint16_t)w;
    sv.viewport_h = (uint16_t)h;
    char msg[64];
    return view_from(&sv, UINT32_MAX, dv, msg, sizeof msg) == VP_OK;
}

/* Fills j->reply with FRAME or ERROR for the render request m. The caller
 * holds scene_lock shared. */
static void render_frame(server *s, worker *wk, job *j, const vp_render *m)
{
    const scene *sc = s->sc;
    uint64_t t0 = now_ns();
    char msg[300] = "";
    int code;
    frame_in fi = {0};
    float *rgba = NULL, *depth = NULL;
    uint8_t *jpeg = NULL, *rgb8 = NULL, *raw = NULL; /* raw: the reply, drawn into in place */
    uint8_t *small8 = NULL;                         /* a frame drawn smaller, tone-mapped */
    size_t jpeg_len = 0;
    int renderer = m->renderer ? m->renderer : s->cfg.renderer;
    j->epoch = sc->epoch;
    cull_view v;
    if ((code = render_check(s, m, &v, msg, sizeof msg))) goto done;
    const uint32_t W = v.viewport_w, H = v.viewport_h; /* the frame's size */
    /* dynamic resolution: a moving stream's frame drawn smaller (dv) and
       scaled up to W x H after its tone map; RAW frames never */
    cull_view dv = v;
    if (j->scale > 0 && m->format != VP_FRAME_RAW && !scaled_view(m, W, H, j->scale, &dv)) dv = v;
    const bool scaled = dv.viewport_w != W || dv.viewport_h != H;
    const uint32_t RW = dv.viewport_w, RH = dv.viewport_h; /* the size drawn */
    j->scaled = scaled;
    size_t np = (size_t)RW * RH;
    if (renderer == VP_RENDERER_SOFT && !worker_soft(wk)) goto nomem;
    if ((code = gather(sc, wk, &dv, (m->flags & VP_RENDER_NO_OCCLUSION) != 0, &fi, msg, sizeof msg))) goto done;
    /* VP_RENDER_NO_SHADOWS .. NO_FXAA are VT_FX_SHADOWS .. FXAA one bit up */
    _Static_assert(VP_RENDER_NO_SHADOWS >> 1 == VT_FX_SHADOWS && VP_RENDER_NO_SSAO >> 1 == VT_FX_SSAO &&
                       VP_RENDER_NO_IBL >> 1 == VT_FX_IBL && VP_RENDER_NO_FXAA >> 1 == VT_FX_FXAA,
                   "effect bits");
    fi.fx_off = s->cfg.fx_off | (uint32_t)((m->flags & VP_RENDER_FX) >> 1);
    vt_adapt ad = {.ev = j->adapt_ev, .valid = j->adapt_valid}; /* a stream's eye, out again below */
    fi.adapt = j->stream ? &ad : NULL;
    fi.dt = j->adapt_dt;
    frame_overlay_make(&fi.ov, sc, fi.subs, wk->res, fi.ninst, m, &s->marks, now_ns());
    if (m->format == VP_FRAME_RAW) {
        /* drawn straight into the reply: RGBA then depth after the header */
        if (!(raw = malloc(vp_size_frame((uint32_t)(np * 20))))) goto nomem;
        rgba = (float *)(void *)(raw + VP_HEADER_SIZE + VP_FRAME_HEADER);
        depth = rgba + np * 4;
    } else {
        rgba = malloc(np * 4 * sizeof *rgba);
        depth = malloc(np * sizeof *depth);
        if (!rgba || !depth) goto nomem;
    }
    char err[256];
    int rc;
    if (renderer == VP_RENDERER_GL) {
        vt_frame gf = frame_of(&dv, &fi, rgba, depth);
        pthread_mutex_lock(&s->gl_mu);
        if (gl_open_locked(s)) {
            code = VP_ERR_UNSUPPORTED;
            snprintf(msg, sizeof msg, "%.250s", s->gl_err);
        } else if ((rc = vt_gl_make_current(s->gl, err, sizeof err)) ||
                   (rc = vt_gldraw_draw(s->gldraw, &gf, NULL, err, sizeof err))) {
            code = vp_code_from_vt(rc);
            snprintf(msg, sizeof msg, "render (gl): %s", err);
        }
        vt_gl_release(s->gl);
        pthread_mutex_unlock(&s->gl_mu);
        if (code) goto done;
    } else if ((code = soft_draw(wk, &dv, &fi, rgba, depth, &j->cancel, msg, sizeof msg))) {
        goto done; /* (FRAME_STOPPED too) */
    }
    if (__atomic_load_n(&j->cancel, __ATOMIC_RELAXED)) { /* not worth its encode either */
        code = FRAME_STOPPED;
        goto done;
    }
    j->adapt_ev = ad.ev;
    j->adapt_valid = ad.valid;
    uint64_t t1 = now_ns();
    vp_frame f = {.epoch = sc->epoch, .width = (uint16_t)W, .height = (uint16_t)H, .format = m->format,
                  .view_seq = j->stream ? j->view_seq : 0, .visible = fi.ninst, .render_ns = (uint32_t)(t1 - t0)};
    /* from here on only this frame's own pixels are read: an edit need not
       wait for the tone map and the JPEG (the worker loop knows not to
       unlock again) */
    pthread_rwlock_unlock(&s->scene_lock);
    wk->scene_released = true;
    /* JPEG and H.264: tone-mapped into rgb8 (bottom row first, as rendered,
       to top row first), in bands over the worker's pool */
    vt_tonemap_desc td = {.exposure_ev = m->exposure_ev, .op = VT_TONEMAP_ACES, .lut = s->cfg.lut};
    uint32_t bands = wk->pool ? 2 * cull_pool_threads(wk->pool) : 1;
    if (m->format != VP_FRAME_RAW && !(rgb8 = malloc(vt_image_rgba8_size(W, H)))) goto nomem;
    if (scaled) {
        /* tone-mapped at the size drawn, then scaled up into rgb8 */
        if (!(small8 = malloc(vt_image_rgba8_size(RW, RH)))) goto nomem;
        if ((rc = vt_tonemap_frame(RW, RH, rgba, RW, &td, small8, bands, wk->pool ? pool_run : NULL, wk->pool)) ||
            (rc = vt_image_resize_rgba8(RW, RH, small8, 4 * (size_t)RW, W, H, rgb8, 4 * (size_t)W, bands,
                                        wk->pool ? pool_run : NULL, wk->pool))) {
            code = vp_code_from_vt(rc);
            snprintf(msg, sizeof msg, "%s", rc == VT_ERR_NOMEM ? "" : "scaling a frame up failed");
            goto done;
        }
    }
    if (m->format == VP_FRAME_H264) {
        /* then the stream's encoder (video.h): a RENDER's is its own, freed with the job */
        const uint8_t *au;
        size_t au_len;
        bool key = false;
        uint32_t vthreads = j->video_threads ? j->video_threads : 1, most = wk->pool ? cull_pool_threads(wk->pool) : 1;
        if (vthreads > most) vthreads = most;
        if ((!scaled && (rc = vt_tonemap_frame(W, H, rgba, W, &td, rgb8, bands, wk->pool ? pool_run : NULL, wk->pool))) ||
            (rc = video_encode(&j->venc, W, H, m, j->stream ? j->fps : 30, j->vkey || !j->stream, vthreads, rgb8,
                               &au, &au_len, &key, err, sizeof err))) {
            code = vp_code_from_vt(rc);
            snprintf(msg, sizeof msg, "h264: %s", err);
            goto done;
        }
        f.data = au;
        f.data_len = (uint32_t)au_len;
        f.key = key;
    } else if (m->format == VP_FRAME_JPEG) {
        /* each band tone-maps the rows it then encodes (vt_jpeg_encode_frame);
           a frame drawn smaller is in rgb8 already */
        vt_jpeg_par par = {.bands = bands, .run = wk->pool ? pool_run : NULL, .run_ctx = wk->pool};
        if (scaled ? (rc = vt_jpeg_encode_par(W, H, rgb8, 4 * (size_t)W, 4, m->quality, &par, &jpeg, &jpeg_len, err,
                                              sizeof err))
                   : (rc = vt_jpeg_encode_frame(W, H, rgba, W, &td, rgb8, m->quality, bands,
                                                wk->pool ? pool_run : NULL, wk->pool, &jpeg, &jpeg_len, err,
                                                sizeof err))) {
            code = vp_code_from_vt(rc);
            snprintf(msg, sizeof msg, "jpeg: %s", err);
            goto done;
        }
        f.data = jpeg;
        f.data_len = (uint32_t)jpeg_len;
    } else {
        f.data = NULL; /* RGBA then depth, as floats (little-endian), already in place */
        f.data_len = (uint32_t)(np * 20);
    }
    f.encode_ns = (uint32_t)(now_ns() - t1);
    j->has_frame = true; /* metrics, recorded on the loop */
    j->render_ns = f.render_ns;
    j->encode_ns = f.encode_ns;
    j->reply_len = vp_size_frame(f.data_len);
    if (raw) {
        j->reply = raw;
        raw = NULL;
    } else if (!(j->reply = malloc(j->reply_len)))
        goto nomem;
    vp_writer fw;
    vp_writer_init(&fw, j->reply, j->reply_len);
    vp_enc_frame(&fw, j->h.req, &f);
    code = VP_OK;
    goto done;
nomem:
    code = VP_ERR_BUSY; /* out of memory: job_finish names what */
done:
    job_finish(j, code, msg, sizeof msg, "a frame");
    frame_in_free(&fi);
    if (m->format != VP_FRAME_RAW) {
        free(rgba);
        free(depth);
    }
    free(rgb8);
    free(small8);
    free(jpeg);
    free(raw);
}

void run_render(server *s, worker *wk, job *j)
{
    if (j->stream) {
        render_frame(s, wk, j, &j->stream_req);
        return;
    }
    vp_render m;
    int rc = vp_dec_render(j->payload, j->h.len, &m);
    if (!rc) {
        render_frame(s, wk, j, &m);
        return;
    }
    job_error(j, rc, UINT32_MAX, vp_strerror(rc));
}

/* LIGHT_QUERY: the tile lists of the software renderer's frame (depth
 * ranges from what is visible), or of the frustum alone. */
void run_light_query(server *s, worker *wk, job *j)
{
    const scene *sc = s->sc;
    uint64_t t0 = now_ns();
    char msg[300] = "";
    int code;
    vp_light_query m;
    frame_in fi = {0};
    float *rgba = NULL, *depth = NULL;
    cull_light_tiles own = {0};
    const cull_light_tiles *lt = &own;
    cull_light *cl = NULL;
    if ((code = vp_dec_light_query(j->payload, j->h.len, &m))) {
        snprintf(msg, sizeof msg, "%s", vp_strerror(code));
        goto done;
    }
    cull_view v;
    if ((code = view_from(&m.view, UINT32_MAX, &v, msg, sizeof msg))) goto done;
    uint32_t W = v.viewport_w, H = v.viewport_h;
    int rc;
    if (m.flags & VP_LQ_NO_DEPTH) {
        /* the frustum alone: the lights, nothing culled or drawn */
        if (gather_lights(sc, scene_visible(sc, NULL, wk->vis), &fi)) goto nomem;
        cl = malloc(((size_t)fi.nl + 1) * sizeof *cl);
        if (!cl) goto nomem;
        for (uint32_t i = 0; i < fi.nl; i++) cl[i] = fi.lights[i].l;
        if ((rc = cull_lights_bin(&v, W, H, cl, fi.nl, NULL, &own))) {
            code = vp_code_from_cull(rc);
            snprintf(msg, sizeof msg, "lights: %s", cull_strerror(rc));
            goto done;
        }
    } else {
        if (!worker_soft(wk)) goto nomem;
        if ((code = gather(sc, wk, &v, false, &fi, msg, sizeof msg))) goto done;
        rgba = malloc((size_t)W * H * 4 * sizeof *rgba);
        depth = malloc((size_t)W * H * sizeof *depth);
        if (!rgba || !depth) goto nomem;
        if ((code = soft_draw(wk, &v, &fi, rgba, depth, NULL, msg, sizeof msg))) goto done;
        lt = vt_soft_light_tiles(wk->soft);
    }
    uint32_t tiles = lt->tiles_x * lt->tiles_y, count = lt->offset ? lt->offset[tiles] : 0;
    j->reply_len = vp_size_light_tiles(tiles, count);
    j->reply = malloc(j->reply_len);
    if (!j->reply) goto nomem;
    vp_writer w;
    vp_writer_init(&w, j->reply, j->reply_len);
    vp_enc_light_tiles_begin(&w, j->h.req,
                             &(vp_light_tiles){.epoch = sc->epoch, .tiles_x = (uint16_t)lt->tiles_x,
                                               .tiles_y = (uint16_t)lt->tiles_y, .tile = CULL_LIGHT_TILE,
                                               .flags = m.flags, .in_view = lt->in_view,
                                               .max_per_tile = lt->max_per_tile, .count = count,
                                               .ns = (uint32_t)(now_ns() - t0)});
    for (uint32_t t = 0; t <= tiles; t++) vp_put_u32(&w, lt->offset ? lt->offset[t] : 0);
    for (uint32_t k = 0; k < count; k++) vp_put_u64(&w, fi.light_ids[lt->index[k]]);
    vp_frame_end(&w);
    code = VP_OK;
    goto done;
nomem:
    code = VP_ERR_BUSY; /* out of memory: job_finish names what */
done:
    job_finish(j, code, msg, sizeof msg, "light tiles");
    frame_in_free(&fi);
    free(rgba);
    free(depth);
    free(cl);
    cull_light_tiles_free(&own);
}

/* ---- subscriptions, on the loop ------------------------------------------------- */

void on_frame_subscribe(server *s, conn *c, const vp_header *h, const uint8_t *p)
{
    vp_frame_sub m;
    int rc = vp_dec_frame_sub(p, h->len, &m);
    if (rc) {
        send_error(s, c, h->req, rc, UINT32_MAX, vp_strerror(rc));
        return;
    }
    /* refused up front, as RENDER refuses it; a stream already running
       keeps its last good view */
    cull_view v;
    char msg[300];
    if ((rc = render_check(s, &m.r, &v, msg, sizeof msg))) {
        send_error(s, c, h->req, rc, UINT32_MAX, msg);
        return;
    }
    frame_sub *f = &c->fsub;
    bool was_video = f->active && f->m.r.format == VP_FRAME_H264, video = m.r.format == VP_FRAME_H264;
    if (video && !was_video && s->nvideo >= s->cfg.max_video) {
        snprintf(msg, sizeof msg,
                 "%u H.264 streams are open, the most this daemon serves at once (--max-video): ask for JPEG frames",
                 s->nvideo);
        send_error(s, c, h->req, VP_ERR_LIMIT, UINT32_MAX, msg);
        return;
    }
    s->nvideo += (uint32_t)video - (uint32_t)was_video;
    /* a new view of the same stream (a camera that moves: size, format,
       quality and renderer unchanged) keeps the frame being drawn, which
       carries its own view_seq, and the new view's frame starts as soon
       as it is out; anything else drops it. Dropping on every move would
       starve a camera that moves faster than frames are drawn. */
    bool same = f->active && f->m.r.format == m.r.format && f->m.r.quality == m.r.quality &&
                f->m.r.renderer == m.r.renderer && f->m.r.view.viewport_w == m.r.view.viewport_w &&
                f->m.r.view.viewport_h == m.r.view.viewport_h;
    /* the rate cap holds across re-aims: the next frame starts 1/max_fps
       (the new rate) after the last one started, however often the view
       moves (a client re-aiming every few ms had every aim drawn at once,
       so max_fps bound only cameras that held still) */
    if (f->active && f->next_ns) f->next_ns = f->next_ns - 1000000000ull / f->m.max_fps + 1000000000ull / m.max_fps;
    else f->next_ns = 0; /* a new stream: its first frame at once */
    /* dynamic resolution: a re-aim of the same stream is a camera moving;
       its frame may be drawn smaller, and a full-size frame of the view it
       left, still being drawn, is not wanted any more */
    f->moving = same && (m.r.flags & VP_RENDER_MOTION) && s->cfg.motion_ms;
    f->aim_ns = now_ns();
    if (f->moving && f->inflight && f->job && f->job->refine) __atomic_store_n(&f->job->cancel, 1, __ATOMIC_RELAXED);
    if (!same || !(m.r.flags & VP_RENDER_MOTION)) f->refine = false;
    if (!same) f->mscale = MOTION_FIRST_SCALE;
    if (!f->active) s->nsubs++;
    f->active = true;
    f->aims++;
    f->req = h->req;
    f->m = m;
    if (!same) f->gen++; /* a frame still being drawn for the old stream is dropped */
    if (!same || !was_video) f->vkey = true; /* a new chain (or a new viewer of it) starts with a key frame */
    f->dirty = true;     /* the new view's frame as soon as the cap allows */
    reply_ack(c, h->req, s->sc->epoch, 0);
    LOGD("client %u: frames %ux%u %s, %s, at most %u/s", c->id, m.r.view.viewport_w, m.r.view.viewport_h,
         m.r.format == VP_FRAME_JPEG ? "jpeg" : m.r.format == VP_FRAME_H264 ? "h264" : "raw", renderer_name(m.r.renderer ? m.r.renderer : s->cfg.renderer),
         m.max_fps);
}

static void sub_end(server *s, conn *c)
{
    if (c->fsub.active) s->nsubs--;
    if (c->fsub.active && c->fsub.m.r.format == VP_FRAME_H264) s->nvideo--;
    video_enc_free(c->fsub.venc); /* (one with a worker comes back to frames_done, and is freed there) */
    c->fsub.venc = NULL;
    c->fsub.active = false;
    c->fsub.gen++;
    c->fsub.held_ns = 0;
    c->fsub.adapt_valid = false; /* a new stream's first frame is exposed directly */
    c->fsub.aim_ns = 0;
    c->fsub.moving = c->fsub.refine = false;
}

void on_frame_unsubscribe(server *s, conn *c, const vp_header *h, const uint8_t *p)
{
    int rc = vp_dec_empty(p, h->len);
    if (rc) {
        send_error(s, c, h->req, rc, UINT32_MAX, vp_strerror(rc));
        return;
    }
    sub_end(s, c);
    reply_ack(c, h->req, s->sc->epoch, 0);
}

void frames_conn_gone(server *s, conn *c)
{
    sub_end(s, c);
}

/* A due frame held back because the viewer has not taken its last one
 * (latest-frame-wins). When a newer scene or view replaces it, at least a
 * frame period (1/max_fps) after it was first held, the held frame counts
 * as dropped (metrics): the frames a viewer that kept up would have had. */
static void frame_held(server *s, frame_sub *f, uint64_t now)
{
    uint64_t epoch = s->sc->epoch, period = 1000000000ull / f->m.max_fps;
    if (f->held_ns && (epoch == f->held_epoch && f->aims == f->held_aims)) return;
    if (f->held_ns && now - f->held_ns < period) return;
    if (f->held_ns) s->m.frames_dropped++;
    f->held_ns = now;
    f->held_epoch = epoch;
    f->held_aims = f->aims;
}

int frames_schedule(server *s)
{
    if (!s->nsubs) return -1;
    uint64_t now = now_ns(), wake = mark_store_expire(&s->marks, now); /* ns; a mark's end redraws */
    for (uint32_t i = 0; i < s->nconns; i++) {
        conn *c = s->live[i];
        frame_sub *f = &c->fsub;
        if (!f->active || f->inflight || c->closing) continue;
        const bool refining = !f->dirty && f->shown_epoch == s->sc->epoch && f->shown_marks == s->marks.gen;
        if (refining) {
            if (!f->refine) continue; /* nothing new to show */
            /* the last frame was drawn smaller while the view moved: the
               full-size one once it has rested */
            if (now - f->aim_ns < MOTION_SETTLE_NS) {
                if (f->aim_ns + MOTION_SETTLE_NS < wake) wake = f->aim_ns + MOTION_SETTLE_NS;
                continue;
            }
        }
        if (c->out_bytes || (c->ws && !web_ws_idle(c))) { /* the last frame is still leaving: it wins */
            frame_held(s, f, now);
            continue;
        }
        if (now < f->drain_next_ns) { /* backing off (below) */
            frame_held(s, f, now);
            if (f->drain_next_ns < wake) wake = f->drain_next_ns;
            continue;
        }
        int outq = 0;
        uint32_t slack = f->last_bytes / 4 > 4096 ? f->last_bytes / 4 : 4096;
        if (ioctl(c->fd, SIOCOUTQ, &outq) == 0 && (uint32_t)outq > slack) {
            /* still in the kernel, unacknowledged or unread: look again
               (no event says when it drains) after 2 ms, doubling up to
               100 ms while it does not, so a viewer that stopped reading
               does not keep an idle loop awake */
            f->drain_wait_ns = f->drain_wait_ns ? f->drain_wait_ns * 2 : 2000000;
            if (f->drain_wait_ns > 100000000) f->drain_wait_ns = 100000000;
            f->drain_next_ns = now + f->drain_wait_ns;
            if (f->drain_next_ns < wake) wake = f->drain_next_ns;
            frame_held(s, f, now);
            continue;
        }
        f->drain_wait_ns = 0;
        if (now < f->next_ns) {
            if (f->next_ns < wake) wake = f->next_ns;
            continue;
        }
        job *j = calloc(1, sizeof *j);
        if (!j) return 1; /* try again on the next pass */
        *j = (job){.fd = c->fd, .conn_id = c->id, .h = {.type = VP_RENDER, .req = f->req}, .stream = true,
                   .gen = f->gen, .view_seq = f->m.view_seq, .stream_req = f->m.r, .start_ns = now,
                   .adapt_ev = f->adapt_ev, .adapt_valid = f->adapt_valid,
                   .adapt_dt = f->adapt_valid ? (float)((double)(now - f->adapt_ns) * 1e-9) : 0,
                   .venc = f->venc, .vkey = f->vkey, .fps = f->m.max_fps,
                   /* a moving view's frame at the stream's scale (the worker draws
                      full size when that is not smaller); x264's threads: two
                      for a stream alone */
                   .scale = f->dirty && f->moving ? f->mscale : 0, .video_threads = s->nvideo <= 1 ? 2 : 1,
                   .refine = refining};
        f->venc = NULL; /* the worker's until the job is back */
        f->vkey = false;
        f->inflight = true;
        f->job = j;
        f->dirty = false;
        f->shown_marks = s->marks.gen;
        f->held_ns = 0;
        /* the cap: frame starts 1/max_fps apart (a late start does not
           bank time for a burst) */
        uint64_t period = 1000000000ull / f->m.max_fps;
        f->next_ns = (f->next_ns && now - f->next_ns < period ? f->next_ns : now) + period;
        job_submit(s, j);
    }
    /* the loop's timer is in whole ms: round up, never 0 (a busy loop) */
    if (wake == UINT64_MAX) return -1;
    uint64_t ms = (wake - now + 999999) / 1000000;
    return ms < 1 ? 1 : ms > INT32_MAX ? INT32_MAX : (int)ms;
}

/* The encoder a stream's job brings back: the stream's again while it is
 * H.264, with a key frame next unless this frame goes out (sent: true). */
static void video_back(frame_sub *f, job *j, bool sent)
{
    if (!j->venc) return;
    if (f->active && f->m.r.format == VP_FRAME_H264 && !f->venc) {
        f->venc = j->venc;
        if (!sent) f->vkey = true;
    } else {
        video_enc_free(j->venc);
    }
    j->venc = NULL;
}

void frames_job_free(job *j)
{
    video_enc_free(j->venc);
    j->venc = NULL;
}

/* A moving view's frame (j->scale > 0) is out: the next one's scale from
 * its render time against the budget (--motion-ms). Render time is about
 * a fixed part plus one in proportion to the pixels, so the sides go by
 * the square root of budget / time, at most MOTION_STEP either way a
 * frame; a full-size frame is due when the view rests if this one was
 * smaller. */
static void motion_measured(server *s, frame_sub *f, const job *j)
{
    const float drawn = j->scale; /* (the worker drew full size if this rounds to it) */
    float ms = (float)j->render_ns * 1e-6f, k = ms > 0 ? sqrtf((float)s->cfg.motion_ms / ms) : MOTION_STEP;
    if (k > MOTION_STEP) k = MOTION_STEP;
    if (k < 1 / MOTION_STEP) k = 1 / MOTION_STEP;
    float next = drawn * k;
    f->mscale = next < MOTION_MIN_SCALE ? MOTION_MIN_SCALE : next > 1 ? 1 : next;
    if (j->scaled) {
        f->refine = true;
        s->m.frames_scaled++;
    } else {
        f->refine = false;
    }
    s->m.motion_frames++;
    s->m.motion_scale_sum += j->scaled ? drawn : 1;
}

/* A stream's frame is back: sent if the subscription still wants it. */
void frames_done(server *s, conn *c, job *j)
{
    frame_sub *f = &c->fsub;
    f->inflight = false;
    f->job = NULL;
    if (!f->active || f->gen != j->gen) { /* unsubscribed or re-aimed meanwhile */
        if (j->ok) s->m.frames_discarded++;
        video_back(f, j, false);
        return;
    }
    if (j->cancelled) { /* a full-size frame the view moved away from: nothing encoded, nothing sent */
        s->m.frames_discarded++;
        video_back(f, j, true);
        return;
    }
    video_back(f, j, j->ok);
    uint32_t bytes = (uint32_t)j->reply_len;
    if (!j->reply || !out_take_reply(c, j)) { /* linked into the queue, not copied */
        c->closing = true;
        return;
    }
    if (j->ok) {
        if (j->scale > 0) motion_measured(s, f, j);
        else f->refine = false; /* a full-size frame */
        f->adapt_ev = j->adapt_ev; /* the eye saw this frame */
        f->adapt_valid = j->adapt_valid;
        f->adapt_ns = j->start_ns;
        f->last_bytes = bytes;
        f->shown_epoch = j->epoch;
        f->frames++;
        s->m.frames_sent++;
    } else {
        sub_end(s, c); /* the ERROR (with the subscription's req) ends it */
        s->errors++;
        metrics_error(&s->m, MT_VP_FRAME_SUBSCRIBE, j->code);
    }
}
