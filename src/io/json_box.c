/* Scene form of the simulation box. */
#include "io/io.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>

/* ---- scene form: "box": {"lo": [..], "hi": [..], "periodic": [bool × dim]} ---- */

psys_status psys__parse_box(psys__parse *p, const cJSON *root)
{
    static const char *const keys[] = {"lo", "hi", "periodic", NULL};
    psys_system *sys = psys__parse_system(p);
    const cJSON *box = cJSON_GetObjectItemCaseSensitive(root, "box");
    if (!box)
        return PSYS_OK;
    if (!cJSON_IsObject(box))
        return psys__parse_fail(p, "box", box, "must be an object {\"lo\", \"hi\", \"periodic\"}");
    int d = sys->dim;
    double lo[3], hi[3];
    bool periodic[3] = {true, true, true};
    psys_status st;
    if ((st = psys__parse_keys(p, box, "box", keys)) != PSYS_OK
        || (st = psys__parse_vec(p, box, "box", "lo", NULL, lo)) != PSYS_OK
        || (st = psys__parse_vec(p, box, "box", "hi", NULL, hi)) != PSYS_OK)
        return st;
    for (int k = 0; k < d; k++)
        if (!(hi[k] > lo[k]) || !isfinite(hi[k] - lo[k])) {
            char kp[64];
            snprintf(kp, sizeof kp, "box.hi[%d]", k);
            const cJSON *h = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(box, "hi"), k);
            return psys__parse_fail(p, kp, h, "must be greater than box.lo[%d] (%.17g)", k, lo[k]);
        }
    const cJSON *per = cJSON_GetObjectItemCaseSensitive(box, "periodic");
    if (per) {
        if (!cJSON_IsArray(per) || cJSON_GetArraySize(per) != d)
            return psys__parse_fail(p, "box.periodic", per, "must be an array of %d true/false values (dim is %d)",
                                    d, d);
        int k = 0;
        for (const cJSON *it = per->child; it; it = it->next, k++) {
            if (!cJSON_IsBool(it)) {
                char kp[64];
                snprintf(kp, sizeof kp, "box.periodic[%d]", k);
                return psys__parse_fail(p, kp, it, "must be true or false");
            }
            periodic[k] = cJSON_IsTrue(it);
        }
    }
    if (psys_system_set_box(sys, lo, hi, periodic) != PSYS_OK)
        return psys__parse_fail(p, "box", NULL, "%s", psys_system_last_error(sys));
    return PSYS_OK;
}

bool psys__save_box(const psys_system *sys, cJSON *root)
{
    if (!sys->box.on)
        return true;
    int d = sys->dim;
    cJSON *o = cJSON_AddObjectToObject(root, "box");
    if (!o || !cJSON_AddItemToObjectCS(o, "lo", psys__vec_json(sys->box.lo, d))
        || !cJSON_AddItemToObjectCS(o, "hi", psys__vec_json(sys->box.hi, d)))
        return false;
    cJSON *per = cJSON_AddArrayToObject(o, "periodic");
    if (!per)
        return false;
    for (int k = 0; k < d; k++) {
        cJSON *b = cJSON_CreateBool(sys->box.periodic[k]);
        if (!b || !cJSON_AddItemToArray(per, b)) {
            cJSON_Delete(b);
            return false;
        }
    }
    return true;
}
