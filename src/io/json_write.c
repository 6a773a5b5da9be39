/* Writing scene JSON: numbers that read back exactly, vectors, particle
 * references and keyframes, for the saver of every scene type. */
#include "io/io.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Items go in with cJSON_AddItemToObjectCS (literal keys, not copied): the
 * copying cJSON_AddItemToObject fails when the key's copy cannot be
 * allocated and then leaks the item (tests/test_alloc.c). */

/* cJSON prints numbers with a relative tolerance and may drop the last bit;
 * write the shortest text that reads back as exactly the same double. */
cJSON *psys__num_json(double x)
{
    char buf[40];
    for (int prec = 15; prec <= 17; prec++) {
        snprintf(buf, sizeof buf, "%.*g", prec, x);
        if (strtod(buf, NULL) == x)
            break;
    }
    return cJSON_CreateRaw(buf);
}

cJSON *psys__add_num(cJSON *obj, const char *key, double x)
{
    cJSON *n = psys__num_json(x);
    if (n && !cJSON_AddItemToObject(obj, key, n)) {
        cJSON_Delete(n);
        return NULL;
    }
    return n;
}

cJSON *psys__vec_json(const double *v, int dim)
{
    cJSON *arr = cJSON_CreateArray();
    for (int k = 0; arr && k < dim; k++) {
        cJSON *n = psys__num_json(v[k]);
        if (!n) {
            cJSON_Delete(arr);
            return NULL;
        }
        cJSON_AddItemToArray(arr, n);
    }
    return arr;
}

cJSON *psys__ref_json(const psys_system *sys, size_t i)
{
    const char *id = psys_system_particle_id(sys, i);
    return id ? cJSON_CreateString(id) : cJSON_CreateNumber((double)i);
}

cJSON *psys__frames_json(const double *frames, size_t count, int dim)
{
    cJSON *arr = cJSON_CreateArray();
    for (size_t k = 0; arr && k < count; k++) {
        cJSON *fr = psys__vec_json(frames + k * (1 + (size_t)dim), 1 + dim);
        if (!fr) {
            cJSON_Delete(arr);
            return NULL;
        }
        cJSON_AddItemToArray(arr, fr);
    }
    return arr;
}

