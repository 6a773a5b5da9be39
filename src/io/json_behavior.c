/* Scene form of the built-in behaviours; user-defined ones (their own
 * class) have none. */
#include "io/io.h"

#include <cjson/cJSON.h>
#include <stdio.h>
#include <string.h>

static const double PI = 3.14159265358979323846;

static double dot(const double *a, const double *b, int d)
{
    double s = 0;
    for (int k = 0; k < d; k++)
        s += a[k] * b[k];
    return s;
}

/* ---- scene form: {"type": "behavior", "function": NAME, "particles": [...], params, "ks", "kd"} ---- */

static psys_status behavior_parse(psys__parse *p, const cJSON *obj, const char *path)
{
    psys_system *sys = psys__parse_system(p);
    int d = sys->dim;
    char kp[256];
    snprintf(kp, sizeof kp, "%s.function", path);
    const cJSON *fn = cJSON_GetObjectItemCaseSensitive(obj, "function");
    if (!fn)
        return psys__parse_fail(p, kp, NULL, "required key missing");
    if (!cJSON_IsString(fn))
        return psys__parse_fail(p, kp, fn, "must be a string");
    psys_behavior_def def = psys_behavior_def_default();
    int nparticles = 0;
    const char *const *bkeys = NULL;
    bool found = false;
    if (psys_behavior_function_from_name(fn->valuestring, &def.function) == PSYS_OK) {
        psys_behavior_function f;
        for (size_t i = 0; !found && psys__behavior_builtin(i, &f, NULL, &nparticles, &bkeys); i++)
            found = f == def.function;
    }
    if (!found) {
        char known[160] = "";
        const char *name;
        for (size_t i = 0; psys__behavior_builtin(i, NULL, &name, NULL, NULL); i++)
            snprintf(known + strlen(known), sizeof known - strlen(known), "%s%s", i ? ", " : "", name);
        return psys__parse_fail(p, kp, fn, "unknown function (known: %s)", known);
    }

    const char *keys[10] = {"type", "function", "particles", "ks", "kd"};
    for (int i = 0, n = 5; bkeys[i]; i++)
        keys[n++] = bkeys[i];
    psys_status st = psys__parse_keys(p, obj, path, keys);
    if (st != PSYS_OK)
        return st;

    snprintf(kp, sizeof kp, "%s.particles", path);
    const cJSON *arr = cJSON_GetObjectItemCaseSensitive(obj, "particles");
    if (!arr)
        return psys__parse_fail(p, kp, NULL, "required key missing");
    if (!cJSON_IsArray(arr) || cJSON_GetArraySize(arr) != nparticles)
        return psys__parse_fail(p, kp, arr, "must list exactly %d particle%s", nparticles,
                                nparticles == 1 ? "" : "s");
    def.nparticles = nparticles;
    int i = 0;
    for (const cJSON *it = arr->child; it; it = it->next, i++) {
        char ep[280];
        snprintf(ep, sizeof ep, "%s[%d]", kp, i);
        if ((st = psys__parse_ref_item(p, it, ep, &def.particles[i])) != PSYS_OK)
            return st;
        for (int j = 0; j < i; j++)
            if (def.particles[j] == def.particles[i])
                return psys__parse_fail(p, ep, it, "the same particle is listed twice");
    }

    if ((st = psys__parse_number(p, obj, path, "ks", false, 0, 0, false, &def.ks)) != PSYS_OK
        || (st = psys__parse_number(p, obj, path, "kd", true, 0, 0, false, &def.kd)) != PSYS_OK)
        return st;
    switch (def.function) {
    case PSYS_BEHAVIOR_DISTANCE:
        st = psys__parse_number(p, obj, path, "r", true, -1, 0, false, &def.r);
        break;
    case PSYS_BEHAVIOR_POINT_ON_PLANE:
        if ((st = psys__parse_vec(p, obj, path, "point", NULL, def.point)) == PSYS_OK
            && (st = psys__parse_vec(p, obj, path, "normal", NULL, def.normal)) == PSYS_OK
            && !(dot(def.normal, def.normal, d) > 0)) {
            snprintf(kp, sizeof kp, "%s.normal", path);
            st = psys__parse_fail(p, kp, cJSON_GetObjectItemCaseSensitive(obj, "normal"), "must not be zero");
        }
        break;
    case PSYS_BEHAVIOR_POINT_ON_SPHERE:
        if ((st = psys__parse_vec(p, obj, path, "center", NULL, def.center)) == PSYS_OK)
            st = psys__parse_number(p, obj, path, "radius", false, 0, 0, false, &def.radius);
        break;
    case PSYS_BEHAVIOR_ANGLE:
        st = psys__parse_number(p, obj, path, "angle", true, -1, 0, false, &def.angle);
        if (st == PSYS_OK && def.angle > PI) {
            snprintf(kp, sizeof kp, "%s.angle", path);
            st = psys__parse_fail(p, kp, cJSON_GetObjectItemCaseSensitive(obj, "angle"),
                                  "must be at most pi (radians)");
        }
        break;
    default:
        break;
    }
    if (st == PSYS_OK && psys_system_add_behavior(sys, &def) != PSYS_OK)
        st = psys__parse_fail(p, path, NULL, "%s", psys_system_last_error(sys));
    return st;
}

static psys_status behavior_save(const psys_system *sys, const void *data, cJSON *arr)
{
    const psys_behavior_def *def = psys__behavior_def(data);
    int d = sys->dim;
    cJSON *o = cJSON_CreateObject(), *refs = NULL;
    bool ok = o && cJSON_AddStringToObject(o, "type", "behavior")
              && cJSON_AddStringToObject(o, "function", psys_behavior_function_name(def->function))
              && (refs = cJSON_AddArrayToObject(o, "particles"));
    for (int i = 0; ok && i < psys__behavior_count(data); i++) {
        cJSON *r = psys__ref_json(sys, def->particles[i]);
        ok = r && cJSON_AddItemToArray(refs, r);
    }
    switch (def->function) {
    case PSYS_BEHAVIOR_DISTANCE:
        ok = ok && psys__add_num(o, "r", def->r);
        break;
    case PSYS_BEHAVIOR_POINT_ON_PLANE:
        ok = ok && cJSON_AddItemToObjectCS(o, "point", psys__vec_json(def->point, d))
             && cJSON_AddItemToObjectCS(o, "normal", psys__vec_json(def->normal, d));
        break;
    case PSYS_BEHAVIOR_POINT_ON_SPHERE:
        ok = ok && cJSON_AddItemToObjectCS(o, "center", psys__vec_json(def->center, d))
             && psys__add_num(o, "radius", def->radius);
        break;
    case PSYS_BEHAVIOR_ANGLE:
        ok = ok && psys__add_num(o, "angle", def->angle);
        break;
    default:
        break;
    }
    ok = ok && psys__add_num(o, "ks", def->ks) && psys__add_num(o, "kd", def->kd);
    if (!ok) {
        cJSON_Delete(o);
        return PSYS_ERR_NOMEM;
    }
    cJSON_AddItemToArray(arr, o);
    return PSYS_OK;
}

/* User-defined behaviours have their own class and no scene form: saving a
 * system with one fails with PSYS_ERR_UNSUPPORTED (io/scene_save.c). */
const psys__force_io psys__behavior_io = {.type = "behavior", .cls = &psys_behavior_class, .parse = behavior_parse, .save = behavior_save};
