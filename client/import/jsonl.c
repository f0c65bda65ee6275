/*
 * jsonl.c — entities as JSON lines (see jsonl.h): json-c parses a line,
 * snprintf writes one. cli_jsonl.c does the reading, writing and talking
 * to the daemon around these.
 */
#include "jsonl.h"

#include <json-c/json.h>
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

size_t cli_json_escape(char *dst, const char *src, size_t n)
{
    char *o = dst;
    for (size_t i = 0; i < n; i++) {
        unsigned char ch = (unsigned char)src[i];
        if (ch == '"' || ch == '\\') {
            *o++ = '\\';
            *o++ = (char)ch;
        } else if (ch < 32 || ch == 127) {
            o += sprintf(o, "\\u%04x", ch);
        } else {
            *o++ = (char)ch;
        }
    }
    *o = 0;
    return (size_t)(o - dst);
}

int jsonl_entity_format(char *buf, size_t cap, const vp_entity *e, bool handle, const char *sublevel_json)
{
    char hd[32] = "", num[8];
    if (handle) snprintf(hd, sizeof hd, "\"handle\": %u, ", e->handle);
    snprintf(num, sizeof num, "%u", e->sublevel);
    const char *q = sublevel_json ? "\"" : "";
    /* the scene model's fields when set: a material, a transform (its
       sphere and aabb are then the derived bounds, not read back) */
    char mat[32] = "", trs[320] = "";
    if (e->material) snprintf(mat, sizeof mat, ", \"material\": %u", e->material);
    if (e->flags & VP_ENT_TRANSFORM)
        snprintf(trs, sizeof trs, ", \"pos\": [%.17g, %.17g, %.17g], \"rot\": [%.9g, %.9g, %.9g, %.9g], "
                                  "\"scale\": [%.9g, %.9g, %.9g]",
                 e->pos[0], e->pos[1], e->pos[2], (double)e->rot[0], (double)e->rot[1], (double)e->rot[2],
                 (double)e->rot[3], (double)e->scale[0], (double)e->scale[1], (double)e->scale[2]);
    return snprintf(buf, cap,
                    "{\"id\": %llu, %s\"class\": %u, \"sphere\": [%.17g, %.17g, %.17g, %.17g], "
                    "\"aabb\": [%.17g, %.17g, %.17g, %.17g, %.17g, %.17g], \"sublevel\": %s%s%s, \"dynamic\": %s%s%s}\n",
                    (unsigned long long)e->id, hd, e->class_id, e->sphere[0], e->sphere[1], e->sphere[2],
                    e->sphere[3], e->aabb[0], e->aabb[1], e->aabb[2], e->aabb[3], e->aabb[4], e->aabb[5], q,
                    sublevel_json ? sublevel_json : num, q, (e->flags & VP_ENT_DYNAMIC) ? "true" : "false", mat, trs);
}

static bool json_num_array(json_object *a, double *out, size_t n)
{
    if (!a || !json_object_is_type(a, json_type_array) || json_object_array_length(a) != n) return false;
    for (size_t i = 0; i < n; i++) {
        json_object *x = json_object_array_get_idx(a, i);
        if (!x || !(json_object_is_type(x, json_type_double) || json_object_is_type(x, json_type_int)))
            return false;
        out[i] = json_object_get_double(x);
        if (!isfinite(out[i])) return false;
    }
    return true;
}

bool jsonl_entity_parse(const char *line, size_t len, vp_entity *e, char sub[VP_MAX_NAME + 1], char *err,
                        size_t errlen)
{
    memset(e, 0, sizeof *e);
    sub[0] = 0;
    /* json-c would stop at a NUL and take what is before it */
    const char *nul = memchr(line, 0, len);
    if (nul) {
        snprintf(err, errlen, "not JSON: a NUL byte at column %zu", (size_t)(nul - line) + 1);
        return false;
    }
    if (len > INT_MAX) {
        snprintf(err, errlen, "not JSON: the line is longer than 2 GiB");
        return false;
    }
    json_tokener *tok = json_tokener_new();
    if (!tok) {
        snprintf(err, errlen, "out of memory");
        return false;
    }
    json_object *o = json_tokener_parse_ex(tok, line, (int)len);
    enum json_tokener_error je = json_tokener_get_error(tok);
    size_t end = json_tokener_get_parse_end(tok);
    json_tokener_free(tok);
    if (!o || je != json_tokener_success) {
        snprintf(err, errlen, "not JSON: %s", json_tokener_error_desc(je));
        if (o) json_object_put(o);
        return false;
    }
    bool ok = false;
    json_object *v;
    if (!json_object_is_type(o, json_type_object)) {
        snprintf(err, errlen, "not a JSON object");
        goto out;
    }
    /* json-c stops after the first value: a second object on the line
       would be dropped without a word */
    for (size_t i = end; i < len; i++)
        if (line[i] != ' ' && line[i] != '\t' && line[i] != '\r' && line[i] != '\n') {
            snprintf(err, errlen, "text after the JSON object (column %zu)", i + 1);
            goto out;
        }
    if (!json_object_object_get_ex(o, "id", &v) || !json_object_is_type(v, json_type_int)) {
        snprintf(err, errlen, "\"id\" must be an integer");
        goto out;
    }
    /* json-c's uint64 read of a negative number is 0 */
    if (json_object_get_int64(v) < 0) {
        snprintf(err, errlen, "\"id\" must not be negative");
        goto out;
    }
    e->id = json_object_get_uint64(v);
    if (json_object_object_get_ex(o, "class", &v)) {
        int64_t cl = json_object_get_int64(v);
        if (!json_object_is_type(v, json_type_int) || cl < 0 || cl > 65535) {
            snprintf(err, errlen, "\"class\" must be 0..65535");
            goto out;
        }
        e->class_id = (uint16_t)cl;
    }
    if (json_object_object_get_ex(o, "sublevel", &v)) {
        if (json_object_is_type(v, json_type_string)) {
            const char *nm = json_object_get_string(v);
            /* the length json-c holds: a \u0000 in the name is a control
               character, not its end */
            size_t l = (size_t)json_object_get_string_len(v);
            bool clean = l >= 1 && l <= VP_MAX_NAME;
            for (size_t i = 0; clean && i < l; i++) clean = (unsigned char)nm[i] >= 32 && nm[i] != 127;
            if (!clean) {
                snprintf(err, errlen, "\"sublevel\" names are 1..255 bytes without control characters");
                goto out;
            }
            memcpy(sub, nm, l);
            sub[l] = 0; /* resolved to an id before sending */
        } else {
            int64_t sl = json_object_get_int64(v);
            if (!json_object_is_type(v, json_type_int) || sl < 0 || sl > 65535) {
                snprintf(err, errlen, "\"sublevel\" must be a name or 0..65535");
                goto out;
            }
            e->sublevel = (uint16_t)sl;
        }
    }
    if (json_object_object_get_ex(o, "dynamic", &v)) {
        if (!json_object_is_type(v, json_type_boolean)) {
            snprintf(err, errlen, "\"dynamic\" must be true or false");
            goto out;
        }
        if (json_object_get_boolean(v)) e->flags |= VP_ENT_DYNAMIC;
    }
    if (json_object_object_get_ex(o, "material", &v)) {
        int64_t m = json_object_get_int64(v);
        if (!json_object_is_type(v, json_type_int) || m < 0 || m > UINT32_MAX) {
            snprintf(err, errlen, "\"material\" must be 0..4294967295");
            goto out;
        }
        e->material = (uint32_t)m;
    }
    /* a transform: "pos" (and "rot", "scale": identity, 1 if left out) */
    double t[4] = {0, 0, 0, 1};
    static const char *const tname[3] = {"pos", "rot", "scale"};
    static const char *const twhat[3] = {"[x, y, z]", "[x, y, z, w] (a unit quaternion)", "[x, y, z]"};
    bool has_trs = false;
    for (int k = 0; k < 3; k++) {
        if (!json_object_object_get_ex(o, tname[k], &v)) continue;
        bool fits = json_num_array(v, t, k == 1 ? 4 : 3);
        for (int a = 0; fits && k && a < (k == 1 ? 4 : 3); a++) fits = isfinite((float)t[a]); /* f32 on the wire */
        if (!fits) {
            snprintf(err, errlen, "\"%s\" must be %s of finite numbers%s", tname[k], twhat[k],
                     k ? " within a float's range" : "");
            goto out;
        }
        has_trs = true;
        for (int a = 0; a < (k == 1 ? 4 : 3); a++) {
            if (k == 0) e->pos[a] = t[a];
            else if (k == 1) e->rot[a] = (float)t[a];
            else e->scale[a] = (float)t[a];
        }
    }
    if (has_trs) {
        if (!json_object_object_get_ex(o, "rot", &v)) e->rot[3] = 1;
        if (!json_object_object_get_ex(o, "scale", &v)) e->scale[0] = e->scale[1] = e->scale[2] = 1;
        e->flags |= VP_ENT_TRANSFORM;
        memset(e->sphere, 0, sizeof e->sphere); /* derived by the daemon */
        memset(e->aabb, 0, sizeof e->aabb);
        ok = true;
        goto out;
    }
    bool has_sphere = json_object_object_get_ex(o, "sphere", &v);
    if (has_sphere && !json_num_array(v, e->sphere, 4)) {
        snprintf(err, errlen, "\"sphere\" must be [x, y, z, r] of finite numbers");
        goto out;
    }
    bool has_aabb = json_object_object_get_ex(o, "aabb", &v);
    if (has_aabb && !json_num_array(v, e->aabb, 6)) {
        snprintf(err, errlen, "\"aabb\" must be [minx, miny, minz, maxx, maxy, maxz] of finite numbers");
        goto out;
    }
    if (!has_sphere && !has_aabb) {
        snprintf(err, errlen, "needs \"sphere\" or \"aabb\"");
        goto out;
    }
    ok = true;
out:
    json_object_put(o);
    if (!ok) {
        memset(e, 0, sizeof *e);
        sub[0] = 0;
    }
    return ok;
}
