/*
 * vt_gl.h — a headless desktop OpenGL context for the renderer: EGL with
 * no window system, a 3.3+ core profile context made current with no
 * surface, offscreen targets (a framebuffer object with a float colour
 * texture and a 32-bit float depth texture), colour and depth read back as
 * float, and shader compile / link helpers that return the info log.
 *
 * Where the context comes from (vt_gl_open, VT_GL_AUTO): in order,
 *   1. EGL_MESA_platform_surfaceless — Mesa on a render node, or Mesa's
 *      software rasterizer (llvmpipe) where there is no GPU;
 *   2. EGL_EXT_platform_device — each device from eglQueryDevicesEXT in
 *      turn; this is how the NVIDIA driver reaches a GPU without X;
 *   3. eglGetDisplay(EGL_DEFAULT_DISPLAY) — whatever the EGL vendor picks
 *      (X11 when $DISPLAY is set, with Mesa).
 * A software renderer found on the way is kept only as a fallback: AUTO
 * goes on looking for a hardware one and takes the first it finds (Mesa's
 * surfaceless display gives llvmpipe on a machine whose GPU is NVIDIA's).
 * Naming one platform in vt_gl_opts tries that platform only.
 * Every display must offer desktop OpenGL (EGL_OPENGL_API) and a context
 * created with EGL 1.5 / EGL_KHR_create_context attributes for 3.3 core;
 * the driver may return a later version (Mesa: 4.5), and anything from
 * 3.3 up in the core profile is accepted.
 *
 * Load it expects: one or a few contexts per process, opened at start-up,
 * then frames of up to a few hundred thousand triangles at 1280x720.
 * Costs are the driver's; this module adds a handful of state queries per
 * call. Measured with Mesa 22.3 llvmpipe, LP_NUM_THREADS=2, on the
 * project's 2-core machine: the first open in a process 30-60 ms (loading
 * the driver and LLVM), an open after the last close 7-10 ms (the display
 * is initialised again), another context on a display in use 1.5 ms; the
 * city scene's 1,000 lit boxes (12k triangles) clear + draw + glFinish
 * 5.5-7 ms with back-face culling, its 15,000 object boxes (180k) 16-18
 * ms; reading back 1280x720: depth 0.3 ms, RGBA32F colour 1.1 ms, RGBA16F
 * colour 2.1-3.5 ms (Mesa widens the halves).
 *
 * Threading: a vt_gl is one GL context, and a GL context is current on at
 * most one thread at a time. vt_gl_open leaves the new context current on
 * the calling thread. To move it: the owning thread calls vt_gl_release
 * (eglMakeCurrent with EGL_NO_CONTEXT, which flushes), then the next thread
 * calls vt_gl_make_current; the handover between the two calls must be
 * ordered by the caller (a mutex, a queue, a join): EGL only reports
 * EGL_BAD_ACCESS if the context is still current elsewhere. Every
 * function that makes GL calls (clip control, targets, readback, shaders)
 * needs the context current on the calling thread and returns
 * VT_ERR_CURRENT otherwise (a GL call with no current context would
 * silently do nothing). Different vt_gl may be used on different
 * threads at the same time; they share no GL objects. These functions
 * call eglBindAPI(EGL_OPENGL_API) on the calling thread and leave it bound.
 *
 * Displays: EGL keeps one EGLDisplay per platform and device per process,
 * and eglTerminate is not reference counted (EGL_KHR_display_reference
 * would be, but Mesa 22 lacks it), so two vt_gl on one display must not
 * terminate it under each other. The module keeps a process-wide count of
 * its references per display — its one piece of global state, behind a
 * mutex — and calls eglTerminate when the last vt_gl on a display closes,
 * and only if the display was not already initialised when the module
 * first took it (code outside this module that uses the same display
 * keeps it alive by initialising it before vt_gl_open, and must not
 * terminate it while a vt_gl uses it). libepoxy keeps its own process-wide
 * table of resolved GL entry points (filled on first use; identical for
 * every context under libglvnd).
 *
 * Conventions: window coordinates have their origin at the lower left, and
 * a readback returns rows bottom-up as GL gives them: rgba[4*(y*w + x)] is
 * the pixel whose centre is at (x + 0.5, y + 0.5) from the lower-left
 * corner. Depth is the raw window-space value in [0,1] from the float
 * depth buffer: with glDepthRange(0,1) (the default) and GL's default clip
 * control it is z_ndc/2 + 1/2, z_ndc = z_clip/w_clip in [-1,1], a float
 * addition whose result is only as fine as floats near 1/2 (6e-8
 * steps), whatever z_ndc; after vt_gl_clip_control(g, true) it is z_ndc
 * itself, in [0,1], which keeps the finer floats near 0 for reversed-Z
 * (clear to 0, glDepthFunc(GL_GREATER)).
 * Depth is linear in window x and y across a triangle whatever the w.
 *
 * Errors: 0 or a negative code from render/'s table (VT_ERRORS, vt_err.h;
 * the GL codes are VT_ERR_NO_DISPLAY .. VT_ERR_GL). `err` (may be NULL, any
 * errlen) receives a NUL-terminated message that says what failed: EGL and
 * GL error names, every platform tried and why it failed, the compiler's
 * info log; it is set to "" on success.
 *
 * Build: pkg-config modules egl and epoxy (Debian: libegl-dev,
 * libepoxy-dev). At run time libEGL needs a vendor library: Mesa's
 * (libegl-mesa0, with libgl1-mesa-dri for its drivers, llvmpipe among
 * them), or NVIDIA's.
 */
#ifndef VANTAGE_VT_GL_H
#define VANTAGE_VT_GL_H

#include "vt_err.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ---- context ------------------------------------------------------------ */

typedef enum vt_gl_platform {
    VT_GL_AUTO = 0,        /* surfaceless, then each device, then default */
    VT_GL_SURFACELESS,     /* EGL_MESA_platform_surfaceless only */
    VT_GL_DEVICE,          /* EGL_EXT_platform_device only */
    VT_GL_DEFAULT_DISPLAY, /* eglGetDisplay(EGL_DEFAULT_DISPLAY) only */
} vt_gl_platform;

/* "auto", "surfaceless", "device", "default"; "?" for other values. Static. */
const char *vt_gl_platform_name(vt_gl_platform p);

/* Device selection for the device platform: VT_GL_ANY_DEVICE (0) tries
 * each device eglQueryDevicesEXT lists, in its order; VT_GL_DEVICE_INDEX(i)
 * only device i (counting from 0). */
#define VT_GL_ANY_DEVICE 0
#define VT_GL_DEVICE_INDEX(i) ((i) + 1)

/* Zero means default everywhere. */
typedef struct vt_gl_opts {
    vt_gl_platform platform; /* AUTO, or the one platform to try */
    int  device;             /* VT_GL_ANY_DEVICE or VT_GL_DEVICE_INDEX(i) */
    bool debug;              /* EGL_CONTEXT_OPENGL_DEBUG: a debug context
                                (the driver may check more, and be slower) */
} vt_gl_opts;

/* What the context is; filled by vt_gl_open, constant afterwards. */
typedef struct vt_gl_info {
    char vendor[128];        /* GL_VENDOR, truncated to fit */
    char renderer[256];      /* GL_RENDERER, e.g. "llvmpipe (LLVM 15.0.6, 256 bits)" */
    char version[128];       /* GL_VERSION, e.g. "4.5 (Core Profile) Mesa 22.3.6" */
    char glsl_version[64];   /* GL_SHADING_LANGUAGE_VERSION */
    int  gl_major, gl_minor; /* the context's version: 3.3 or later, core profile */
    int  egl_major, egl_minor; /* eglInitialize's version of the display */
    char egl_vendor[64];     /* EGL_VENDOR of the display, e.g. "Mesa Project" */
    vt_gl_platform platform; /* the platform used: never VT_GL_AUTO */
    int  device_index;       /* with VT_GL_DEVICE: index in eglQueryDevicesEXT's
                                list; -1 with the other platforms */
    char device_file[64];    /* the device's DRM render node or device file
                                when EGL can say (EGL_EXT_device_drm*), or "" */
    bool software;           /* a software rasterizer (Mesa's software device,
                                llvmpipe or softpipe) */
    bool clip_control;       /* glClipControl is available (GL 4.5 or
                                GL_ARB_clip_control): see vt_gl_clip_control */
    int  max_texture_size;   /* GL_MAX_TEXTURE_SIZE, pixels per side */
    int  max_target_size;    /* largest vt_gl_target side: the least of
                                GL_MAX_TEXTURE_SIZE, GL_MAX_RENDERBUFFER_SIZE
                                and GL_MAX_VIEWPORT_DIMS */
    char tried[512];         /* every platform tried and what it gave, e.g.
                                "surfaceless: software (llvmpipe), kept as
                                fallback; device 0: skipped, software" */
} vt_gl_info;

typedef struct vt_gl vt_gl;

/* Creates a context as described at the top of this file and makes it
 * current on the calling thread (replacing the thread's current OpenGL
 * context, if any). `o` may be NULL (all defaults). On success *out owns
 * the context; free it with vt_gl_close. On failure *out is NULL, the
 * thread's previously current context (if any) is current again, and err
 * names every platform tried and why it failed:
 *   VT_ERR_NO_DISPLAY — no platform gave an initialised EGL display
 *     (no EGL vendor library, no device, no X server, ...);
 *   VT_ERR_NO_CONTEXT — some display initialised, but none gave a
 *     desktop OpenGL 3.3+ core context current with no surface;
 *   VT_ERR_INVALID, VT_ERR_NOMEM. */
int vt_gl_open(vt_gl **out, const vt_gl_opts *o, char *err, size_t errlen);

/* Destroys the context and every target still alive on it (their pointers
 * become invalid), releases the display (eglTerminate if this was the last
 * vt_gl on a display the module initialised). Call it on the thread where
 * the context is current, or when it is current nowhere; if it is current
 * on another thread, EGL defers the context's destruction until that
 * thread releases it. NULL is ignored. */
void vt_gl_close(vt_gl *g);

/* Makes g current on the calling thread, with no surface. VT_ERR_CURRENT
 * if EGL refuses (most often: still current on another thread). Cheap when
 * already current. */
int vt_gl_make_current(vt_gl *g, char *err, size_t errlen);

/* If g is current on the calling thread, flushes it and makes no context
 * current; otherwise does nothing. Afterwards any thread may take g with
 * vt_gl_make_current. NULL is ignored. */
void vt_gl_release(vt_gl *g);

/* g's description; valid until vt_gl_close. Any thread. */
const vt_gl_info *vt_gl_get_info(const vt_gl *g);

/* Selects the depth convention for this context (it is per-context GL
 * state): zero_to_one = true sets glClipControl(GL_LOWER_LEFT,
 * GL_ZERO_TO_ONE), so window depth is z_ndc in [0,1]; false restores GL's
 * default (GL_LOWER_LEFT, GL_NEGATIVE_ONE_TO_ONE), depth z_ndc/2 + 1/2.
 * VT_ERR_UNSUPPORTED when info.clip_control is false. */
int vt_gl_clip_control(vt_gl *g, bool zero_to_one, char *err, size_t errlen);

/* ---- offscreen targets -------------------------------------------------- */

typedef enum vt_gl_color_format {
    VT_GL_RGBA16F = 0, /* half floats: 8 bytes a pixel, 11-bit precision,
                          magnitudes to 65504; a float written becomes one
                          of its two neighbouring halves (GL leaves the
                          rounding to the driver: llvmpipe truncates toward
                          zero) */
    VT_GL_RGBA32F,     /* floats: 16 bytes a pixel, stored exactly */
} vt_gl_color_format;

typedef struct vt_gl_target_desc {
    vt_gl_color_format color; /* default VT_GL_RGBA16F */
} vt_gl_target_desc;

typedef struct vt_gl_target vt_gl_target;

/* A framebuffer object w x h pixels (1 .. info.max_target_size a side)
 * with a colour texture (desc's format, attachment 0, draw and read
 * buffer) and a GL_DEPTH_COMPONENT32F depth texture, contents undefined
 * until cleared. `d` may be NULL. Both textures have one level, NEAREST
 * filtering and CLAMP_TO_EDGE, so they can be sampled as they are. Costs
 * (16 + 4) * w * h bytes of GPU memory with RGBA32F, (8 + 4) * w * h with
 * RGBA16F. Restores the framebuffer and texture bindings it changes.
 * VT_ERR_RANGE for a bad size, VT_ERR_GL (GL_OUT_OF_MEMORY, ...),
 * VT_ERR_FRAMEBUFFER, VT_ERR_CURRENT, VT_ERR_NOMEM. */
int vt_gl_target_create(vt_gl *g, uint32_t w, uint32_t h, const vt_gl_target_desc *d,
                        vt_gl_target **out, char *err, size_t errlen);

/* Reallocates both textures at w x h (same GL names, contents undefined).
 * On failure the target keeps its old size only if the error was
 * VT_ERR_RANGE or VT_ERR_CURRENT; after a GL failure it must be
 * destroyed. */
int vt_gl_target_resize(vt_gl_target *t, uint32_t w, uint32_t h, char *err, size_t errlen);

/* Deletes the GL objects (needs t's context current; if it is not, only
 * the memory is freed and the objects live until the context closes).
 * NULL is ignored. */
void vt_gl_target_destroy(vt_gl_target *t);

/* Binds t as GL_FRAMEBUFFER (draw and read) and sets the viewport to the
 * whole target, ready to draw. */
int vt_gl_target_bind(vt_gl_target *t);

/* Binds t (as vt_gl_target_bind) and clears colour to rgba (NULL: leave
 * colour) and depth to `depth` (clamped to [0,1]; NaN: leave depth) with
 * glClearBufferfv. Obeys the scissor test and the write masks, as GL does. */
int vt_gl_target_clear(vt_gl_target *t, const float rgba[4], float depth);

/* Size and GL names, for drawing and sampling: the framebuffer, the colour
 * texture and the depth texture (GL_TEXTURE_2D). Owned by t. */
void vt_gl_target_size(const vt_gl_target *t, uint32_t *w, uint32_t *h);
unsigned vt_gl_target_fbo(const vt_gl_target *t);
unsigned vt_gl_target_color_texture(const vt_gl_target *t);
unsigned vt_gl_target_depth_texture(const vt_gl_target *t);

/* ---- readback ------------------------------------------------------------ */

typedef enum vt_gl_read_path {
    VT_GL_READ_AUTO = 0, /* DIRECT, the faster one measured (llvmpipe) */
    VT_GL_READ_DIRECT,   /* glReadPixels into the caller's memory */
    VT_GL_READ_PBO,      /* glReadPixels into a pixel pack buffer owned by the
                            target (grown to fit, 20 bytes a pixel read),
                            then map and copy: one copy more, 1.5-2.5x the
                            time on llvmpipe. A PBO pays only when the map
                            waits for a later frame, which this synchronous
                            call cannot do */
} vt_gl_read_path;

typedef struct vt_gl_read_desc {
    uint32_t x, y, w, h;  /* region, lower-left origin; w = h = 0: all */
    vt_gl_read_path path;
} vt_gl_read_desc;

/* Floats needed for a region of w x h: 4*w*h for colour, w*h for depth.
 * 0 if that overflows size_t. */
size_t vt_gl_read_bound(uint32_t w, uint32_t h, bool color);

/* Waits for the rendering into t to finish and reads the region
 * (d NULL: all of t) back: colour as RGBA floats into rgba[0 ..
 * 4*w*h), depth as floats in [0,1] into depth[0 .. w*h), either
 * pointer NULL to skip it (both NULL is VT_ERR_INVALID). Rows
 * bottom-up and tightly packed: sample (x, y) of the region (y = 0 the
 * lowest row) at rgba[4*(y*w + x) + c] and depth[y*w + x]. Colour is
 * exactly the stored value (a half widens exactly; no clamping: GL
 * clamps only fixed-point buffers on read). Sets GL_PACK_ALIGNMENT to 4 and
 * GL_PACK_ROW_LENGTH, GL_PACK_SKIP_ROWS and GL_PACK_SKIP_PIXELS to 0 (GL's
 * defaults) and leaves them so; restores the framebuffer and pixel pack
 * buffer bindings. VT_ERR_RANGE if the region is outside t. */
int vt_gl_readback(vt_gl_target *t, float *rgba, float *depth, const vt_gl_read_desc *d,
                   char *err, size_t errlen);

/* ---- shaders ---------------------------------------------------------------- */

/* Compiles one shader of GL type `stage` (GL_VERTEX_SHADER, GL_FRAGMENT_SHADER,
 * ...) from a NUL-terminated source; *out is the shader name, the caller's
 * to glDeleteShader. VT_ERR_COMPILE with "vertex shader: " and the info
 * log in err. */
int vt_gl_shader_compile(vt_gl *g, unsigned stage, const char *src, unsigned *out, char *err,
                         size_t errlen);

/* Links the n shaders into a program; *out is the caller's to
 * glDeleteProgram. The shaders are detached again (the caller may delete
 * them). VT_ERR_LINK with the info log in err. */
int vt_gl_program_link(vt_gl *g, const unsigned *shaders, size_t n, unsigned *out, char *err,
                       size_t errlen);

/* Compiles a vertex and a fragment shader, links them, deletes the shaders:
 * *out is the program. Either step's error and log as above. */
int vt_gl_program_build(vt_gl *g, const char *vs, const char *fs, unsigned *out, char *err,
                        size_t errlen);

#ifdef __cplusplus
}
#endif

#endif
