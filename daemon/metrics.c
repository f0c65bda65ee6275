/*
 * metrics.c — see metrics.h: the registry's helpers and the exposition in
 * the Prometheus text format 0.0.4 (one `# HELP` and one `# TYPE` line per
 * family, then its samples; histograms as cumulative `_bucket{le=...}`,
 * `_sum` in seconds and `_count`). Built on the loop thread in a buffer
 * the server keeps between scrapes: about 30 kB and 50-150 us for a daemon
 * that has seen a dozen request types.
 *
 * What is shown: request counters for every request type (zeros
 * included, so the series exist from the start); latency histograms for
 * the types seen at least once; error counters for each (type, code) seen.
 */
#include "server_internal.h"
#include "cluster.h"
#include "vp_grow.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

const uint64_t mh_bound_ns[MH_BOUNDS] = {
    1000,      2000,      5000,      10000,      20000,      50000,      100000,     200000,
    500000,    1000000,   2000000,   5000000,    10000000,   20000000,   50000000,   100000000,
    200000000, 500000000, 1000000000, 2000000000, 5000000000, 10000000000,
};
/* the same bounds in seconds, as `le` label values */
static const char *const mh_le[MH_BOUNDS] = {
    "1e-06", "2e-06", "5e-06", "1e-05", "2e-05", "5e-05", "0.0001", "0.0002", "0.0005", "0.001", "0.002",
    "0.005", "0.01",  "0.02",  "0.05",  "0.1",   "0.2",   "0.5",    "1",      "2",      "5",     "10",
};

/* ---- the registry ----------------------------------------------------------------- */

static const uint16_t mt_wire[] = {
#define METRICS_X_WIRE(t) t,
    METRICS_REQUEST_TYPES(METRICS_X_WIRE)
#undef METRICS_X_WIRE
};

int metrics_type(uint16_t type)
{
    switch (type) {
#define METRICS_X_CASE(t) case t: return MT_##t;
        METRICS_REQUEST_TYPES(METRICS_X_CASE)
#undef METRICS_X_CASE
    }
    return MT_OTHER;
}

static const char *type_label(int mt)
{
    if (mt == MT_OTHER) return "other";
    if (mt == MT_NONE) return "none";
    return vp_type_name(mt_wire[mt]);
}

static unsigned err_slot(int code)
{
    return code <= -1 && code >= -(int)(METRICS_ERR_SLOTS - 1) ? (unsigned)(-code - 1) : METRICS_ERR_SLOTS - 1;
}

static const char *strip_prefix(const char *s)
{
    return strncmp(s, "VP_ERR_", 7) ? s : s + 7;
}

/* The code's name as in PROTOCOL.md's table ("MATRIX"), or "other". */
static const char *err_label(unsigned slot)
{
    if (slot == METRICS_ERR_SLOTS - 1) return "other";
    switch (-(int)slot - 1) {
#define METRICS_X_ERR(name, value, msg) case value: return strip_prefix(#name);
        VP_ERRORS(METRICS_X_ERR)
#undef METRICS_X_ERR
    }
    return "other";
}

void metrics_error(metrics *m, int type, int code)
{
    if (type < 0 || type >= MT_COUNT) type = MT_NONE;
    m->errors[type][err_slot(code)]++;
}

void metrics_query_add(metrics *m, const metrics_query *q)
{
    mhist_add(&m->query, q->total_ns);
    for (int i = 0; i < MS_COUNT; i++) mhist_add(&m->stage[i], q->stage_ns[i]);
    for (int i = 0; i < ME_COUNT; i++) m->entities[i] += q->entities[i];
    for (int i = 0; i < MC_COUNT; i++) m->cells[i] += q->cells[i];
    m->occ_buffers[0] += q->occ_kept;
    m->occ_buffers[1] += q->occ_rendered;
}

/* ---- text ---------------------------------------------------------------------------- */

void mbuf_put(mbuf *b, const char *s, size_t n)
{
    if (b->oom) return;
    if (b->cap - b->len < n) {
        size_t cap = n <= SIZE_MAX - b->len ? vp_grow_cap(b->cap, b->len + n, 16384, 1, SIZE_MAX) : 0;
        char *p = cap ? realloc(b->p, cap) : NULL;
        if (!p) {
            b->oom = true;
            return;
        }
        b->p = p;
        b->cap = cap;
    }
    memcpy(b->p + b->len, s, n);
    b->len += n;
}

void mbuf_free(mbuf *b)
{
    free(b->p);
    *b = (mbuf){0};
}

static void put(mbuf *b, const char *s)
{
    mbuf_put(b, s, strlen(s));
}

static void put_u64(mbuf *b, uint64_t v)
{
    char t[24];
    int n = 0;
    do t[sizeof t - 1 - n++] = (char)('0' + v % 10); while ((v /= 10));
    mbuf_put(b, t + sizeof t - n, (size_t)n);
}

/* Nanoseconds as seconds, exactly ("12.000345678"). */
static void put_seconds(mbuf *b, uint64_t ns)
{
    char t[16];
    put_u64(b, ns / 1000000000u);
    snprintf(t, sizeof t, ".%09u", (unsigned)(ns % 1000000000u));
    put(b, t);
}

/* s with backslash and line feed escaped, and the double quote too in a
 * label value (quote). */
static void put_escaped(mbuf *b, const char *s, bool quote)
{
    const char *special = quote ? "\\\"\n" : "\\\n";
    for (;;) {
        size_t n = strcspn(s, special);
        mbuf_put(b, s, n);
        s += n;
        if (!*s) return;
        put(b, *s == '\\' ? "\\\\" : *s == '"' ? "\\\"" : "\\n");
        s++;
    }
}

/* `# HELP` and `# TYPE`. */
static void family(mbuf *b, const char *name, const char *type, const char *help)
{
    put(b, "# HELP ");
    put(b, name);
    put(b, " ");
    put_escaped(b, help, false);
    put(b, "\n# TYPE ");
    put(b, name);
    put(b, " ");
    put(b, type);
    put(b, "\n");
}

/* name + suffix, up to two labels (a NULL key is left out), a space. */
static void head(mbuf *b, const char *name, const char *suffix, const char *k1, const char *v1, const char *k2,
                 const char *v2)
{
    put(b, name);
    if (suffix) put(b, suffix);
    if (k1 || k2) {
        put(b, "{");
        if (k1) {
            put(b, k1);
            put(b, "=\"");
            put_escaped(b, v1, true);
            put(b, "\"");
        }
        if (k2) {
            if (k1) put(b, ",");
            put(b, k2);
            put(b, "=\"");
            put_escaped(b, v2, true);
            put(b, "\"");
        }
        put(b, "}");
    }
    put(b, " ");
}

static void sample(mbuf *b, const char *name, const char *k, const char *v, uint64_t value)
{
    head(b, name, NULL, k, v, NULL, NULL);
    put_u64(b, value);
    put(b, "\n");
}

static void sample_f(mbuf *b, const char *name, const char *k, const char *v, double value)
{
    char num[40];
    snprintf(num, sizeof num, "%.9g", value);
    head(b, name, NULL, k, v, NULL, NULL);
    put(b, num);
    put(b, "\n");
}

static void sample_seconds(mbuf *b, const char *name, uint64_t ns)
{
    head(b, name, NULL, NULL, NULL, NULL, NULL);
    put_seconds(b, ns);
    put(b, "\n");
}

/* One series of a histogram: cumulative buckets, +Inf, sum, count. */
static void hist(mbuf *b, const char *name, const char *k, const char *v, const mhist *h)
{
    uint64_t cum = 0;
    for (unsigned i = 0; i < MH_BOUNDS; i++) {
        cum += h->n[i];
        head(b, name, "_bucket", k, v, "le", mh_le[i]);
        put_u64(b, cum);
        put(b, "\n");
    }
    cum += h->n[MH_BOUNDS];
    head(b, name, "_bucket", k, v, "le", "+Inf");
    put_u64(b, cum);
    put(b, "\n");
    head(b, name, "_sum", k, v, NULL, NULL);
    put_seconds(b, h->sum_ns);
    put(b, "\n");
    head(b, name, "_count", k, v, NULL, NULL);
    put_u64(b, cum);
    put(b, "\n");
}

static uint64_t hist_count(const mhist *h)
{
    uint64_t n = 0;
    for (unsigned i = 0; i <= MH_BOUNDS; i++) n += h->n[i];
    return n;
}

/* ---- the exposition ------------------------------------------------------------------ */

/* An HTTP endpoint's two families: PREFIX_responses_total by status code
 * and PREFIX_connections open now. */
static void http_families(mbuf *b, const char *prefix, const char *flag, const char *note, const uint64_t *counts,
                          uint32_t conns)
{
    char name[64], help[160];
    snprintf(name, sizeof name, "%s_responses_total", prefix);
    snprintf(help, sizeof help, "Answers of the %s HTTP endpoint, by status code.", flag);
    family(b, name, "counter", help);
    for (int i = 0; i < HS_COUNT; i++) sample(b, name, "code", httpd_codes[i], counts[i]);
    snprintf(name, sizeof name, "%s_connections", prefix);
    snprintf(help, sizeof help, "HTTP connections to the %s endpoint open now (%s).", flag, note);
    family(b, name, "gauge", help);
    sample(b, name, NULL, NULL, conns);
}

bool metrics_expose(server *s, mbuf *b)
{
    metrics *m = &s->m;
    const scene *sc = s->sc;
    b->len = 0;
    b->oom = false;

    family(b, "vantage_build_info", "gauge", "Always 1; the labels say the protocol version the daemon speaks.");
    head(b, "vantage_build_info", NULL, "protocol", "1", NULL, NULL);
    put(b, "1\n");
    family(b, "vantage_start_time_seconds", "gauge", "When the daemon started serving, Unix time.");
    sample_seconds(b, "vantage_start_time_seconds", s->start_unix_ns);
    family(b, "vantage_uptime_seconds", "gauge", "Time since the daemon started serving.");
    sample_seconds(b, "vantage_uptime_seconds", (ae_now_ms() - s->start_ms) * 1000000u);

    /* ---- requests ---- */
    family(b, "vantage_requests_total", "counter",
           "Protocol requests taken, by message type (type=\"other\": a frame whose type is no request, "
           "answered ERROR TYPE).");
    for (int t = 0; t < MT_NONE; t++) sample(b, "vantage_requests_total", "type", type_label(t), m->requests[t]);
    family(b, "vantage_request_errors_total", "counter",
           "ERROR replies sent, by the request's type and the error code (PROTOCOL.md); type=\"none\": errors "
           "that answer no request (a frame over the size limit or with flags set, a timeout). Only pairs seen "
           "are shown.");
    for (int t = 0; t < MT_COUNT; t++)
        for (unsigned e = 0; e < METRICS_ERR_SLOTS; e++)
            if (m->errors[t][e]) {
                head(b, "vantage_request_errors_total", NULL, "type", type_label(t), "code", err_label(e));
                put_u64(b, m->errors[t][e]);
                put(b, "\n");
            }
    family(b, "vantage_request_duration_seconds", "histogram",
           "From the daemon taking a request's whole frame from the connection's input (after that "
           "connection's earlier requests are answered) to its reply queued in the connection's output; "
           "for queries, frames and light lists this includes the wait for a worker. Network time and the "
           "client's own queueing are not in it. Types seen at least once.");
    for (int t = 0; t < MT_NONE; t++)
        if (hist_count(&m->latency[t])) hist(b, "vantage_request_duration_seconds", "type", type_label(t), &m->latency[t]);

    /* ---- queries ---- */
    family(b, "vantage_query_seconds", "histogram",
           "A visibility query on its worker thread: decode, view set-up, culling and writing the reply "
           "(VIS_RESULT's stage_ns total), without the wait for the worker.");
    hist(b, "vantage_query_seconds", NULL, NULL, &m->query);
    family(b, "vantage_query_stage_seconds", "histogram",
           "A visibility query's stages on its worker: decode (decoding and view set-up), cull (regions, cells, "
           "sphere, AABB, screen-area and occlusion tests: one fused pass in the culling core, which times "
           "only the occlusion raster apart), occlusion_raster (drawing the occluders into the depth buffers), "
           "write (encoding the records).");
    {
        static const char *const st[MS_COUNT] = {"decode", "cull", "occlusion_raster", "write"};
        for (int i = 0; i < MS_COUNT; i++) hist(b, "vantage_query_stage_seconds", "stage", st[i], &m->stage[i]);
    }
    family(b, "vantage_query_entities_total", "counter",
           "Entities through the visibility queries' stages, summed over queries: tested (in the cells that "
           "survived), then those still visible in some view after the sphere, aabb, area and occlusion tests, "
           "then visible (reported, after the sub-level filter).");
    {
        static const char *const st[ME_COUNT] = {"tested", "sphere", "aabb", "area", "occlusion", "visible"};
        for (int i = 0; i < ME_COUNT; i++) sample(b, "vantage_query_entities_total", "stage", st[i], m->entities[i]);
    }
    family(b, "vantage_query_cells_total", "counter",
           "Grid cells met by the visibility queries, summed over queries: searched (every cell of the grids a "
           "query searched), culled whole by the frustum (with their region or alone), skipped for holding none "
           "of the query's sub-levels, and (cell, view) pairs hidden whole by occlusion.");
    {
        static const char *const st[MC_COUNT] = {"searched", "frustum_culled", "sublevel_skipped", "occluded"};
        for (int i = 0; i < MC_COUNT; i++) sample(b, "vantage_query_cells_total", "result", st[i], m->cells[i]);
    }
    family(b, "vantage_query_occlusion_buffers_total", "counter",
           "Views' occlusion buffers in the visibility queries: kept (the worker drew the same view of the same "
           "occluders last time: a still camera's re-query) or rendered.");
    {
        static const char *const how[2] = {"kept", "rendered"};
        for (int i = 0; i < 2; i++) sample(b, "vantage_query_occlusion_buffers_total", "how", how[i], m->occ_buffers[i]);
    }

    /* ---- clients ---- */
    uint64_t roles[4] = {0}, buffered = 0, held = 0;
    for (uint32_t i = 0; i < s->nconns; i++) {
        const conn *c = s->live[i];
        roles[!c->hello ? 0 : c->role >= VP_ROLE_VIEWER && c->role <= VP_ROLE_EDITOR ? 1 + c->role : 1]++;
        buffered += c->out_bytes;
        held += c->in_cap + c->out_mem;
    }
    family(b, "vantage_clients", "gauge",
           "Protocol connections now, by role (role=\"handshake\": connected, HELLO not yet accepted).");
    {
        static const char *const rn[4] = {"handshake", "viewer", "commander", "editor"};
        for (int i = 0; i < 4; i++) sample(b, "vantage_clients", "role", rn[i], roles[i]);
    }
    family(b, "vantage_clients_max", "gauge", "Protocol connections the daemon takes (--max-clients).");
    sample(b, "vantage_clients_max", NULL, NULL, s->cfg.max_clients);
    family(b, "vantage_connections_accepted_total", "counter", "Protocol connections accepted.");
    sample(b, "vantage_connections_accepted_total", NULL, NULL, m->accepted);
    family(b, "vantage_connections_rejected_total", "counter",
           "Protocol connections refused at accept: --max-clients reached.");
    sample(b, "vantage_connections_rejected_total", NULL, NULL, m->rejected);
    family(b, "vantage_disconnects_total", "counter",
           "Protocol connections ended, by why: peer (closed by the client, or a socket error), error (closed "
           "by the daemon after an error that ends a connection: a bad HELLO, a refused role, a frame over the "
           "limit), hello_timeout, frame_timeout (slow-loris), output_limit (replies left unread past "
           "--out-limit), sync_failed (--durability always: the journal's sync failed), output_limit_total (the largest "
           "backlog while all clients' output buffers held more than --out-limit-total).");
    {
        static const char *const dn[MD_COUNT] = {NULL,          "peer",         "error",       "hello_timeout",
                                                 "frame_timeout", "output_limit", "sync_failed", "output_limit_total",
                                                 NULL};
        for (int i = 0; i < MD_COUNT; i++)
            if (dn[i]) sample(b, "vantage_disconnects_total", "reason", dn[i], m->disconnects[i]);
    }
    family(b, "vantage_auth_failures_total", "counter", "HELLOs refused the role they asked for (ERROR AUTH).");
    sample(b, "vantage_auth_failures_total", NULL, NULL, m->auth_failures);
    family(b, "vantage_received_bytes_total", "counter", "Bytes read from protocol connections.");
    sample(b, "vantage_received_bytes_total", NULL, NULL, s->bytes_in);
    family(b, "vantage_sent_bytes_total", "counter", "Bytes written to protocol connections.");
    sample(b, "vantage_sent_bytes_total", NULL, NULL, s->bytes_out);
    family(b, "vantage_output_buffered_bytes", "gauge",
           "Reply and frame bytes queued in the daemon for protocol clients, not yet taken by the kernel.");
    sample(b, "vantage_output_buffered_bytes", NULL, NULL, buffered);
    family(b, "vantage_output_reply_bytes_total", "counter",
           "Worker replies (query results, frames) queued to clients, by how: linked (queued by pointer, "
           "no copy: every frame and every reply over 1 KiB) or copied (into the reply queue's tail block).");
    {
        const char *const how[2] = {"linked", "copied"};
        const uint64_t bytes[2] = {m->out_linked, m->out_copied};
        for (int i = 0; i < 2; i++) sample(b, "vantage_output_reply_bytes_total", "how", how[i], bytes[i]);
    }
    family(b, "vantage_output_pending_clients", "gauge",
           "Protocol connections with output still to write (or an event or a held answer to send): the "
           "only ones the loop visits on a turn.");
    sample(b, "vantage_output_pending_clients", NULL, NULL, s->npend);
    family(b, "vantage_client_buffer_bytes", "gauge",
           "Memory held by protocol clients' input buffers and output blocks (what they hold, used or not: an "
           "input buffer a burst grew shrinks back to 64 KiB, and an idle output block is given back, within "
           "half a second of going unused; sent output blocks are given back at once).");
    sample(b, "vantage_client_buffer_bytes", NULL, NULL, held);
    family(b, "vantage_client_output_buffer_bytes", "gauge",
           "Memory held by protocol clients' output blocks together: what --out-limit-total bounds.");
    sample(b, "vantage_client_output_buffer_bytes", NULL, NULL, s->out_held);
    family(b, "vantage_client_output_buffer_limit_bytes", "gauge",
           "--out-limit-total: past it the client with the largest backlog is dropped (0: no limit).");
    sample(b, "vantage_client_output_buffer_limit_bytes", NULL, NULL, s->cfg.out_limit_total);

    /* ---- frames ---- */
    family(b, "vantage_frame_streams", "gauge", "Connections with a frame stream (FRAME_SUBSCRIBE).");
    sample(b, "vantage_frame_streams", NULL, NULL, s->nsubs);
    family(b, "vantage_frames_sent_total", "counter", "Stream frames queued to subscribers.");
    sample(b, "vantage_frames_sent_total", NULL, NULL, m->frames_sent);
    family(b, "vantage_frames_dropped_total", "counter",
           "Stream frames a subscriber did not get because it had not taken its previous frame "
           "(latest-frame-wins): a due frame replaced by a newer scene or view while the viewer was behind, "
           "at most one per 1/max_fps.");
    sample(b, "vantage_frames_dropped_total", NULL, NULL, m->frames_dropped);
    family(b, "vantage_frames_discarded_total", "counter",
           "Stream frames drawn and thrown away: the stream was changed (size, format, renderer) or ended, "
           "or its connection closed, while the frame was drawn; or a full-size frame stopped because its "
           "view moved again (dynamic resolution).");
    sample(b, "vantage_frames_discarded_total", NULL, NULL, m->frames_discarded);
    family(b, "vantage_frames_scaled_total", "counter",
           "Stream frames drawn at a lower resolution while their view moved (dynamic resolution, "
           "VP_RENDER_MOTION and --motion-ms) and scaled up to the stream's size.");
    sample(b, "vantage_frames_scaled_total", NULL, NULL, m->frames_scaled);
    family(b, "vantage_frame_motion_scale", "summary",
           "The scale of each side a moving view's frame was drawn at (dynamic resolution; 1: full size): "
           "_sum / _count is the mean.");
    sample_f(b, "vantage_frame_motion_scale_sum", NULL, NULL, m->motion_scale_sum);
    sample(b, "vantage_frame_motion_scale_count", NULL, NULL, m->motion_frames);
    family(b, "vantage_frame_render_seconds", "histogram",
           "A frame (RENDER or a stream's) on its worker: culling and rendering.");
    hist(b, "vantage_frame_render_seconds", NULL, NULL, &m->frame_render);
    family(b, "vantage_frame_encode_seconds", "histogram",
           "A frame's encoding on its worker (JPEG: tone map and compression; RAW: none).");
    hist(b, "vantage_frame_encode_seconds", NULL, NULL, &m->frame_encode);

    /* ---- the scene ---- */
    cull_world_info info;
    cull_world_info_get(sc->world, &info);
    family(b, "vantage_scene_epoch", "gauge", "The scene epoch: +1 per applied edit message.");
    sample(b, "vantage_scene_epoch", NULL, NULL, sc->epoch);
    if (s->cluster) {
        cluster_stats cs;
        cluster_stats_get(s->cluster, &cs);
        family(b, "vantage_cluster_role", "gauge",
               "This daemon's role in its cluster (vantaged --cluster): 1 for the role it has.");
        for (int r = CLUSTER_REPLICA; r <= CLUSTER_WRITER; r++)
            sample(b, "vantage_cluster_role", "role", cluster_role_name(r), cs.role == r);
        family(b, "vantage_cluster_stream_sequence", "gauge",
               "The scene stream's message sequence: applied (a replica: applied to this scene; the writer: "
               "published), stored (the writer: acknowledged by JetStream), last (the stream's end as last seen).");
        sample(b, "vantage_cluster_stream_sequence", "kind", "applied", cs.applied);
        sample(b, "vantage_cluster_stream_sequence", "kind", "stored", cs.stored);
        sample(b, "vantage_cluster_stream_sequence", "kind", "last", cs.last);
        family(b, "vantage_cluster_lag_messages", "gauge",
               "Stream messages behind: a replica's not yet applied, the writer's published and not yet stored.");
        sample(b, "vantage_cluster_lag_messages", NULL, NULL,
               cs.role == CLUSTER_WRITER ? cs.applied - (cs.stored < cs.applied ? cs.stored : cs.applied)
                                         : cs.last - cs.applied);
        family(b, "vantage_cluster_promotions_total", "counter", "Times this daemon became the writer after it started.");
        sample(b, "vantage_cluster_promotions_total", NULL, NULL, cs.promotions);
        family(b, "vantage_cluster_snapshots_total", "counter",
               "Snapshots of the scene this daemon published to JetStream (as the writer).");
        sample(b, "vantage_cluster_snapshots_total", NULL, NULL, cs.snapshots);
    }
    family(b, "vantage_scene_entities", "gauge", "Entities in the scene, by kind.");
    sample(b, "vantage_scene_entities", "kind", "static", info.static_entities);
    sample(b, "vantage_scene_entities", "kind", "dynamic", info.dynamic_entities);
    family(b, "vantage_scene_cells", "gauge", "Grid cells holding entities.");
    sample(b, "vantage_scene_cells", NULL, NULL, info.cells);
    family(b, "vantage_scene_regions", "gauge", "Grid regions (8x8x8 cells) holding entities.");
    sample(b, "vantage_scene_regions", NULL, NULL, info.regions);
    family(b, "vantage_scene_meshes", "gauge", "Mesh classes with a mesh.");
    sample(b, "vantage_scene_meshes", NULL, NULL, sc->nmeshes);
    family(b, "vantage_scene_occluders", "gauge", "Occluders.");
    sample(b, "vantage_scene_occluders", NULL, NULL, sc->occluders.count);
    family(b, "vantage_scene_lights", "gauge", "Lights.");
    sample(b, "vantage_scene_lights", NULL, NULL, sc->lights.count);
    family(b, "vantage_scene_materials", "gauge", "Materials (MATERIAL_PUT).");
    sample(b, "vantage_scene_materials", NULL, NULL, sc->materials.count);
    family(b, "vantage_scene_sublevels", "gauge", "Named sub-levels.");
    sample(b, "vantage_scene_sublevels", NULL, NULL, sc->nsublevels);
    family(b, "vantage_scene_textures", "gauge", "Textures (TEXTURE_PUT).");
    sample(b, "vantage_scene_textures", NULL, NULL, sc->textures.count);
    family(b, "vantage_scene_texture_bytes", "gauge",
           "Bytes the textures hold (uploads as sent, decoded pixels, mip chains), under --max-texture-mem.");
    sample(b, "vantage_scene_texture_bytes", NULL, NULL, sc->texture_mem);
    family(b, "vantage_texture_upload_bytes", "gauge",
           "Texture uploads under way on the connections (their total sizes), also under --max-texture-mem.");
    sample(b, "vantage_texture_upload_bytes", NULL, NULL, s->upload_bytes);
    {
        static const char *const sky[3] = {"color", "analytic", "texture"};
        family(b, "vantage_env_sky", "gauge", "The environment's sky mode: 1 for the current one.");
        for (uint8_t i = 0; i < 3; i++) sample(b, "vantage_env_sky", "mode", sky[i], sc->env.sky_mode == i);
        family(b, "vantage_env_exposure_auto", "gauge", "1: auto exposure, 0: fixed EV.");
        sample(b, "vantage_env_exposure_auto", NULL, NULL, sc->env.exposure_mode == VP_EXPOSURE_AUTO);
        family(b, "vantage_env_ground", "gauge", "1: the ground plane is on.");
        sample(b, "vantage_env_ground", NULL, NULL, (sc->env.flags & VP_ENV_GROUND) != 0);
        family(b, "vantage_env_sun_lux", "gauge", "The sun's illuminance (lux, rounded; 0 with no sun).");
        bool sun = sc->env.sun_dir[0] || sc->env.sun_dir[1] || sc->env.sun_dir[2];
        sample(b, "vantage_env_sun_lux", NULL, NULL, sun ? (uint64_t)(sc->env.sun_lux + 0.5f) : 0);
    }
    family(b, "vantage_scene_edit_records_total", "counter", "Entity records applied by edits, ever.");
    sample(b, "vantage_scene_edit_records_total", NULL, NULL, sc->edits);

    /* ---- workers, the endpoint ---- */
    family(b, "vantage_worker_threads", "gauge", "Query worker threads (--threads).");
    sample(b, "vantage_worker_threads", NULL, NULL, s->nworkers);
    family(b, "vantage_worker_jobs", "gauge",
           "Jobs (queries, frames, light lists) handed to the workers and not yet back: waiting or running.");
    sample(b, "vantage_worker_jobs", NULL, NULL, m->jobs_submitted - m->jobs_done);
    http_families(b, "vantage_metrics_http", "--metrics", "this scrape's included", m->http, httpd_conns(s->http));
    if (s->web) {
        http_families(b, "vantage_web_http", "--web", "upgraded WebSockets are clients", m->web_http,
                      httpd_conns(s->web));
        family(b, "vantage_web_ws_text_refused_total", "counter",
               "WebSocket text messages refused with a close 1003 (ones that are not UTF-8 wslay closes with 1007, uncounted).");
        sample(b, "vantage_web_ws_text_refused_total", NULL, NULL, m->ws_bad);
    }
    return !b->oom;
}
