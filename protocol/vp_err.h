/*
 * vp_err.h — what every module's error handling shares, header-only so
 * that any folder (culling/, render/, protocol/, daemon/, client/) can use
 * it without linking another folder's library:
 *
 *   * the one message formatter, vp_errf(err, errlen, code, fmt, ...):
 *     formats into the caller's buffer and returns `code`, so a failing
 *     path reads `return vp_errf(err, errlen, CULL_ERR_RANGE, "x is %g", x);`;
 *   * the X-macro plumbing of an error table. A module lists its codes once
 *     as X(NAME, value, "message") rows (CULL_ERRORS, VP_ERRORS,
 *     VT_ERRORS) and gets its enum with VP_ERR_ENUM(TABLE) and its
 *     code -> message function with VP_ERR_DEFINE_STRERROR(fn, TABLE).
 *
 * Each module keeps its own code space (docs/ARCHITECTURE.md, "Error
 * spaces"); only the daemon translates them into protocol codes
 * (daemon/errmap.c). Nothing here allocates or keeps state.
 */
#ifndef VANTAGE_VP_ERR_H
#define VANTAGE_VP_ERR_H

#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>

/* Formats into err[0..errlen) (err NULL or errlen 0: nothing written; the
 * message is cut to fit and always NUL-terminated) and returns code. */
static inline int vp_errf(char *err, size_t errlen, int code, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
static inline int vp_errf(char *err, size_t errlen, int code, const char *fmt, ...)
{
    if (err && errlen) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(err, errlen, fmt, ap);
        va_end(ap);
    }
    return code;
}

/* The table's rows as enumerators: `VP_ERR_ENUM(CULL_ERRORS);` */
#define VP_ERR_ENUM_ROW_(name, value, msg) name = value,
#define VP_ERR_ENUM(TABLE) enum { TABLE(VP_ERR_ENUM_ROW_) }

/* Defines `const char *fn(int code)`: the row's message, "unknown error"
 * for a value in no row. The strings are static. */
#define VP_ERR_MSG_ROW_(name, value, msg) case value: return msg;
#define VP_ERR_DEFINE_STRERROR(fn, TABLE)                                        \
    const char *fn(int code)                                                     \
    {                                                                            \
        switch (code) {                                                          \
            TABLE(VP_ERR_MSG_ROW_)                                               \
        }                                                                        \
        return "unknown error";                                                  \
    }

#endif
