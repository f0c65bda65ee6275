/*
 * vt_err.h — render/'s one error table. Every public function of render/
 * (the two renderers, the GL context and its helpers, the image and EXR
 * files) returns 0 or a negative code from VT_ERRORS, never an errno: a
 * file-system failure becomes VT_ERR_FILE (VT_ERR_NOT_FOUND for a missing
 * file, VT_ERR_NOMEM for ENOMEM) and its errno's text goes into the
 * caller's message. The GL codes keep the values they had as VT_GL_ERR_*.
 * The daemon maps these to protocol codes in one place (daemon/errmap.c).
 */
#ifndef VANTAGE_VT_ERR_H
#define VANTAGE_VT_ERR_H

#include "vp_err.h" /* the X-macro plumbing, vp_errf */

#ifdef __cplusplus
extern "C" {
#endif

#define VT_ERRORS(X)                                                                   \
    X(VT_OK,                0, "ok")                                                   \
    X(VT_ERR_INVALID,      -1, "invalid argument")                                     \
    X(VT_ERR_NOMEM,        -2, "out of memory")                                        \
    /* the GL context (vt_gl.h) */                                                     \
    X(VT_ERR_NO_DISPLAY,   -3, "no EGL display could be initialised")                  \
    X(VT_ERR_NO_CONTEXT,   -4, "no desktop OpenGL 3.3+ core context")                  \
    X(VT_ERR_CURRENT,      -5, "context not current on this thread, or cannot be made current") \
    X(VT_ERR_UNSUPPORTED,  -6, "not supported (a GL feature, or a valid file this reader does not handle)") \
    /* drawing with it */                                                              \
    X(VT_ERR_RANGE,        -7, "size, region or count beyond the target, the GL limits or the renderer's") \
    X(VT_ERR_FRAMEBUFFER,  -8, "framebuffer incomplete")                               \
    X(VT_ERR_COMPILE,      -9, "shader did not compile")                               \
    X(VT_ERR_LINK,        -10, "program did not link")                                 \
    X(VT_ERR_GL,          -11, "a GL call failed (glGetError)")                        \
    /* files and streams (vt_exr.h, vt_image.h) */                                     \
    X(VT_ERR_FILE,        -12, "file system error (the message names the call and the cause)") \
    X(VT_ERR_NOT_FOUND,   -13, "no such file, or no such channel in it")               \
    X(VT_ERR_CORRUPT,     -14, "not a valid file or stream of its format, or corrupt") \
    X(VT_ERR_TOO_LARGE,   -15, "image or file larger than this module accepts")        \
    X(VT_ERR_CODEC,       -16, "the image library failed otherwise (its message is in err)") \
    X(VT_ERR_CANCELLED,   -17, "stopped: the caller no longer wants the picture (vt_frame.cancel)")

VP_ERR_ENUM(VT_ERRORS);

/* Message for a code from VT_ERRORS; "unknown error" otherwise. Static. */
const char *vt_strerror(int code);

/* The code for a failed system call's errno: VT_ERR_NOMEM for ENOMEM,
 * VT_ERR_NOT_FOUND for ENOENT, VT_ERR_FILE for any other (the caller puts
 * strerror's text in its message). */
int vt_err_from_errno(int e);

#ifdef __cplusplus
}
#endif

#endif
