/*
 * errmap.c — see errmap.h. One switch per module; the table test
 * (tests/test_errmap.c) walks every row of every module's table through
 * these and checks each lands on a defined protocol code.
 */
#include "errmap.h"

#include "culling.h"
#include "protocol.h"
#include "vt_err.h"

int vp_code_from_cull(int rc)
{
    switch (rc) {
    case CULL_OK:            return VP_OK;
    case CULL_ERR_INVALID:   return VP_ERR_INVALID;
    case CULL_ERR_NONFINITE: return VP_ERR_NONFINITE;
    case CULL_ERR_RADIUS:    return VP_ERR_INVALID;
    case CULL_ERR_AABB:      return VP_ERR_INVALID;
    case CULL_ERR_RANGE:     return VP_ERR_INVALID;
    case CULL_ERR_MATRIX:    return VP_ERR_MATRIX;
    case CULL_ERR_VIEWPORT:  return VP_ERR_INVALID;
    case CULL_ERR_VIEWS:     return VP_ERR_COUNT;
    case CULL_ERR_HANDLE:    return VP_ERR_STALE;
    case CULL_ERR_CAPACITY:  return VP_ERR_LIMIT;
    case CULL_ERR_NOMEM:     return VP_ERR_BUSY;
    case CULL_ERR_OUTPUT:    return VP_ERR_INTERNAL; /* the daemon sized a buffer wrong */
    case CULL_ERR_THREADS:   return VP_ERR_INTERNAL;
    case CULL_ERR_MESH:      return VP_ERR_INVALID;
    case CULL_ERR_BUFFER:    return VP_ERR_INTERNAL; /* the daemon's own occlusion buffer size */
    }
    return VP_ERR_INTERNAL;
}

int vp_code_from_vt(int rc)
{
    switch (rc) {
    case VT_OK:              return VP_OK;
    case VT_ERR_INVALID:     return VP_ERR_INVALID;
    case VT_ERR_NOMEM:       return VP_ERR_BUSY;
    case VT_ERR_NO_DISPLAY:  return VP_ERR_UNSUPPORTED;
    case VT_ERR_NO_CONTEXT:  return VP_ERR_UNSUPPORTED;
    case VT_ERR_CURRENT:     return VP_ERR_INTERNAL;
    case VT_ERR_UNSUPPORTED: return VP_ERR_UNSUPPORTED;
    case VT_ERR_RANGE:       return VP_ERR_LIMIT; /* a frame beyond the GL limits */
    case VT_ERR_FRAMEBUFFER: return VP_ERR_INTERNAL;
    case VT_ERR_COMPILE:     return VP_ERR_INTERNAL;
    case VT_ERR_LINK:        return VP_ERR_INTERNAL;
    case VT_ERR_GL:          return VP_ERR_INTERNAL;
    case VT_ERR_FILE:        return VP_ERR_INTERNAL; /* the daemon renders to memory */
    case VT_ERR_NOT_FOUND:   return VP_ERR_INTERNAL;
    case VT_ERR_CORRUPT:     return VP_ERR_INTERNAL;
    case VT_ERR_TOO_LARGE:   return VP_ERR_LIMIT;
    case VT_ERR_CODEC:       return VP_ERR_INTERNAL;
    case VT_ERR_CANCELLED:   return VP_ERR_BUSY; /* (the daemon sends none: a stream's frame it stopped) */
    }
    return VP_ERR_INTERNAL;
}
