/*
 * cli_env.c — `vantage texture put ID FILE [--srgb]`, `texture rm ID...`
 * and `vantage env [changes]`: images uploaded as textures (format from
 * the file's first bytes, chunked by libvantage), and the environment
 * read, changed field by field and written back whole (ENV_GET, then
 * ENV_SET of the result; another editor's change in between is lost,
 * as with any read-modify-write).
 *
 * Sun directions are azimuth / elevation in degrees: azimuth from +Z
 * towards +X (Y is up), elevation above the horizon; the direction stored
 * points towards the sun.
 */
#include "cli.h"

#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int cmd_texture(cli *k, int argc, char **argv)
{
    static const char *use = "texture put ID FILE [--srgb] | texture rm ID [ID...]";
    int rc;
    uint64_t id, epoch = 0;
    if (argc >= 4 && !strcmp(argv[1], "put")) {
        bool srgb = argc == 5 && !strcmp(argv[4], "--srgb");
        if (argc > 5 || (argc == 5 && !srgb)) return die_usage("%s", use);
        if (!parse_u64(argv[2], &id) || !id || id > UINT32_MAX)
            return die_usage("texture put: bad id %s: expected 1..4294967295", argv[2]);
        if ((rc = connect_cli(k, VP_ROLE_EDITOR))) return rc;
        if ((rc = vtc_texture_put_file(k->c, (uint32_t)id, -1, srgb ? VP_TEX_SRGB : 0, argv[3], &epoch)))
            return server_fail(k, "texture put", rc);
        printf("texture %llu from %s%s, epoch %llu\n", (unsigned long long)id, argv[3], srgb ? " (sRGB)" : "",
               (unsigned long long)epoch);
        return 0;
    }
    if (argc >= 3 && !strcmp(argv[1], "rm")) {
        uint64_t *ids = calloc((size_t)argc, sizeof *ids);
        if (!ids) return die_usage("texture rm: out of memory");
        for (int i = 2; i < argc; i++)
            if (!parse_u64(argv[i], &ids[i - 2]) || !ids[i - 2] || ids[i - 2] > UINT32_MAX) {
                free(ids);
                return die_usage("texture rm: bad id %s: expected 1..4294967295", argv[i]);
            }
        rc = connect_cli(k, VP_ROLE_EDITOR);
        if (!rc && (rc = vtc_texture_remove(k->c, ids, (uint32_t)(argc - 2), &epoch)))
            rc = server_fail(k, "texture rm", rc);
        else if (!rc)
            printf("removed %d texture%s, epoch %llu\n", argc - 2, argc > 3 ? "s" : "", (unsigned long long)epoch);
        free(ids);
        return rc;
    }
    return die_usage("%s", use);
}

/* ---- env ------------------------------------------------------------------------------- */

static void sun_from(vp_env *e, double az_deg, double el_deg)
{
    double az = az_deg * M_PI / 180, el = el_deg * M_PI / 180;
    e->sun_dir[0] = (float)(cos(el) * sin(az));
    e->sun_dir[1] = (float)sin(el);
    e->sun_dir[2] = (float)(cos(el) * cos(az));
}

/* The night preset: no sun, a dark blue sky, exposure for a lit street. */
static void night(vp_env *e)
{
    e->sun_dir[0] = e->sun_dir[1] = e->sun_dir[2] = 0;
    e->sun_lux = 0;
    e->sky_mode = VP_SKY_COLOR;
    e->sky_texture = 0;
    e->sky_color[0] = 0.010f, e->sky_color[1] = 0.015f, e->sky_color[2] = 0.035f;
    e->sky_intensity = 1;
    e->fog_density = 0.001f;
    e->fog_color[0] = 0.02f, e->fog_color[1] = 0.025f, e->fog_color[2] = 0.04f;
    e->exposure_mode = VP_EXPOSURE_AUTO;
    e->exposure_comp = 0;
}

static void print_env(const vp_env *e)
{
    static const char *const sky[3] = {"color", "analytic", "exr"};
    const float *d = e->sun_dir;
    if (d[0] || d[1] || d[2]) {
        double el = asin(d[1] > 1 ? 1 : d[1] < -1 ? -1 : d[1]) * 180 / M_PI, az = atan2(d[0], d[2]) * 180 / M_PI;
        printf("sun:      azimuth %.1f, elevation %.1f degrees, %g lux, colour %g,%g,%g\n", az < 0 ? az + 360 : az,
               el, (double)e->sun_lux, (double)e->sun_color[0], (double)e->sun_color[1], (double)e->sun_color[2]);
    } else {
        printf("sun:      off\n");
    }
    printf("sky:      %s", e->sky_mode < 3 ? sky[e->sky_mode] : "?");
    if (e->sky_mode == VP_SKY_COLOR)
        printf(":%g,%g,%g", (double)e->sky_color[0], (double)e->sky_color[1], (double)e->sky_color[2]);
    if (e->sky_mode == VP_SKY_ANALYTIC) printf(", turbidity %g", (double)e->turbidity);
    if (e->sky_mode == VP_SKY_TEXTURE) printf(":%u, rotation %g degrees", e->sky_texture, e->sky_rotation * 180 / M_PI);
    printf(", intensity %g\n", (double)e->sky_intensity);
    if (e->flags & VP_ENV_GROUND) {
        printf("ground:   height %g m, colour %g,%g,%g", e->ground_height, (double)e->ground_color[0],
               (double)e->ground_color[1], (double)e->ground_color[2]);
        if (e->ground_material) printf(", material %u", e->ground_material);
        printf("\n");
    } else {
        printf("ground:   off\n");
    }
    printf("fog:      density %g per metre, colour %g,%g,%g, height falloff %g\n", (double)e->fog_density,
           (double)e->fog_color[0], (double)e->fog_color[1], (double)e->fog_color[2], (double)e->fog_height_falloff);
    if (e->exposure_mode == VP_EXPOSURE_AUTO) printf("exposure: auto, compensation %+g EV\n", (double)e->exposure_comp);
    else printf("exposure: fixed, EV100 %g\n", (double)e->exposure_ev);
}

/* R,G,B into f[3]. */
static bool parse_rgb(const char *s, float *f)
{
    double v[3];
    if (!parse_vec(s, v, 3)) return false;
    for (int i = 0; i < 3; i++) f[i] = (float)v[i];
    return true;
}

/* One option's change to e; false: its value is refused. */
static bool env_option(vp_env *e, int o, const char *a)
{
    double v[4];
    uint64_t id;
    switch (o) {
    case 'd': vp_env_default(e); return true;
    case 'n': night(e); return true;
    case 's':
        if (!strcmp(a, "off")) {
            e->sun_dir[0] = e->sun_dir[1] = e->sun_dir[2] = 0;
            return true;
        }
        if (parse_vec(a, v, 3)) e->sun_lux = (float)v[2];
        else if (!parse_vec(a, v, 2)) return false;
        sun_from(e, v[0], v[1]);
        return true;
    case 'c': return parse_rgb(a, e->sun_color);
    case 'k':
        e->sky_texture = 0;
        if (!strcmp(a, "analytic")) e->sky_mode = VP_SKY_ANALYTIC;
        else if (!strncmp(a, "color:", 6) && parse_rgb(a + 6, e->sky_color)) e->sky_mode = VP_SKY_COLOR;
        else if (!strncmp(a, "exr:", 4) && parse_u64(a + 4, &id) && id && id <= UINT32_MAX) {
            e->sky_mode = VP_SKY_TEXTURE;
            e->sky_texture = (uint32_t)id;
        } else return false;
        return true;
    case 'i': return parse_vec(a, v, 1) && (e->sky_intensity = (float)v[0], true);
    case 'r': return parse_vec(a, v, 1) && (e->sky_rotation = (float)(v[0] * M_PI / 180), true);
    case 't': return parse_vec(a, v, 1) && (e->turbidity = (float)v[0], true);
    case 'g':
        if (!strcmp(a, "off")) e->flags &= (uint8_t)~VP_ENV_GROUND;
        else if (parse_vec(a, v, 1)) e->flags |= VP_ENV_GROUND, e->ground_height = v[0];
        else return false;
        return true;
    case 'G': return parse_rgb(a, e->ground_color);
    case 'm': return parse_u64(a, &id) && id <= UINT32_MAX && (e->ground_material = (uint32_t)id, true);
    case 'f':
        if (parse_vec(a, v, 4)) {
            for (int i = 0; i < 3; i++) e->fog_color[i] = (float)v[i + 1];
        } else if (!parse_vec(a, v, 1)) return false;
        e->fog_density = (float)v[0];
        return true;
    case 'e':
        if (!strncmp(a, "auto", 4) && (!a[4] || (a[4] == ':' && parse_vec(a + 5, v, 1)))) {
            e->exposure_mode = VP_EXPOSURE_AUTO;
            e->exposure_comp = a[4] ? (float)v[0] : 0;
        } else if (parse_vec(a, v, 1)) {
            e->exposure_mode = VP_EXPOSURE_FIXED;
            e->exposure_ev = (float)v[0];
        } else return false;
        return true;
    default: return false;
    }
}

int cmd_env(cli *k, int argc, char **argv)
{
    static const struct option opts[] = {
        {"day", 0, 0, 'd'}, {"night", 0, 0, 'n'}, {"sun", 1, 0, 's'}, {"sun-color", 1, 0, 'c'},
        {"sky", 1, 0, 'k'}, {"sky-intensity", 1, 0, 'i'}, {"sky-rotation", 1, 0, 'r'}, {"turbidity", 1, 0, 't'},
        {"ground", 1, 0, 'g'}, {"ground-color", 1, 0, 'G'}, {"ground-material", 1, 0, 'm'}, {"fog", 1, 0, 'f'},
        {"exposure", 1, 0, 'e'}, {0, 0, 0, 0}};
    static const cli_opt_doc docs[] = {
        {'s', "--sun", "AZ,EL[,LUX] in degrees (azimuth from +Z towards +X, elevation), or off"},
        {'c', "--sun-color", "R,G,B linear, 0..1 each"},
        {'k', "--sky", "analytic, color:R,G,B or exr:TEXTURE_ID"},
        {'i', "--sky-intensity", "a number, 0..1e6"},
        {'r', "--sky-rotation", "degrees about +Y"},
        {'t', "--turbidity", "a number, 1..10"},
        {'g', "--ground", "HEIGHT in metres, or off"},
        {'G', "--ground-color", "R,G,B albedo, 0..1 each"},
        {'m', "--ground-material", "a material id, 0 for --ground-color"},
        {'f', "--fog", "DENSITY[,R,G,B] (per metre, 0..1; 0 = none)"},
        {'e', "--exposure", "auto, auto:COMP (EV added) or a fixed EV100"},
    };
    /* the values checked before connecting (on a scratch copy); then the
       environment read (any role) and the changes made in the order given */
    int o, rc;
    bool change = false;
    vp_env e;
    vp_env_default(&e);
    optind = 1;
    opterr = 0;
    while ((o = getopt_long(argc, argv, "", opts, NULL)) != -1) {
        if (o == '?' || o == ':') return die_usage("env: bad option %s", argv[optind - 1]);
        if (!env_option(&e, o, optarg)) return die_bad_opt("env", docs, sizeof docs / sizeof docs[0], o, optarg);
        change = true;
    }
    if (optind != argc) return die_usage("env: unexpected argument %s", argv[optind]);
    if ((rc = connect_cli(k, change ? VP_ROLE_EDITOR : VP_ROLE_VIEWER))) return rc;
    if ((rc = vtc_env_get(k->c, &e))) return server_fail(k, "env", rc);
    if (change) {
        optind = 1;
        while ((o = getopt_long(argc, argv, "", opts, NULL)) != -1) (void)env_option(&e, o, optarg);
        if ((rc = vtc_env_set(k->c, &e, NULL))) return server_fail(k, "env", rc);
        if ((rc = vtc_env_get(k->c, &e))) return server_fail(k, "env", rc);
    }
    print_env(&e);
    return 0;
}
