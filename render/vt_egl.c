/*
 * vt_egl.c — the headless OpenGL context of vt_gl.h (bring-up): EGL
 * displays and platforms, opening and closing a context, making it current
 * and releasing it, its description, clip control, and the helpers the
 * module's other files share (vt_gl_internal.h). On EGL (libglvnd's
 * libEGL, linked directly) and libepoxy (GL entry points, resolved on
 * first call). Targets and readback: vt_gl_target.c; shaders:
 * vt_gl_shader.c.
 *
 * What it owns: one EGLContext per vt_gl, a reference on its EGLDisplay
 * in the process-wide display table below, and the list of its targets
 * (freed with it; their GL objects die with the context). Opening walks
 * the platforms of vt_gl.h in order; each attempt appends "platform: what
 * happened" to a log that becomes the error message when nothing works and
 * vt_gl_info.tried when something does.
 *
 * EGL entry points: eglGetPlatformDisplayEXT (EGL_EXT_platform_base) and
 * the EGL_EXT_device_* queries are extensions, fetched with
 * eglGetProcAddress on each open into a local table: nothing is cached in
 * a global. The EGL 1.5 context attributes have the same values as
 * EGL_KHR_create_context's (MAJOR_VERSION = 0x3098, MINOR_VERSION, the
 * profile mask), so one attribute list serves both. Contexts are created
 * with EGL_NO_CONFIG_KHR where the display has EGL_KHR_no_config_context
 * (a surfaceless context needs no config), otherwise with any config that
 * renders OpenGL. EGL_KHR_surfaceless_context is required: there is no
 * pbuffer fallback.
 *
 * GL calls: libepoxy resolves each entry point on its first call through
 * the current context (eglGetProcAddress; GL 1.x entry points by dlsym
 * from libGL.so.1, which libepoxy 1.5.10 loads and which brings libGLX and
 * libX11 in, unused). Under libglvnd these are dispatch stubs valid for
 * every context, so the process-wide table is correct for any number of
 * contexts and threads (two threads resolving one entry point at once
 * both store the same pointer).
 */
#ifndef _GNU_SOURCE
#define _GNU_SOURCE
#endif
#include "vt_gl_internal.h"

#include <EGL/eglext.h>

#ifdef __SANITIZE_ADDRESS__
#include <dlfcn.h>
#include <link.h>
#endif
#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Values the headers of older EGL may lack (all from the Khronos registry). */
#ifndef EGL_PLATFORM_SURFACELESS_MESA
#define EGL_PLATFORM_SURFACELESS_MESA 0x31DD
#endif
#ifndef EGL_DRM_RENDER_NODE_FILE_EXT
#define EGL_DRM_RENDER_NODE_FILE_EXT 0x3377
#endif
#ifndef EGL_NO_CONFIG_KHR
#define EGL_NO_CONFIG_KHR ((EGLConfig)0)
#endif

/* ---- messages -------------------------------------------------------------- */

const char *vt_gl_platform_name(vt_gl_platform p)
{
    switch (p) {
    case VT_GL_AUTO:            return "auto";
    case VT_GL_SURFACELESS:     return "surfaceless";
    case VT_GL_DEVICE:          return "device";
    case VT_GL_DEFAULT_DISPLAY: return "default";
    }
    return "?";
}

static const char *egl_error_name(EGLint e)
{
    switch (e) {
    case EGL_SUCCESS:             return "EGL_SUCCESS";
    case EGL_NOT_INITIALIZED:     return "EGL_NOT_INITIALIZED";
    case EGL_BAD_ACCESS:          return "EGL_BAD_ACCESS";
    case EGL_BAD_ALLOC:           return "EGL_BAD_ALLOC";
    case EGL_BAD_ATTRIBUTE:       return "EGL_BAD_ATTRIBUTE";
    case EGL_BAD_CONFIG:          return "EGL_BAD_CONFIG";
    case EGL_BAD_CONTEXT:         return "EGL_BAD_CONTEXT";
    case EGL_BAD_CURRENT_SURFACE: return "EGL_BAD_CURRENT_SURFACE";
    case EGL_BAD_DISPLAY:         return "EGL_BAD_DISPLAY";
    case EGL_BAD_MATCH:           return "EGL_BAD_MATCH";
    case EGL_BAD_NATIVE_PIXMAP:   return "EGL_BAD_NATIVE_PIXMAP";
    case EGL_BAD_NATIVE_WINDOW:   return "EGL_BAD_NATIVE_WINDOW";
    case EGL_BAD_PARAMETER:       return "EGL_BAD_PARAMETER";
    case EGL_BAD_SURFACE:         return "EGL_BAD_SURFACE";
    case EGL_CONTEXT_LOST:        return "EGL_CONTEXT_LOST";
    }
    return "unknown EGL error";
}

const char *vt_gl_error_name(GLenum e)
{
    switch (e) {
    case GL_NO_ERROR:                      return "GL_NO_ERROR";
    case GL_INVALID_ENUM:                  return "GL_INVALID_ENUM";
    case GL_INVALID_VALUE:                 return "GL_INVALID_VALUE";
    case GL_INVALID_OPERATION:             return "GL_INVALID_OPERATION";
    case GL_INVALID_FRAMEBUFFER_OPERATION: return "GL_INVALID_FRAMEBUFFER_OPERATION";
    case GL_OUT_OF_MEMORY:                 return "GL_OUT_OF_MEMORY";
    }
    return "unknown GL error";
}

int vt_gl_ok(char *err, size_t errlen)
{
    if (err && errlen) err[0] = 0;
    return VT_OK;
}

/* Appends to a fixed buffer, "; " between entries, truncating quietly. */
typedef struct open_log {
    char   s[512];
    size_t n;
} open_log;

#if defined(__GNUC__)
__attribute__((format(printf, 2, 3)))
#endif
static void log_add(open_log *l, const char *fmt, ...)
{
    if (l->n >= sizeof l->s - 1) return;
    if (l->n) {
        int k = snprintf(l->s + l->n, sizeof l->s - l->n, "; ");
        if (k > 0) l->n += (size_t)k;
        if (l->n >= sizeof l->s - 1) { l->n = sizeof l->s - 1; return; }
    }
    va_list ap;
    va_start(ap, fmt);
    int k = vsnprintf(l->s + l->n, sizeof l->s - l->n, fmt, ap);
    va_end(ap);
    if (k > 0) l->n += (size_t)k;
    if (l->n > sizeof l->s - 1) l->n = sizeof l->s - 1;
}

/* Whole-word search in a space-separated extension list (NULL: none). */
static bool has_word(const char *list, const char *word)
{
    if (!list) return false;
    size_t n = strlen(word);
    for (const char *p = list; (p = strstr(p, word)); p += n)
        if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == 0)) return true;
    return false;
}

static void copy_str(char *dst, size_t cap, const char *src)
{
    snprintf(dst, cap, "%s", src ? src : "");
}

/* ---- the display table ------------------------------------------------------
 * One entry per EGLDisplay some vt_gl holds: how many hold it, and whether
 * this module initialised it (then the last close terminates it). A short
 * list: a process has a few displays at most. The lock is held across
 * eglInitialize and eglTerminate so that an open and a close of the same
 * display cannot interleave. */

typedef struct dpy_ref {
    EGLDisplay      dpy;
    int             refs;
    bool            owned; /* eglInitialize'd here, not by someone before */
    EGLint          major, minor;
    struct dpy_ref *next;
} dpy_ref;

static pthread_mutex_t g_dpy_lock = PTHREAD_MUTEX_INITIALIZER;
static dpy_ref        *g_dpys;

/* Takes a reference, initialising the display on the first. On failure
 * returns the EGL error (EGL_BAD_ALLOC for our own allocation) and holds
 * no reference. */
static EGLint dpy_acquire(EGLDisplay dpy, EGLint *major, EGLint *minor)
{
    EGLint rc = EGL_SUCCESS;
    pthread_mutex_lock(&g_dpy_lock);
    dpy_ref *r = g_dpys;
    while (r && r->dpy != dpy) r = r->next;
    if (!r) {
        r = calloc(1, sizeof *r);
        if (!r) { rc = EGL_BAD_ALLOC; goto out; }
        /* an initialised display answers EGL_VERSION; then it is someone
         * else's and is never terminated here */
        bool already = eglQueryString(dpy, EGL_VERSION) != NULL;
        if (!already) eglGetError(); /* drop the EGL_NOT_INITIALIZED just raised */
        if (!eglInitialize(dpy, &r->major, &r->minor)) {
            rc = eglGetError();
            free(r);
            goto out;
        }
        r->dpy = dpy;
        r->owned = !already;
        r->next = g_dpys;
        g_dpys = r;
    }
    r->refs++;
    *major = r->major;
    *minor = r->minor;
out:
    pthread_mutex_unlock(&g_dpy_lock);
    return rc;
}

static void dpy_release(EGLDisplay dpy)
{
    pthread_mutex_lock(&g_dpy_lock);
    for (dpy_ref **pp = &g_dpys; *pp; pp = &(*pp)->next) {
        dpy_ref *r = *pp;
        if (r->dpy != dpy) continue;
        if (--r->refs == 0) {
            if (r->owned) eglTerminate(dpy);
            *pp = r->next;
            free(r);
        }
        break;
    }
    pthread_mutex_unlock(&g_dpy_lock);
}

/* ---- opening --------------------------------------------------------------- */

/* The EGL extension entry points one open uses; NULL where absent. */
typedef struct egl_fns {
    const char                         *client_ext; /* EGL_NO_DISPLAY's EGL_EXTENSIONS */
    PFNEGLGETPLATFORMDISPLAYEXTPROC     get_platform_display;
    PFNEGLQUERYDEVICESEXTPROC           query_devices;
    PFNEGLQUERYDEVICESTRINGEXTPROC      query_device_string;
    PFNEGLQUERYDISPLAYATTRIBEXTPROC     query_display_attrib;
} egl_fns;

static void egl_fns_load(egl_fns *f)
{
    memset(f, 0, sizeof *f);
    /* NULL (EGL_BAD_DISPLAY) without EGL_EXT_client_extensions */
    f->client_ext = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
    if (!f->client_ext) eglGetError();
    const char *ce = f->client_ext;
    if (has_word(ce, "EGL_EXT_platform_base"))
        f->get_platform_display =
            (PFNEGLGETPLATFORMDISPLAYEXTPROC)eglGetProcAddress("eglGetPlatformDisplayEXT");
    if (has_word(ce, "EGL_EXT_device_enumeration") || has_word(ce, "EGL_EXT_device_base"))
        f->query_devices = (PFNEGLQUERYDEVICESEXTPROC)eglGetProcAddress("eglQueryDevicesEXT");
    if (has_word(ce, "EGL_EXT_device_query") || has_word(ce, "EGL_EXT_device_base")) {
        f->query_device_string =
            (PFNEGLQUERYDEVICESTRINGEXTPROC)eglGetProcAddress("eglQueryDeviceStringEXT");
        f->query_display_attrib =
            (PFNEGLQUERYDISPLAYATTRIBEXTPROC)eglGetProcAddress("eglQueryDisplayAttribEXT");
    }
}

/* The device's extensions, or NULL. */
static const char *device_ext(const egl_fns *f, EGLDeviceEXT dev)
{
    if (!f->query_device_string || dev == EGL_NO_DEVICE_EXT) return NULL;
    const char *s = f->query_device_string(dev, EGL_EXTENSIONS);
    if (!s) eglGetError();
    return s;
}

static bool device_is_software(const egl_fns *f, EGLDeviceEXT dev)
{
    return has_word(device_ext(f, dev), "EGL_MESA_device_software");
}

/* The device file of a DRM device ("" if EGL cannot say). */
static void device_file(const egl_fns *f, EGLDeviceEXT dev, char *out, size_t cap)
{
    out[0] = 0;
    const char *ext = device_ext(f, dev);
    const char *s = NULL;
    if (has_word(ext, "EGL_EXT_device_drm_render_node"))
        s = f->query_device_string(dev, EGL_DRM_RENDER_NODE_FILE_EXT);
    if (!s && has_word(ext, "EGL_EXT_device_drm"))
        s = f->query_device_string(dev, EGL_DRM_DEVICE_FILE_EXT);
    if (!s) eglGetError();
    copy_str(out, cap, s);
}

/* The device behind an initialised display (EGL_EXT_device_query). */
static EGLDeviceEXT display_device(const egl_fns *f, EGLDisplay dpy)
{
    EGLAttrib a = 0;
    if (!f->query_display_attrib || !f->query_display_attrib(dpy, EGL_DEVICE_EXT, &a)) {
        eglGetError();
        return EGL_NO_DEVICE_EXT;
    }
    return (EGLDeviceEXT)a;
}

/* Renderer strings of software rasterizers, for displays whose device EGL
 * cannot name (Mesa's: "llvmpipe (LLVM ...)", "softpipe"). */
static bool renderer_is_software(const char *r)
{
    return !strncmp(r, "llvmpipe", 8) || !strncmp(r, "softpipe", 8) ||
           strstr(r, "Software Rasterizer") != NULL;
}

bool vt_gl_is_current(const vt_gl *g)
{
    return g && g->ctx != EGL_NO_CONTEXT && eglGetCurrentContext() == g->ctx;
}

/* Makes nothing current if c is current here, destroys c, drops dpy. */
static void drop_context(EGLDisplay dpy, EGLContext c)
{
    if (c != EGL_NO_CONTEXT) {
        if (eglGetCurrentContext() == c)
            eglMakeCurrent(dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
        eglDestroyContext(dpy, c);
    }
    dpy_release(dpy);
}

/* Reads the GL side of info from the context current on this thread.
 * false (with why in `why`) if it is not a 3.3+ core desktop context. */
static bool read_gl_info(vt_gl_info *in, char *why, size_t whylen)
{
    const char *s;
    if (!epoxy_is_desktop_gl()) {
        snprintf(why, whylen, "not desktop OpenGL");
        return false;
    }
    int ver = epoxy_gl_version();
    in->gl_major = ver / 10;
    in->gl_minor = ver % 10;
    copy_str(in->vendor, sizeof in->vendor, (s = (const char *)glGetString(GL_VENDOR)));
    copy_str(in->renderer, sizeof in->renderer, (s = (const char *)glGetString(GL_RENDERER)));
    copy_str(in->version, sizeof in->version, (s = (const char *)glGetString(GL_VERSION)));
    if (ver < 33) {
        snprintf(why, whylen, "GL %d.%d (%s), need 3.3", in->gl_major, in->gl_minor, in->version);
        return false;
    }
    GLint mask = 0;
    glGetIntegerv(GL_CONTEXT_PROFILE_MASK, &mask);
    if (!(mask & GL_CONTEXT_CORE_PROFILE_BIT)) {
        snprintf(why, whylen, "GL %d.%d is not a core profile", in->gl_major, in->gl_minor);
        return false;
    }
    copy_str(in->glsl_version, sizeof in->glsl_version,
             (const char *)glGetString(GL_SHADING_LANGUAGE_VERSION));
    in->clip_control = ver >= 45 || epoxy_has_gl_extension("GL_ARB_clip_control");
    GLint tex = 0, rb = 0, vp[2] = {0, 0};
    glGetIntegerv(GL_MAX_TEXTURE_SIZE, &tex);
    glGetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &rb);
    glGetIntegerv(GL_MAX_VIEWPORT_DIMS, vp);
    in->max_texture_size = tex;
    int m = tex;
    if (rb < m) m = rb;
    if (vp[0] < m) m = vp[0];
    if (vp[1] < m) m = vp[1];
    in->max_target_size = m;
    while (glGetError() != GL_NO_ERROR) {}
    return true;
}

/* One attempt's outcome. */
enum { TRY_OK, TRY_NO_DISPLAY, TRY_NO_CONTEXT, TRY_SKIPPED };

/* Initialises dpy (a reference in the display table), creates a 3.3 core
 * context and makes it current with no surface. On TRY_OK, *g holds the
 * display reference and the context; otherwise nothing is held and the
 * log says why. With skip_software (AUTO holding a software fallback), a
 * display whose device is a software one is dropped before a context is
 * made, and a context that turns out to be software afterwards. */
static int try_display(const egl_fns *f, EGLDisplay dpy, const char *label, vt_gl_platform p,
                       int dev_index, const vt_gl_opts *o, bool skip_software, vt_gl *g,
                       open_log *log)
{
    if (dpy == EGL_NO_DISPLAY) {
        log_add(log, "%s: no display (%s)", label, egl_error_name(eglGetError()));
        return TRY_NO_DISPLAY;
    }
    EGLint major = 0, minor = 0;
    EGLint e = dpy_acquire(dpy, &major, &minor);
    if (e != EGL_SUCCESS) {
        log_add(log, "%s: eglInitialize: %s", label, egl_error_name(e));
        return TRY_NO_DISPLAY;
    }
    EGLDeviceEXT device = display_device(f, dpy);
    bool soft_device = device_is_software(f, device);
    if (skip_software && soft_device) {
        log_add(log, "%s: skipped, software", label);
        dpy_release(dpy);
        return TRY_SKIPPED;
    }
    const char *dext = eglQueryString(dpy, EGL_EXTENSIONS);
    const char *apis = eglQueryString(dpy, EGL_CLIENT_APIS);
    bool egl15 = major > 1 || (major == 1 && minor >= 5);
    if (!has_word(apis, "OpenGL")) {
        log_add(log, "%s: no desktop OpenGL (EGL_CLIENT_APIS \"%s\")", label, apis ? apis : "");
        dpy_release(dpy);
        return TRY_NO_CONTEXT;
    }
    if (!egl15 && !has_word(dext, "EGL_KHR_create_context")) {
        log_add(log, "%s: EGL %d.%d without EGL_KHR_create_context", label, major, minor);
        dpy_release(dpy);
        return TRY_NO_CONTEXT;
    }
    if (!has_word(dext, "EGL_KHR_surfaceless_context")) {
        log_add(log, "%s: no EGL_KHR_surfaceless_context", label);
        dpy_release(dpy);
        return TRY_NO_CONTEXT;
    }
    if (!eglBindAPI(EGL_OPENGL_API)) {
        log_add(log, "%s: eglBindAPI(EGL_OPENGL_API): %s", label, egl_error_name(eglGetError()));
        dpy_release(dpy);
        return TRY_NO_CONTEXT;
    }
    EGLConfig cfg = EGL_NO_CONFIG_KHR;
    if (!has_word(dext, "EGL_KHR_no_config_context")) {
        /* any config that renders OpenGL; SURFACE_TYPE 0 matches every one
         * (its default, EGL_WINDOW_BIT, would miss surfaceless displays) */
        const EGLint want[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_SURFACE_TYPE, 0, EGL_NONE};
        EGLint n = 0;
        if (!eglChooseConfig(dpy, want, &cfg, 1, &n) || n < 1) {
            log_add(log, "%s: no OpenGL config (%s)", label, egl_error_name(eglGetError()));
            dpy_release(dpy);
            return TRY_NO_CONTEXT;
        }
    }
    /* EGL 1.5 names; the values are EGL_KHR_create_context's */
    EGLint attr[16], k = 0;
    attr[k++] = EGL_CONTEXT_MAJOR_VERSION;
    attr[k++] = 3;
    attr[k++] = EGL_CONTEXT_MINOR_VERSION;
    attr[k++] = 3;
    attr[k++] = EGL_CONTEXT_OPENGL_PROFILE_MASK;
    attr[k++] = EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT;
    if (o->debug) {
        if (egl15) {
            attr[k++] = EGL_CONTEXT_OPENGL_DEBUG;
            attr[k++] = EGL_TRUE;
        } else {
            attr[k++] = EGL_CONTEXT_FLAGS_KHR;
            attr[k++] = EGL_CONTEXT_OPENGL_DEBUG_BIT_KHR;
        }
    }
    attr[k++] = EGL_NONE;
    EGLContext ctx = eglCreateContext(dpy, cfg, EGL_NO_CONTEXT, attr);
    if (ctx == EGL_NO_CONTEXT) {
        log_add(log, "%s: eglCreateContext(3.3 core): %s", label, egl_error_name(eglGetError()));
        dpy_release(dpy);
        return TRY_NO_CONTEXT;
    }
    if (!eglMakeCurrent(dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, ctx)) {
        log_add(log, "%s: eglMakeCurrent(EGL_NO_SURFACE): %s", label,
                egl_error_name(eglGetError()));
        eglDestroyContext(dpy, ctx);
        dpy_release(dpy);
        return TRY_NO_CONTEXT;
    }
    vt_gl_info in = {0};
    char why[160];
    if (!read_gl_info(&in, why, sizeof why)) {
        log_add(log, "%s: %s", label, why);
        drop_context(dpy, ctx);
        return TRY_NO_CONTEXT;
    }
    in.software = soft_device || renderer_is_software(in.renderer);
    if (skip_software && in.software) {
        log_add(log, "%s: skipped, software (%s)", label, in.renderer);
        drop_context(dpy, ctx);
        return TRY_SKIPPED;
    }
    in.egl_major = major;
    in.egl_minor = minor;
    copy_str(in.egl_vendor, sizeof in.egl_vendor, eglQueryString(dpy, EGL_VENDOR));
    in.platform = p;
    in.device_index = dev_index;
    device_file(f, device, in.device_file, sizeof in.device_file);
    g->dpy = dpy;
    g->ctx = ctx;
    g->info = in;
    return TRY_OK;
}

/* The open in progress: the best context so far and what was tried. */
typedef struct open_state {
    const egl_fns    *f;
    const vt_gl_opts *o;
    bool              auto_mode;
    vt_gl             best;     /* best.ctx set once something worked */
    bool              have_display; /* some display initialised */
    open_log          log;
} open_state;

/* Tries dpy; true when the search can stop (a hardware context, or any
 * context when a platform was named). */
static bool consider(open_state *s, EGLDisplay dpy, const char *label, vt_gl_platform p,
                     int dev_index)
{
    bool have_soft = s->best.ctx != EGL_NO_CONTEXT;
    vt_gl got = {0};
    int r = try_display(s->f, dpy, label, p, dev_index, s->o, s->auto_mode && have_soft, &got,
                        &s->log);
    if (r != TRY_NO_DISPLAY) s->have_display = true;
    if (r != TRY_OK) return false;
    if (have_soft) { /* got is hardware: it replaces the software fallback */
        drop_context(s->best.dpy, s->best.ctx);
        eglMakeCurrent(got.dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, got.ctx);
    }
    s->best = got;
    if (s->auto_mode && got.info.software) {
        log_add(&s->log, "%s: software (%s), kept as fallback", label, got.info.renderer);
        return false;
    }
    log_add(&s->log, "%s: %s", label, got.info.renderer);
    return true;
}

static bool try_surfaceless(open_state *s)
{
    if (!s->f->get_platform_display || !has_word(s->f->client_ext, "EGL_MESA_platform_surfaceless")) {
        log_add(&s->log, "surfaceless: no EGL_MESA_platform_surfaceless");
        return false;
    }
    EGLDisplay d = s->f->get_platform_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, NULL);
    return consider(s, d, "surfaceless", VT_GL_SURFACELESS, -1);
}

static bool try_devices(open_state *s)
{
    const egl_fns *f = s->f;
    if (!f->get_platform_display || !f->query_devices ||
        !has_word(f->client_ext, "EGL_EXT_platform_device")) {
        log_add(&s->log, "device: no EGL_EXT_platform_device / EGL_EXT_device_enumeration");
        return false;
    }
    EGLint n = 0;
    if (!f->query_devices(0, NULL, &n)) {
        log_add(&s->log, "device: eglQueryDevicesEXT: %s", egl_error_name(eglGetError()));
        return false;
    }
    if (n <= 0) {
        log_add(&s->log, "device: 0 devices");
        return false;
    }
    EGLDeviceEXT *devs = calloc((size_t)n, sizeof *devs);
    if (!devs) {
        log_add(&s->log, "device: out of memory");
        return false;
    }
    bool done = false;
    if (!f->query_devices(n, devs, &n)) {
        log_add(&s->log, "device: eglQueryDevicesEXT: %s", egl_error_name(eglGetError()));
        n = 0;
    }
    int want = s->o->device - 1; /* -1: any */
    if (want >= n) log_add(&s->log, "device %d: only %d devices", want, (int)n);
    for (int i = 0; i < n && !done; i++) {
        if (want >= 0 && i != want) continue;
        char label[32];
        snprintf(label, sizeof label, "device %d", i);
        /* no context for a software device while AUTO holds one already */
        if (s->auto_mode && s->best.ctx != EGL_NO_CONTEXT && device_is_software(f, devs[i])) {
            log_add(&s->log, "%s: skipped, software", label);
            continue;
        }
        EGLDisplay d = f->get_platform_display(EGL_PLATFORM_DEVICE_EXT, devs[i], NULL);
        done = consider(s, d, label, VT_GL_DEVICE, i);
    }
    free(devs);
    return done;
}

static bool try_default(open_state *s)
{
    return consider(s, eglGetDisplay(EGL_DEFAULT_DISPLAY), "default", VT_GL_DEFAULT_DISPLAY, -1);
}

#ifdef __SANITIZE_ADDRESS__
/* Mesa's driver (swrast_dri.so and the other *_dri.so, libgallium-*.so
 * from Mesa 24.2) allocates state once per load that only its own static
 * data points to (in 22.3, most likely util_cpu_detect's CPU topology
 * arrays, under a pthread_once). eglTerminate unloads the driver, LSan no
 * longer sees those pointers and reports a few hundred bytes per
 * open/close cycle from "<unknown module>", which no suppression can name.
 * Built with ASan, a successful open therefore pins the loaded driver
 * (RTLD_NODELETE): eglTerminate still runs, the memory stays reachable,
 * and any leak of ours still shows. */
static int pin_one(struct dl_phdr_info *info, size_t size, void *data)
{
    (void)size;
    (void)data;
    const char *name = info->dlpi_name, *base = strrchr(name, '/');
    base = base ? base + 1 : name;
    size_t n = strlen(base);
    bool dri = n > 7 && !strcmp(base + n - 7, "_dri.so");
    if (dri || !strncmp(base, "libgallium", 10)) {
        void *h = dlopen(name, RTLD_LAZY | RTLD_NOLOAD | RTLD_NODELETE);
        if (h) dlclose(h); /* the flag stays */
    }
    return 0;
}

static void pin_drivers(void)
{
    dl_iterate_phdr(pin_one, NULL);
}
#else
static void pin_drivers(void) {}
#endif

int vt_gl_open(vt_gl **out, const vt_gl_opts *opts, char *err, size_t errlen)
{
    vt_gl_opts o = opts ? *opts : (vt_gl_opts){0};
    if (!out) return vp_errf(err, errlen, VT_ERR_INVALID, "vt_gl_open: out is NULL");
    *out = NULL;
    if ((unsigned)o.platform > VT_GL_DEFAULT_DISPLAY || o.device < 0)
        return vp_errf(err, errlen, VT_ERR_INVALID, "vt_gl_open: bad platform or device");
    vt_gl *g = calloc(1, sizeof *g);
    if (!g) return vp_errf(err, errlen, VT_ERR_NOMEM, "vt_gl_open: out of memory");

    /* what was current here before, to restore it if nothing works */
    EGLenum prev_api = eglQueryAPI();
    eglBindAPI(EGL_OPENGL_API);
    EGLDisplay prev_dpy = eglGetCurrentDisplay();
    EGLContext prev_ctx = eglGetCurrentContext();
    EGLSurface prev_draw = eglGetCurrentSurface(EGL_DRAW);
    EGLSurface prev_read = eglGetCurrentSurface(EGL_READ);

    egl_fns f;
    egl_fns_load(&f);
    open_state s = {.f = &f, .o = &o, .auto_mode = o.platform == VT_GL_AUTO};
    bool done = false;
    if (o.platform == VT_GL_AUTO || o.platform == VT_GL_SURFACELESS) done = try_surfaceless(&s);
    if (!done && (o.platform == VT_GL_AUTO || o.platform == VT_GL_DEVICE)) done = try_devices(&s);
    if (!done && (o.platform == VT_GL_AUTO || o.platform == VT_GL_DEFAULT_DISPLAY)) try_default(&s);

    if (s.best.ctx == EGL_NO_CONTEXT) {
        /* every failed attempt released its context: nothing of ours is current */
        if (prev_ctx != EGL_NO_CONTEXT) eglMakeCurrent(prev_dpy, prev_draw, prev_read, prev_ctx);
        if (prev_api != EGL_NONE) eglBindAPI(prev_api);
        eglGetError();
        free(g);
        if (!f.client_ext)
            log_add(&s.log, "libEGL has no client extensions (no EGL vendor library installed?)");
        if (!s.have_display)
            return vp_errf(err, errlen, VT_ERR_NO_DISPLAY,
                        "no EGL: libEGL could not initialise a display on any platform (%s); "
                        "is an EGL driver installed (Debian: libegl-mesa0 and libgl1-mesa-dri, "
                        "or NVIDIA's)?",
                        s.log.s);
        return vp_errf(err, errlen, VT_ERR_NO_CONTEXT,
                    "no desktop OpenGL 3.3 core context on any EGL display (%s)", s.log.s);
    }
    /* a failed attempt after the fallback was made left nothing current */
    if (!eglMakeCurrent(s.best.dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, s.best.ctx)) {
        EGLint e = eglGetError();
        drop_context(s.best.dpy, s.best.ctx);
        free(g);
        return vp_errf(err, errlen, VT_ERR_NO_CONTEXT, "eglMakeCurrent: %s (%s)",
                    egl_error_name(e), s.log.s);
    }
    *g = s.best;
    copy_str(g->info.tried, sizeof g->info.tried, s.log.s);
    pin_drivers();
    *out = g;
    return vt_gl_ok(err, errlen);
}

void vt_gl_close(vt_gl *g)
{
    if (!g) return;
    /* the targets' GL objects die with the context (it shares with none) */
    for (vt_gl_target *t = g->targets, *next; t; t = next) {
        next = t->next;
        free(t);
    }
    eglBindAPI(EGL_OPENGL_API);
    drop_context(g->dpy, g->ctx);
    free(g);
}

int vt_gl_make_current(vt_gl *g, char *err, size_t errlen)
{
    if (!g) return vp_errf(err, errlen, VT_ERR_INVALID, "vt_gl_make_current: NULL");
    eglBindAPI(EGL_OPENGL_API);
    if (eglGetCurrentContext() == g->ctx) return vt_gl_ok(err, errlen);
    if (!eglMakeCurrent(g->dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, g->ctx)) {
        EGLint e = eglGetError();
        return vp_errf(err, errlen, VT_ERR_CURRENT, "eglMakeCurrent: %s%s", egl_error_name(e),
                    e == EGL_BAD_ACCESS ? " (current on another thread)" : "");
    }
    return vt_gl_ok(err, errlen);
}

void vt_gl_release(vt_gl *g)
{
    if (!g) return;
    eglBindAPI(EGL_OPENGL_API);
    if (eglGetCurrentContext() == g->ctx)
        eglMakeCurrent(g->dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
}

const vt_gl_info *vt_gl_get_info(const vt_gl *g)
{
    return g ? &g->info : NULL;
}

/* VT_OK, or VT_ERR_CURRENT with a message naming the call. */
int vt_gl_need_current(const vt_gl *g, const char *what, char *err, size_t errlen)
{
    if (!g) return vp_errf(err, errlen, VT_ERR_INVALID, "%s: NULL", what);
    eglBindAPI(EGL_OPENGL_API);
    if (!vt_gl_is_current(g))
        return vp_errf(err, errlen, VT_ERR_CURRENT,
                    "%s: the context is not current on this thread (vt_gl_make_current)", what);
    return VT_OK;
}

/* Clears GL's error flags so the next check sees only our calls. */
void vt_gl_drain(void)
{
    for (int i = 0; i < 16 && glGetError() != GL_NO_ERROR; i++) {}
}

int vt_gl_clip_control(vt_gl *g, bool zero_to_one, char *err, size_t errlen)
{
    int rc = vt_gl_need_current(g, "vt_gl_clip_control", err, errlen);
    if (rc) return rc;
    if (!g->info.clip_control)
        return vp_errf(err, errlen, VT_ERR_UNSUPPORTED,
                    "glClipControl needs GL 4.5 or GL_ARB_clip_control (have %s)", g->info.version);
    glClipControl(GL_LOWER_LEFT, zero_to_one ? GL_ZERO_TO_ONE : GL_NEGATIVE_ONE_TO_ONE);
    return vt_gl_ok(err, errlen);
}
