/*
 * vt_overlay.h — what a frame draws over its picture for a viewer that
 * commands (issue 20 item 8, the seeds' Tablet Commander): the outline
 * of highlighted instances (the selection) and icons at world positions
 * (marks, units). Both renderers run the same C pass, vt_overlay_draw,
 * once at the end of their draw, after exposure and the post passes, on
 * the picture they return (the GL path on its readback): one set of rules,
 * and the overlay stays crisp (nothing filters or re-exposes it after).
 *
 * An outline is the silhouette of the highlighted instances' pixel
 * coverage, which this file rasterises itself (their meshes under their
 * placement, every triangle, both windings; destruction masks ignored:
 * a damaged building's outline is its intact one). Each covered pixel is
 * visible where its nearness is not behind the frame's depth output: the
 * picture's own visibility, read the same way from either renderer. The
 * outline is a band 2 px wide at 720 rows (1 px each side of the coverage
 * edge; scaled with the height), bright where the edge's object pixels
 * are visible, dimmer where they are hidden behind something else. A
 * caller that culled a highlighted thing as hidden passes it as an extra
 * instance, outlined (dim, where the picture covers it) but not drawn.
 *
 * Icons are shapes of constant screen size at the projected position,
 * drawn on top (not depth-tested) with a dark halo for contrast, their
 * edges anti-aliased by coverage from a signed distance; a position behind
 * the near plane draws nothing, one off screen only what reaches the view.
 *
 * Colours are linear HDR values written after exposure: chosen so the
 * daemon's ACES tone map (at exposure_ev 0) shows them near saturation.
 * Cost: nothing without an overlay; else the highlighted meshes'
 * triangles plus a pass over their screen box (a 1280x720 selection of a
 * building: well under a millisecond), and 2 x 2r px per icon.
 */
#ifndef VANTAGE_VT_OVERLAY_H
#define VANTAGE_VT_OVERLAY_H

#include "vt_soft.h"

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* An icon's shape (its kind), as the commander's marks name them. */
enum {
    VT_ICON_PING = 0,       /* a diamond */
    VT_ICON_SELECT = 1,     /* a hollow square */
    VT_ICON_UNIT = 2        /* a disc; every other kind is drawn as this */
};

typedef struct vt_icon {
    double pos[3];          /* world position, each |x| <= 1e15 */
    uint32_t kind;          /* VT_ICON_* */
    float color[3];         /* linear, after exposure, 0..1e6; all 0: the kind's default */
} vt_icon;

#define VT_OVERLAY_MAX_HL 64u
#define VT_OVERLAY_MAX_ICONS 4096u

/* One outline: a set of instances outlined together in one colour. */
typedef struct vt_outline {
    const uint32_t *hl;     /* indices into the frame's inst, < ninst */
    uint32_t nhl;           /* <= VT_OVERLAY_MAX_HL */
    const vt_instance *extra; /* outlined but not drawn: highlighted things the
                               caller culled as hidden (their outline is the
                               dim one where the picture covers them); BOUNDS
                               placement, mesh an index into the frame's */
    uint32_t nextra;        /* <= VT_OVERLAY_MAX_HL */
    float color[3];         /* linear, after exposure; all 0: the outline's default */
} vt_outline;

/* The outlines, drawn in this order (a later one over an earlier one):
 * a viewer's own highlight (RENDER's, golden (4, 0.6, 0) by default) and
 * the scene's shared selection (SELECT's, cyan (0, 0.6, 4): the select
 * mark's colour). */
enum { VT_OUTLINE_HIGHLIGHT = 0, VT_OUTLINE_SELECTION = 1, VT_OUTLINES = 2 };

/* Zero fields default: no outline, no icons, the default outline colours. */
typedef struct vt_overlay {
    vt_outline outline[VT_OUTLINES];
    const vt_icon *icons;
    uint32_t nicons;        /* <= VT_OVERLAY_MAX_ICONS */
} vt_overlay;

/* The checks of f->overlay (NULL passes): counts, indices, positions,
 * colours. 0, or VT_ERR_INVALID with the field named in err. vt_frame_check
 * runs it. */
int vt_overlay_check(const vt_frame *f, char *err, size_t errlen);

/* Draws f->overlay (NULL: nothing) over f->rgba (alpha set to 1 where
 * drawn), reading f->depth (as the renderer left it) for the outline's
 * visibility. f passed vt_picture_check. 0, or VT_ERR_NOMEM (a scratch
 * mask of the highlighted instances' screen box is allocated per call). */
int vt_overlay_draw(const vt_frame *f, const cull_view_rows *vr, char *err, size_t errlen);

/* The outline's half width in pixels for a picture of height rows: 1
 * below 1260 rows (a 2 px band at 720 and 1080), 2 from 1260 (4 px at
 * 1440), one more each 720 rows after. */
uint32_t vt_overlay_half_width(uint32_t height);

#ifdef __cplusplus
}
#endif
#endif
