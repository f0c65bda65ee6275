/*
 * vt_err.c — see vt_err.h: the messages of render/'s error table and the
 * one place an errno becomes one of its codes.
 */
#include "vt_err.h"

#include <errno.h>

VP_ERR_DEFINE_STRERROR(vt_strerror, VT_ERRORS)

int vt_err_from_errno(int e)
{
    switch (e) {
    case ENOMEM: return VT_ERR_NOMEM;
    case ENOENT: return VT_ERR_NOT_FOUND;
    default:     return VT_ERR_FILE;
    }
}
