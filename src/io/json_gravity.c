/* Scene form of gravity: {"type": "gravity", "g": [..]} (g defaults to -9.81 along y). */
#include "io/io.h"

#include <cjson/cJSON.h>

static psys_status gravity_parse(psys__parse *p, const cJSON *obj, const char *path)
{
    static const char *const keys[] = {"type", "g", NULL};
    psys_system *sys = psys__parse_system(p);
    double def[3] = {0, -9.81, 0}, g[3];
    psys_status st = psys__parse_keys(p, obj, path, keys);
    if (st == PSYS_OK)
        st = psys__parse_vec(p, obj, path, "g", def, g);
    if (st == PSYS_OK && psys_system_add_gravity(sys, g) != PSYS_OK)
        st = psys__parse_fail(p, path, NULL, "%s", psys_system_last_error(sys));
    return st;
}

static psys_status gravity_save(const psys_system *sys, const void *data, cJSON *arr)
{
    cJSON *o = cJSON_CreateObject();
    if (!o || !cJSON_AddStringToObject(o, "type", "gravity")
        || !cJSON_AddItemToObjectCS(o, "g", psys__vec_json(psys__gravity_g(data), sys->dim))) {
        cJSON_Delete(o);
        return PSYS_ERR_NOMEM;
    }
    cJSON_AddItemToArray(arr, o);
    return PSYS_OK;
}

const psys__force_io psys__gravity_io = {.type = "gravity", .cls = &psys_gravity_class, .parse = gravity_parse, .save = gravity_save};
