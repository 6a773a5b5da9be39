/* Error reporting and allocation helpers. */
#include "base/base.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

const char *psys_status_name(psys_status s)
{
    switch (s) {
    case PSYS_OK: return "ok";
    case PSYS_ERR_INVALID: return "invalid";
    case PSYS_ERR_NOMEM: return "out of memory";
    case PSYS_ERR_IO: return "i/o error";
    case PSYS_ERR_NONFINITE: return "non-finite state";
    case PSYS_ERR_UNSUPPORTED: return "unsupported";
    }
    return "unknown";
}

psys_status psys__vfail(psys_error *err, psys_status code, const char *fmt, va_list ap)
{
    if (err) {
        err->code = code;
        vsnprintf(err->message, sizeof err->message, fmt, ap);
        /* One line, whatever a scene's keys or ids hold ("a\nb" as a key). */
        for (char *c = err->message; *c; c++)
            if ((unsigned char)*c < 0x20 || *c == 0x7f)
                *c = '?';
    }
    return code;
}

psys_status psys__fail(psys_error *err, psys_status code, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    psys__vfail(err, code, fmt, ap);
    va_end(ap);
    return code;
}

void psys__ok(psys_error *err)
{
    if (err) {
        err->code = PSYS_OK;
        err->message[0] = '\0';
    }
}

void *psys__calloc(size_t n, size_t size)
{
    if (n == 0 || size == 0)
        n = size = 1;
    if (n > SIZE_MAX / size)
        return NULL;
    return calloc(n, size);
}

void *psys__calloc_lines(size_t n, size_t size)
{
    if (n == 0 || size == 0)
        n = size = 1;
    if (n > (SIZE_MAX - 63) / size)
        return NULL;
    const size_t bytes = n * size;
    void *p = aligned_alloc(64, (bytes + 63) / 64 * 64);
    if (p)
        memset(p, 0, bytes);
    return p;
}

void *psys__realloc(void *p, size_t n, size_t size)
{
    if (n == 0 || size == 0)
        n = size = 1;
    if (n > SIZE_MAX / size)
        return NULL;
    return realloc(p, n * size);
}

void *psys__grow(void *p, size_t *cap, size_t want, size_t size)
{
    if (want <= *cap && p)
        return p;
    size_t c = *cap ? *cap : 64;
    while (c < want) {
        if (c > SIZE_MAX / 2)
            return NULL;
        c *= 2;
    }
    void *q = psys__realloc(p, c, size);
    if (q)
        *cap = c;
    return q;
}

char *psys__strdup(const char *s)
{
    size_t len = strlen(s) + 1;
    char *d = malloc(len);
    if (d)
        memcpy(d, s, len);
    return d;
}
