/* Scene form of mouse springs (a keyframed target path, or a fixed target). */
#include "io/io.h"

#include <cjson/cJSON.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Scene form: {"type": "mouse-spring", "particle": ref, "ks", "kd", "target": [..] | "path": [[t, x...], ...]} */
static psys_status mouse_parse(psys__parse *p, const cJSON *obj, const char *path)
{
    static const char *const keys[] = {"type", "particle", "ks", "kd", "target", "path", NULL};
    psys_system *sys = psys__parse_system(p);
    int d = sys->dim;
    size_t i, handle;
    double ks, kd, target[3] = {0, 0, 0};
    psys_status st = psys__parse_keys(p, obj, path, keys);
    if (st == PSYS_OK) st = psys__parse_ref(p, obj, path, "particle", &i);
    if (st == PSYS_OK) st = psys__parse_number(p, obj, path, "ks", false, 0, 0, false, &ks);
    if (st == PSYS_OK) st = psys__parse_number(p, obj, path, "kd", true, 0, 0, false, &kd);
    if (st != PSYS_OK)
        return st;
    const cJSON *tg = cJSON_GetObjectItemCaseSensitive(obj, "target");
    const cJSON *pa = cJSON_GetObjectItemCaseSensitive(obj, "path");
    char kp[256];
    if (!!tg == !!pa) {
        snprintf(kp, sizeof kp, "%s", path);
        return psys__parse_fail(p, kp, NULL, "give exactly one of target or path");
    }
    double *frames = NULL;
    size_t count = 0;
    if (tg) {
        if ((st = psys__parse_vec(p, obj, path, "target", NULL, target)) != PSYS_OK)
            return st;
    } else {
        snprintf(kp, sizeof kp, "%s.path", path);
        if ((st = psys__parse_frames(p, pa, kp, &frames, &count)) != PSYS_OK)
            return st;
        memcpy(target, frames + 1, sizeof(double) * (size_t)d);
    }
    if (psys_system_add_mouse_spring(sys, i, target, ks, kd, &handle) != PSYS_OK
        || (frames && psys_system_mouse_set_path(sys, handle, frames, count) != PSYS_OK)) {
        free(frames);
        return psys__parse_fail(p, path, NULL, "%s", psys_system_last_error(sys));
    }
    free(frames);
    return PSYS_OK;
}

static psys_status mouse_save(const psys_system *sys, const void *data, cJSON *arr)
{
    size_t particle, nframes;
    double ks, kd;
    const double *target, *frames;
    psys__mouse_get(data, &particle, &ks, &kd, &target, &frames, &nframes);
    int d = sys->dim;
    cJSON *o = cJSON_CreateObject();
    bool ok = o && cJSON_AddStringToObject(o, "type", "mouse-spring")
              && cJSON_AddItemToObjectCS(o, "particle", psys__ref_json(sys, particle))
              && psys__add_num(o, "ks", ks) && psys__add_num(o, "kd", kd);
    if (ok && nframes)
        ok = cJSON_AddItemToObjectCS(o, "path", psys__frames_json(frames, nframes, d));
    else if (ok)
        ok = cJSON_AddItemToObjectCS(o, "target", psys__vec_json(target, d));
    if (!ok) {
        cJSON_Delete(o);
        return PSYS_ERR_NOMEM;
    }
    cJSON_AddItemToArray(arr, o);
    return PSYS_OK;
}

const psys__force_io psys__mouse_io = {.type = "mouse-spring", .cls = &psys_mouse_spring_class, .parse = mouse_parse, .save = mouse_save};
