/* Scene form of drag: {"type": "drag", "kd": number >= 0}. */
#include "io/io.h"

#include <cjson/cJSON.h>

static psys_status drag_parse(psys__parse *p, const cJSON *obj, const char *path)
{
    static const char *const keys[] = {"type", "kd", NULL};
    psys_system *sys = psys__parse_system(p);
    double kd;
    psys_status st = psys__parse_keys(p, obj, path, keys);
    if (st == PSYS_OK)
        st = psys__parse_number(p, obj, path, "kd", false, 0, 0, false, &kd);
    if (st == PSYS_OK && psys_system_add_drag(sys, kd) != PSYS_OK)
        st = psys__parse_fail(p, path, NULL, "%s", psys_system_last_error(sys));
    return st;
}

static psys_status drag_save(const psys_system *sys, const void *data, cJSON *arr)
{
    (void)sys;
    cJSON *o = cJSON_CreateObject();
    if (!o || !cJSON_AddStringToObject(o, "type", "drag")
        || !psys__add_num(o, "kd", psys__drag_kd(data))) {
        cJSON_Delete(o);
        return PSYS_ERR_NOMEM;
    }
    cJSON_AddItemToArray(arr, o);
    return PSYS_OK;
}

const psys__force_io psys__drag_io = {.type = "drag", .cls = &psys_drag_class, .parse = drag_parse, .save = drag_save};
