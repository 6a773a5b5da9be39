/* Reading scene JSON: the helpers every parser of the scene format uses
 * (numbers, vectors, particle references, keyframes), each failing with
 * "PATH: problem (got VALUE)". */
#include "io/io.h"

#include <cjson/cJSON.h>
#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

psys_system *psys__parse_system(psys__parse *p) { return p->sys; }

/* A short printed form of item for "(got ...)". */
static void describe(const cJSON *item, char *out, size_t cap)
{
    if (cJSON_IsNumber(item) && !isfinite(item->valuedouble)) {
        /* cJSON would print a number that overflowed (1e999) as null. */
        snprintf(out, cap, "%s", isnan(item->valuedouble) ? "nan" : item->valuedouble > 0 ? "inf" : "-inf");
        return;
    }
    char *txt = item ? cJSON_PrintUnformatted(item) : NULL;
    if (!txt) {
        snprintf(out, cap, "%s", item ? "?" : "");
        return;
    }
    size_t len = strlen(txt);
    if (len > 60)
        snprintf(out, cap, "%.57s...", txt);
    else
        snprintf(out, cap, "%s", txt);
    free(txt);
}

psys_status psys__parse_fail(psys__parse *p, const char *path, const cJSON *item, const char *fmt, ...)
{
    char what[384], got[96];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(what, sizeof what, fmt, ap);
    va_end(ap);
    /* Builders' and the system's allocation failures come through here as
     * their messages ("out of memory ..."): keep them PSYS_ERR_NOMEM. */
    psys_status code = strncmp(what, "out of memory", 13) == 0 ? PSYS_ERR_NOMEM : PSYS_ERR_INVALID;
    if (item) {
        describe(item, got, sizeof got);
        return psys__fail(p->err, code, "%s: %s (got %s)", path, what, got);
    }
    return psys__fail(p->err, code, "%s: %s", path, what);
}

/* out = path + "." + key (or key at the top level), truncated to cap. */
void psys__key_path(char *out, size_t cap, const char *path, const char *key)
{
    size_t n = 0;
    for (const char *c = path; *c && n + 1 < cap; c++)
        out[n++] = *c;
    if (path[0] && n + 1 < cap)
        out[n++] = '.';
    for (const char *c = key; *c && n + 1 < cap; c++)
        out[n++] = *c;
    out[n] = '\0';
}

psys_status psys__parse_keys(psys__parse *p, const cJSON *obj, const char *path, const char *const *allowed)
{
    char kp[256];
    for (const cJSON *it = obj->child; it; it = it->next) {
        bool ok = false;
        for (const char *const *a = allowed; *a; a++)
            if (strcmp(*a, it->string) == 0)
                ok = true;
        psys__key_path(kp, sizeof kp, path, it->string);
        if (!ok)
            return psys__parse_fail(p, kp, NULL, "unknown key");
        for (const cJSON *jt = obj->child; jt != it; jt = jt->next)
            if (strcmp(jt->string, it->string) == 0)
                return psys__parse_fail(p, kp, NULL, "duplicate key");
    }
    return PSYS_OK;
}

psys_status psys__parse_number(psys__parse *p, const cJSON *obj, const char *path, const char *key,
                               bool has_def, double def, double min, bool min_exclusive, double *out)
{
    char kp[256];
    psys__key_path(kp, sizeof kp, path, key);
    const cJSON *it = cJSON_GetObjectItemCaseSensitive(obj, key);
    if (!it) {
        if (!has_def)
            return psys__parse_fail(p, kp, NULL, "required key missing");
        *out = def;
        return PSYS_OK;
    }
    if (!cJSON_IsNumber(it))
        return psys__parse_fail(p, kp, it, "must be a number");
    double v = it->valuedouble;
    if (!isfinite(v))
        return psys__parse_fail(p, kp, it, "must be finite");
    if (min_exclusive ? !(v > min) : !(v >= min))
        return psys__parse_fail(p, kp, it, "must be %s %g", min_exclusive ? ">" : ">=", min);
    *out = v;
    return PSYS_OK;
}

/* cJSON parses numbers as doubles; an integer must be exact and in range. */
psys_status psys__parse_integer(psys__parse *p, const cJSON *obj, const char *path, const char *key,
                                long long min, long long *out, bool *present)
{
    char kp[256];
    psys__key_path(kp, sizeof kp, path, key);
    const cJSON *it = cJSON_GetObjectItemCaseSensitive(obj, key);
    if (present)
        *present = it != NULL;
    if (!it)
        return PSYS_OK;
    if (!cJSON_IsNumber(it) || !isfinite(it->valuedouble) || it->valuedouble != floor(it->valuedouble))
        return psys__parse_fail(p, kp, it, "must be an integer");
    if (it->valuedouble < (double)min || it->valuedouble > 1e15)
        return psys__parse_fail(p, kp, it, "must be an integer from %lld to 1e15", min);
    *out = (long long)it->valuedouble;
    return PSYS_OK;
}

psys_status psys__parse_vec(psys__parse *p, const cJSON *obj, const char *path, const char *key,
                            const double *def, double *out)
{
    char kp[256];
    int d = p->sys->dim;
    psys__key_path(kp, sizeof kp, path, key);
    const cJSON *it = cJSON_GetObjectItemCaseSensitive(obj, key);
    if (!it) {
        if (!def)
            return psys__parse_fail(p, kp, NULL, "required key missing");
        for (int k = 0; k < d; k++)
            out[k] = def[k];
        return PSYS_OK;
    }
    return psys__parse_vec_item(p, it, kp, d, out);
}

psys_status psys__parse_vec_item(psys__parse *p, const cJSON *it, const char *kp, int dim, double *out)
{
    if (!cJSON_IsArray(it) || cJSON_GetArraySize(it) != dim)
        return psys__parse_fail(p, kp, it, "must be an array of %d numbers (dim is %d)", dim, dim);
    int k = 0;
    for (const cJSON *c = it->child; c; c = c->next, k++) {
        if (!cJSON_IsNumber(c) || !isfinite(c->valuedouble)) {
            char ep[400];
            snprintf(ep, sizeof ep, "%s[%d]", kp, k);
            return psys__parse_fail(p, ep, c, "must be a finite number");
        }
        out[k] = c->valuedouble;
    }
    return PSYS_OK;
}

psys_status psys__parse_ref(psys__parse *p, const cJSON *obj, const char *path, const char *key, size_t *out)
{
    char kp[256];
    psys__key_path(kp, sizeof kp, path, key);
    const cJSON *it = cJSON_GetObjectItemCaseSensitive(obj, key);
    if (!it)
        return psys__parse_fail(p, kp, NULL, "required key missing");
    return psys__parse_ref_item(p, it, kp, out);
}

psys_status psys__parse_ref_item(psys__parse *p, const cJSON *it, const char *path, size_t *out)
{
    if (cJSON_IsString(it)) {
        if (psys_system_find(p->sys, it->valuestring, out) != PSYS_OK)
            return psys__parse_fail(p, path, it, "unknown particle id");
        return PSYS_OK;
    }
    if (cJSON_IsNumber(it)) {
        double v = it->valuedouble;
        if (v != floor(v) || v < 0 || v >= (double)p->sys->n) {
            if (p->sys->n == 0)
                return psys__parse_fail(p, path, it, "particle index out of range (there are no particles)");
            return psys__parse_fail(p, path, it, "particle index out of range (particles are numbered 0 to %zu)",
                                    p->sys->n - 1);
        }
        *out = (size_t)v;
        return PSYS_OK;
    }
    return psys__parse_fail(p, path, it, "must be a particle id (string) or index (integer)");
}

psys_status psys__parse_bool(psys__parse *p, const cJSON *obj, const char *path, const char *key, bool *out)
{
    char kp[256];
    psys__key_path(kp, sizeof kp, path, key);
    const cJSON *it = cJSON_GetObjectItemCaseSensitive(obj, key);
    if (!it)
        return PSYS_OK;
    if (!cJSON_IsBool(it))
        return psys__parse_fail(p, kp, it, "must be true or false");
    *out = cJSON_IsTrue(it);
    return PSYS_OK;
}

psys_status psys__parse_string(psys__parse *p, const cJSON *obj, const char *path, const char *key,
                               char *out, size_t cap)
{
    char kp[256];
    psys__key_path(kp, sizeof kp, path, key);
    const cJSON *it = cJSON_GetObjectItemCaseSensitive(obj, key);
    if (!it)
        return PSYS_OK;
    if (!cJSON_IsString(it))
        return psys__parse_fail(p, kp, it, "must be a string");
    if (strlen(it->valuestring) >= cap)
        return psys__parse_fail(p, kp, it, "is too long (at most %zu characters)", cap - 1);
    if (it->valuestring[0] == '\0')
        return psys__parse_fail(p, kp, it, "must not be empty");
    memcpy(out, it->valuestring, strlen(it->valuestring) + 1);
    return PSYS_OK;
}

psys_status psys__parse_frames(psys__parse *p, const cJSON *item, const char *path, double **frames,
                               size_t *count)
{
    int d = p->sys->dim;
    size_t stride = 1 + (size_t)d;
    *frames = NULL;
    *count = 0;
    if (!item)
        return psys__parse_fail(p, path, NULL, "required key missing");
    if (!cJSON_IsArray(item) || cJSON_GetArraySize(item) < 1)
        return psys__parse_fail(p, path, item, "must be a non-empty array of frames [t, x...]");
    size_t n = (size_t)cJSON_GetArraySize(item);
    double *f = psys__calloc(n * stride, sizeof(double));
    if (!f)
        return psys__fail(p->err, PSYS_ERR_NOMEM, "%s: out of memory", path);
    size_t k = 0;
    char ep[300];
    for (const cJSON *fr = item->child; fr; fr = fr->next, k++) {
        snprintf(ep, sizeof ep, "%s[%zu]", path, k);
        if (!cJSON_IsArray(fr) || cJSON_GetArraySize(fr) != (int)stride) {
            free(f);
            return psys__parse_fail(p, ep, fr, "must be [t, %s] (%zu numbers)", d == 2 ? "x, y" : "x, y, z", stride);
        }
        size_t c = 0;
        for (const cJSON *num = fr->child; num; num = num->next, c++) {
            if (!cJSON_IsNumber(num) || !isfinite(num->valuedouble)) {
                free(f);
                return psys__parse_fail(p, ep, fr, "must contain finite numbers");
            }
            f[k * stride + c] = num->valuedouble;
        }
        if (k > 0 && !(f[k * stride] > f[(k - 1) * stride])) {
            free(f);
            return psys__parse_fail(p, ep, fr, "frame times must increase strictly");
        }
    }
    *frames = f;
    *count = n;
    return PSYS_OK;
}

