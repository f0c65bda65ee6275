/*
 * vtc_view.c — the client library's view builders (vantage.h: gluLookAt
 * and gluPerspective / glOrtho as a vp_view), out of libvantage.c so that
 * code with no sockets builds them too: the commander's camera
 * (client/commander/pad_map.c) in the native client and, compiled to
 * WebAssembly, in the browser's commander page (cmdr_wasm.c). Pure: math
 * and culling/cull_mat.h only, no state, no allocation, no I/O.
 */
#include "vantage.h"

#include "cull_mat.h"

#include <math.h>
#include <string.h>

/* ---- views ------------------------------------------------------------------------ */

static bool camera(vp_view *v, const double eye[3], const double at[3], const double up[3], const double proj[16],
                   uint16_t w, uint16_t h)
{
    double dir[3] = {at[0] - eye[0], at[1] - eye[1], at[2] - eye[2]};
    double u[3] = {up ? up[0] : 0, up ? up[1] : 1, up ? up[2] : 0};
    double cr[3] = {dir[1] * u[2] - dir[2] * u[1], dir[2] * u[0] - dir[0] * u[2], dir[0] * u[1] - dir[1] * u[0]};
    if (!(sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]) > 0) ||
        !(sqrt(cr[0] * cr[0] + cr[1] * cr[1] + cr[2] * cr[2]) > 1e-12))
        return false;
    double view[16];
    cull_mat_look_dir(view, dir, u);
    memset(v, 0, sizeof *v);
    cull_mat_mul(v->view_proj, proj, view);
    memcpy(v->origin, eye, sizeof v->origin);
    v->depth_mode = CULL_DEPTH_GL;
    v->viewport_w = w;
    v->viewport_h = h;
    return true;
}

bool vtc_view_perspective(vp_view *v, const double eye[3], const double at[3], const double up[3], double fovy_deg,
                          uint16_t w, uint16_t h, double znear, double zfar)
{
    if (!(fovy_deg > 0 && fovy_deg < 180) || !w || !h || !(znear > 0) || !(zfar > znear)) return false;
    double proj[16];
    cull_mat_perspective(proj, fovy_deg * M_PI / 180, (double)w / h, znear, zfar, CULL_DEPTH_GL);
    return camera(v, eye, at, up, proj, w, h);
}

bool vtc_view_ortho(vp_view *v, const double eye[3], const double at[3], const double up[3], double width,
                    double height, uint16_t w, uint16_t h, double znear, double zfar)
{
    if (!(width > 0) || !(height > 0) || !w || !h || !(zfar > znear)) return false;
    double proj[16];
    cull_mat_ortho(proj, -width / 2, width / 2, -height / 2, height / 2, znear, zfar, CULL_DEPTH_GL);
    return camera(v, eye, at, up, proj, w, h);
}
