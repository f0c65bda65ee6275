/* fuzz_render_gl.c — fuzz_render.c with the GL path (see there). */
#define FUZZ_RENDER_GL 1
#include "fuzz_render.c"
