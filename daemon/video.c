/*
 * video.c — a stream's H.264 encoder for the daemon (video.h) over
 * render/vt_h264.c: x264 ultrafast, zerolatency, sliced threads as the
 * caller says (frames.c: two for a stream alone, whose encode is then the
 * only work on the cores; one each when several streams' frames run on
 * several workers at once), key frames
 * only when asked (a viewer joining, a broken chain), CRF from the
 * request's quality (1..51, 0: 23) and its rate cap.
 */
#include "video.h"

#include "vt_h264.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct video_enc {
    vt_h264 *e;
    vt_h264_cfg cfg;
};

void video_enc_free(video_enc *ve)
{
    if (!ve) return;
    vt_h264_close(ve->e);
    free(ve);
}

int video_encode(video_enc **vep, uint32_t width, uint32_t height, const vp_render *m, uint32_t fps, bool key,
                 uint32_t threads, const uint8_t *rgba8, const uint8_t **au, size_t *len, bool *is_key, char *err,
                 size_t errlen)
{
    video_enc *ve = *vep;
    /* a chain keeps its own thread count, whatever the daemon's load now */
    vt_h264_cfg cfg = {.width = width, .height = height, .crf_x10 = m->quality * 10, .max_kbps = m->max_kbps,
                       .fps = fps, .threads = ve ? ve->cfg.threads : (int)threads};
    if (ve && memcmp(&ve->cfg, &cfg, sizeof cfg)) { /* another size or rate: a new chain */
        cfg.threads = (int)threads;
        video_enc_free(ve);
        ve = *vep = NULL;
    }
    if (!ve) {
        if (!(ve = calloc(1, sizeof *ve))) {
            snprintf(err, errlen, "out of memory");
            return VT_ERR_NOMEM;
        }
        int rc = vt_h264_open(&ve->e, &cfg, err, errlen);
        if (rc) {
            free(ve);
            return rc;
        }
        ve->cfg = cfg;
        *vep = ve;
        key = true;
    }
    int rc = vt_h264_encode(ve->e, rgba8, 4 * (size_t)width, 4, key, au, len, is_key, err, errlen);
    if (rc == VT_ERR_CODEC) { /* x264's state is unknown: start over */
        video_enc_free(ve);
        *vep = NULL;
    }
    return rc;
}
