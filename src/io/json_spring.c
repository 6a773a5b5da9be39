/* Scene form of springs: {"type": "spring", "a": ref, "b": ref, "ks", "kd",
 * "rest", "muscle": {...}}, one object per spring of the system's set; and
 * the "muscle" object shared with chains (io/json_structures.c). */
#include "io/io.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>

psys_status psys__parse_muscle(psys__parse *p, const cJSON *obj, const char *path, bool with_step,
                               bool *present, double out[4])
{
    static const char *const keys[] = {"amplitude", "omega", "phase", NULL};
    static const char *const step_keys[] = {"amplitude", "omega", "phase", "phase_step", NULL};
    char mp[256];
    const cJSON *m = cJSON_GetObjectItemCaseSensitive(obj, "muscle");
    snprintf(mp, sizeof mp, "%s.muscle", path);
    *present = m != NULL;
    out[0] = out[1] = out[2] = out[3] = 0;
    if (!m)
        return PSYS_OK;
    if (!cJSON_IsObject(m))
        return psys__parse_fail(p, mp, m, "must be an object {\"amplitude\", \"omega\", \"phase\"%s}",
                                with_step ? ", \"phase_step\"" : "");
    psys_status st = psys__parse_keys(p, m, mp, with_step ? step_keys : keys);
    if (st == PSYS_OK) st = psys__parse_number(p, m, mp, "amplitude", false, 0, 0, false, &out[0]);
    if (st == PSYS_OK && out[0] > 1) {
        char ap[280];
        snprintf(ap, sizeof ap, "%s.amplitude", mp);
        st = psys__parse_fail(p, ap, cJSON_GetObjectItemCaseSensitive(m, "amplitude"), "must be from 0 to 1");
    }
    if (st == PSYS_OK) st = psys__parse_number(p, m, mp, "omega", false, 0, -INFINITY, false, &out[1]);
    if (st == PSYS_OK) st = psys__parse_number(p, m, mp, "phase", true, 0, -INFINITY, false, &out[2]);
    if (st == PSYS_OK && with_step)
        st = psys__parse_number(p, m, mp, "phase_step", true, 0, -INFINITY, false, &out[3]);
    return st;
}

static psys_status spring_parse(psys__parse *p, const cJSON *obj, const char *path)
{
    static const char *const keys[] = {"type", "a", "b", "ks", "kd", "rest", "muscle", NULL};
    psys_system *sys = psys__parse_system(p);
    size_t a, b;
    double ks, kd, rest, muscle[4];
    bool has_muscle = false;
    psys_status st = psys__parse_keys(p, obj, path, keys);
    if (st == PSYS_OK) st = psys__parse_ref(p, obj, path, "a", &a);
    if (st == PSYS_OK) st = psys__parse_ref(p, obj, path, "b", &b);
    if (st == PSYS_OK) st = psys__parse_number(p, obj, path, "ks", false, 0, 0, false, &ks);
    if (st == PSYS_OK) st = psys__parse_number(p, obj, path, "kd", true, 0, 0, false, &kd);
    if (st == PSYS_OK) st = psys__parse_number(p, obj, path, "rest", true, -1, 0, false, &rest);
    if (st == PSYS_OK) st = psys__parse_muscle(p, obj, path, false, &has_muscle, muscle);
    if (st == PSYS_OK && a == b) {
        char bpath[256];
        snprintf(bpath, sizeof bpath, "%s.b", path);
        st = psys__parse_fail(p, bpath, cJSON_GetObjectItemCaseSensitive(obj, "b"),
                              "a spring needs two different particles");
    }
    if (st == PSYS_OK && psys_system_add_spring(sys, a, b, ks, kd, rest) != PSYS_OK)
        st = psys__parse_fail(p, path, NULL, "%s", psys_system_last_error(sys));
    if (st == PSYS_OK && has_muscle
        && psys_system_set_spring_muscle(sys, psys_system_spring_count(sys) - 1, muscle[0], muscle[1], muscle[2])
               != PSYS_OK)
        st = psys__parse_fail(p, path, NULL, "%s", psys_system_last_error(sys));
    return st;
}

static psys_status spring_save(const psys_system *sys, const void *data, cJSON *arr)
{
    size_t n = psys__springs_count(data);
    for (size_t k = 0; k < n; k++) {
        size_t a, b;
        double ks, kd, rest, amp, omega, phase;
        psys__springs_get(data, k, &a, &b, &ks, &kd, &rest);
        cJSON *o = cJSON_CreateObject();
        if (!o || !cJSON_AddStringToObject(o, "type", "spring")
            || !cJSON_AddItemToObjectCS(o, "a", psys__ref_json(sys, a))
            || !cJSON_AddItemToObjectCS(o, "b", psys__ref_json(sys, b))
            || !psys__add_num(o, "ks", ks) || !psys__add_num(o, "kd", kd)
            || !psys__add_num(o, "rest", rest)) {
            cJSON_Delete(o);
            return PSYS_ERR_NOMEM;
        }
        if (psys__springs_muscle(data, k, &amp, &omega, &phase)) {
            cJSON *mo = cJSON_AddObjectToObject(o, "muscle");
            if (!mo || !psys__add_num(mo, "amplitude", amp) || !psys__add_num(mo, "omega", omega)
                || !psys__add_num(mo, "phase", phase)) {
                cJSON_Delete(o);
                return PSYS_ERR_NOMEM;
            }
        }
        cJSON_AddItemToArray(arr, o);
    }
    return PSYS_OK;
}

const psys__force_io psys__spring_io = {.type = "spring", .cls = &psys_spring_class, .parse = spring_parse, .save = spring_save};
