/*
 * errmap.h — the daemon's one translation of each module's error codes
 * into protocol codes (VP_ERRORS), which is all a client ever sees. Every
 * call site that turns a culling or render code into a reply goes through
 * these, so one module code always means one protocol code.
 *
 * The rules (docs/ARCHITECTURE.md, "Error spaces"):
 *   * a bad value the client sent: VP_ERR_INVALID, or the more exact
 *     NONFINITE / MATRIX / STALE / COUNT where the protocol has one;
 *   * a fixed limit of the server (entity capacity, a size beyond what a
 *     renderer takes): VP_ERR_LIMIT;
 *   * out of memory: VP_ERR_BUSY. It is the server's state at that moment,
 *     not the request's fault nor a fixed limit, and memory comes back as
 *     frames and replies finish, so the client may retry (the daemon's own
 *     allocation failures answer BUSY too);
 *   * a GL context or feature this server lacks: VP_ERR_UNSUPPORTED;
 *   * anything else (a GL call failing, a codec failing, an output buffer
 *     the daemon sized wrong): VP_ERR_INTERNAL.
 * Codes outside a module's table map to VP_ERR_INTERNAL. Pure functions.
 */
#ifndef VANTAGE_ERRMAP_H
#define VANTAGE_ERRMAP_H

/* A CULL_ERRORS code (culling.h) as a VP_ERRORS code; CULL_OK -> VP_OK. */
int vp_code_from_cull(int rc);

/* A VT_ERRORS code (render/vt_err.h) as a VP_ERRORS code; VT_OK -> VP_OK. */
int vp_code_from_vt(int rc);

#endif
