/*
 * install_check.c — built against an installed libvantage through
 * pkg-config (make install-check): the header, the library and the .pc
 * file work together.
 */
#include <vantage.h>

#include <stdio.h>
#include <string.h>

int main(void)
{
    vp_view v;
    double eye[3] = {0, 2, -10}, at[3] = {0, 2, 0};
    if (!vtc_view_perspective(&v, eye, at, NULL, 60, 640, 480, 0.1, 100)) return 1;
    if (strcmp(vp_strerror(VP_ERR_MAGIC), "bad magic: not a Vantage client")) return 1;
    vtc_client *c = NULL;
    char err[256];
    /* nothing listens on port 1: a clear error, no crash */
    int rc = vtc_connect(&(vtc_connect_opts){.port = 1, .timeout_ms = 1000}, &c, err, sizeof err);
    printf("install check: libvantage links; connect to port 1: %s (%d)\n", err, rc);
    return rc == VTC_ERR_IO && c == NULL ? 0 : 1;
}
