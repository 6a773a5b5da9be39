/* Scene form of the built-in pair forces; user laws (their own class) have none. */
#include "io/io.h"

#include <cjson/cJSON.h>
#include <stdio.h>
#include <string.h>

/* The built-in laws, psys_pair_law 0..NLAWS-1. */
#define NLAWS 4

/* ---- scene form ----
 * {"type": "pair", "law": NAME, law parameters, "method": NAME, "skin" (grid), "theta" (barnes-hut)} */

/* Fail at PATH.key with the value found there. */
static psys_status fail_at(psys__parse *p, const cJSON *obj, const char *path, const char *key, const char *what)
{
    char kp[256];
    snprintf(kp, sizeof kp, "%s.%s", path, key);
    return psys__parse_fail(p, kp, cJSON_GetObjectItemCaseSensitive(obj, key), "%s", what);
}

static psys_status pair_parse(psys__parse *p, const cJSON *obj, const char *path)
{
    static const char *const law_keys[NLAWS][5] = {
        {"G", "softening", NULL},
        {"k", NULL},
        {"epsilon", "sigma", "cutoff", "shift", NULL},
        {"k", "radius", NULL},
    };
    psys_system *sys = psys__parse_system(p);
    char kp[256];
    psys_pair_def def = psys_pair_def_default();
    psys_status st;

    const cJSON *law = cJSON_GetObjectItemCaseSensitive(obj, "law");
    snprintf(kp, sizeof kp, "%s.law", path);
    if (!law)
        return psys__parse_fail(p, kp, NULL, "required key missing");
    if (!cJSON_IsString(law))
        return psys__parse_fail(p, kp, law, "must be a string");
    int li = -1;
    for (int k = 0; k < NLAWS; k++)
        if (strcmp(law->valuestring, psys_pair_law_name((psys_pair_law)k)) == 0)
            li = k;
    if (li < 0)
        return psys__parse_fail(p, kp, law, "unknown pair law (known: gravity, coulomb, lennard-jones, soft-repulsion)");
    def.law = (psys_pair_law)li;
    bool cut = def.law == PSYS_PAIR_LENNARD_JONES || def.law == PSYS_PAIR_SOFT_REPULSION;

    const cJSON *meth = cJSON_GetObjectItemCaseSensitive(obj, "method");
    if (meth) {
        snprintf(kp, sizeof kp, "%s.method", path);
        if (!cJSON_IsString(meth))
            return psys__parse_fail(p, kp, meth, "must be a string");
        if (strcmp(meth->valuestring, "direct") == 0)
            def.method = PSYS_PAIR_DIRECT;
        else if (strcmp(meth->valuestring, "grid") == 0)
            def.method = PSYS_PAIR_GRID;
        else if (strcmp(meth->valuestring, "barnes-hut") == 0)
            def.method = PSYS_PAIR_BARNES_HUT;
        else
            return psys__parse_fail(p, kp, meth, "unknown method (known: direct, grid, barnes-hut)");
        if (def.method == PSYS_PAIR_GRID && !cut)
            return psys__parse_fail(p, kp, meth, "grid needs a law with a cutoff (lennard-jones, soft-repulsion)");
        if (def.method == PSYS_PAIR_BARNES_HUT && cut)
            return psys__parse_fail(p, kp, meth, "barnes-hut is only for the long-range laws gravity and coulomb");
    } else {
        def.method = cut ? PSYS_PAIR_GRID : PSYS_PAIR_DIRECT;
    }
    if (def.method != PSYS_PAIR_GRID && cJSON_GetObjectItemCaseSensitive(obj, "skin"))
        return fail_at(p, obj, path, "skin", "only used by method \"grid\"");
    if (def.method != PSYS_PAIR_BARNES_HUT && cJSON_GetObjectItemCaseSensitive(obj, "theta"))
        return fail_at(p, obj, path, "theta", "only used by method \"barnes-hut\"");

    const char *keys[12] = {"type", "law", "method"};
    int nk = 3;
    for (int k = 0; law_keys[li][k]; k++)
        keys[nk++] = law_keys[li][k];
    keys[nk++] = def.method == PSYS_PAIR_GRID ? "skin" : "theta";
    keys[nk] = NULL;
    if ((st = psys__parse_keys(p, obj, path, keys)) != PSYS_OK)
        return st;

    switch (def.law) {
    case PSYS_PAIR_GRAVITY:
        if ((st = psys__parse_number(p, obj, path, "G", true, 1, 0, false, &def.G)) != PSYS_OK
            || (st = psys__parse_number(p, obj, path, "softening", true, 0, 0, false, &def.softening)) != PSYS_OK)
            return st;
        break;
    case PSYS_PAIR_COULOMB:
        if ((st = psys__parse_number(p, obj, path, "k", true, 1, 0, false, &def.k)) != PSYS_OK)
            return st;
        break;
    case PSYS_PAIR_LENNARD_JONES: {
        if ((st = psys__parse_number(p, obj, path, "epsilon", false, 0, 0, false, &def.epsilon)) != PSYS_OK
            || (st = psys__parse_number(p, obj, path, "sigma", false, 0, 0, true, &def.sigma)) != PSYS_OK
            || (st = psys__parse_number(p, obj, path, "cutoff", true, 2.5 * def.sigma, 0, true, &def.cutoff))
                   != PSYS_OK)
            return st;
        const cJSON *sh = cJSON_GetObjectItemCaseSensitive(obj, "shift");
        if (sh) {
            if (!cJSON_IsBool(sh))
                return fail_at(p, obj, path, "shift", "must be true or false");
            def.shift = cJSON_IsTrue(sh);
        }
        break;
    }
    default: /* soft-repulsion */
        if ((st = psys__parse_number(p, obj, path, "k", false, 0, 0, false, &def.k)) != PSYS_OK
            || (st = psys__parse_number(p, obj, path, "radius", false, 0, 0, true, &def.radius)) != PSYS_OK)
            return st;
        break;
    }
    if (def.method == PSYS_PAIR_GRID
        && (st = psys__parse_number(p, obj, path, "skin", true, -1, 0, false, &def.skin)) != PSYS_OK)
        return st;
    if (def.method == PSYS_PAIR_BARNES_HUT
        && (st = psys__parse_number(p, obj, path, "theta", true, 0.5, 0, false, &def.theta)) != PSYS_OK)
        return st;

    /* the periodic box (parsed before forces) */
    const psys__box *box = &sys->box;
    if (box->on && box->any_periodic) {
        if (!cut) {
            char what[160];
            snprintf(what, sizeof what, "%s has no cutoff, so it cannot be used with a periodic box (no Ewald sums)",
                     psys_pair_law_name(def.law));
            return fail_at(p, obj, path, "law", what);
        }
        double rc = def.law == PSYS_PAIR_SOFT_REPULSION ? def.radius : def.cutoff;
        const char *ck = def.law == PSYS_PAIR_SOFT_REPULSION ? "radius" : "cutoff";
        for (int k = 0; k < sys->dim; k++)
            if (box->periodic[k] && !(rc < 0.5 * box->len[k])) {
                char what[160];
                snprintf(what, sizeof what, "must be less than half the periodic box (box length %.17g on axis %d)",
                         box->len[k], k);
                return fail_at(p, obj, path, ck, what);
            }
    }
    if (psys_system_add_pair(sys, &def, NULL) != PSYS_OK)
        return psys__parse_fail(p, path, NULL, "%s", psys_system_last_error(sys));
    return PSYS_OK;
}

static psys_status pair_save(const psys_system *sys, const void *data, cJSON *arr)
{
    (void)sys;
    const psys_pair_def *d = psys__pair_def(data);
    cJSON *o = cJSON_CreateObject();
    bool ok = o && cJSON_AddStringToObject(o, "type", "pair")
              && cJSON_AddStringToObject(o, "law", psys_pair_law_name(d->law));
    switch (d->law) {
    case PSYS_PAIR_GRAVITY:
        ok = ok && psys__add_num(o, "G", d->G) && psys__add_num(o, "softening", d->softening);
        break;
    case PSYS_PAIR_COULOMB:
        ok = ok && psys__add_num(o, "k", d->k);
        break;
    case PSYS_PAIR_LENNARD_JONES:
        ok = ok && psys__add_num(o, "epsilon", d->epsilon) && psys__add_num(o, "sigma", d->sigma)
             && psys__add_num(o, "cutoff", d->cutoff) && cJSON_AddBoolToObject(o, "shift", d->shift);
        break;
    default:
        ok = ok && psys__add_num(o, "k", d->k) && psys__add_num(o, "radius", d->radius);
        break;
    }
    ok = ok && cJSON_AddStringToObject(o, "method", psys_pair_method_name(d->method));
    if (d->method == PSYS_PAIR_GRID)
        ok = ok && psys__add_num(o, "skin", d->skin);
    if (d->method == PSYS_PAIR_BARNES_HUT)
        ok = ok && psys__add_num(o, "theta", d->theta);
    if (!ok) {
        cJSON_Delete(o);
        return PSYS_ERR_NOMEM;
    }
    cJSON_AddItemToArray(arr, o);
    return PSYS_OK;
}

const psys__force_io psys__pair_io = {.type = "pair", .cls = &psys_pair_class, .parse = pair_parse, .save = pair_save};
