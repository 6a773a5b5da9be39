/* Scene form of structures: the "structures" array, built by the builders
 * of sim/structures.c, whose problems are reported at their JSON path. */
#include "io/io.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef psys__problem problem;

/* ---- scene format: the "structures" array ---- */

static void key_path(char *out, size_t cap, const char *path, const char *key)
{
    snprintf(out, cap, "%s.%s", path, key);
}

/* Report a builder problem at its JSON path, with the JSON value. */
static psys_status scene_report(psys__parse *p, const cJSON *obj, const char *path, const char *kind,
                                psys_status st, const problem *pb)
{
    char kp[320];
    if (st == PSYS_OK)
        return PSYS_OK;
    if (!pb->key)
        return psys__parse_fail(p, path, NULL, "out of memory building the %s", kind);
    const cJSON *item = cJSON_GetObjectItemCaseSensitive(obj, pb->key);
    key_path(kp, sizeof kp, path, pb->key);
    if (pb->index >= 0 && item) {
        size_t len = strlen(kp);
        snprintf(kp + len, sizeof kp - len, "[%ld]", pb->index);
        item = cJSON_GetArrayItem(item, (int)pb->index);
    }
    return psys__parse_fail(p, kp, item, "%s", pb->what);
}

static psys_status get_id(psys__parse *p, const cJSON *obj, const char *path, const char **id)
{
    char kp[320];
    const cJSON *it = cJSON_GetObjectItemCaseSensitive(obj, "id");
    *id = NULL;
    if (!it)
        return PSYS_OK;
    key_path(kp, sizeof kp, path, "id");
    if (!cJSON_IsString(it) || !it->valuestring[0])
        return psys__parse_fail(p, kp, it, "must be a non-empty string");
    *id = it->valuestring;
    return PSYS_OK;
}

static psys_status get_bool(psys__parse *p, const cJSON *obj, const char *path, const char *key, bool *out)
{
    char kp[320];
    const cJSON *it = cJSON_GetObjectItemCaseSensitive(obj, key);
    if (!it)
        return PSYS_OK;
    key_path(kp, sizeof kp, path, key);
    if (!cJSON_IsBool(it))
        return psys__parse_fail(p, kp, it, "must be true or false");
    *out = cJSON_IsTrue(it);
    return PSYS_OK;
}

/* A JSON integer >= 0 as size_t; SIZE_MAX when negative or beyond any limit
 * (builders then report it as out of range). False if not an integer. */
static bool as_size(const cJSON *it, size_t *out)
{
    if (!cJSON_IsNumber(it) || !isfinite(it->valuedouble) || it->valuedouble != floor(it->valuedouble))
        return false;
    double v = it->valuedouble;
    *out = v < 0 || v > 1e15 ? SIZE_MAX : (size_t)v;
    return true;
}

/* Required integer count >= min. */
static psys_status get_count(psys__parse *p, const cJSON *obj, const char *path, const char *key, size_t min,
                             size_t *out)
{
    char kp[320];
    const cJSON *it = cJSON_GetObjectItemCaseSensitive(obj, key);
    key_path(kp, sizeof kp, path, key);
    if (!it)
        return psys__parse_fail(p, kp, NULL, "required key missing");
    if (!as_size(it, out) || it->valuedouble < (double)min)
        return psys__parse_fail(p, kp, it, "must be an integer >= %zu", min);
    return PSYS_OK;
}

/* Required "size": an array of nd integers >= 2. */
static psys_status get_size(psys__parse *p, const cJSON *obj, const char *path, int nd, size_t *n)
{
    char kp[320];
    const cJSON *it = cJSON_GetObjectItemCaseSensitive(obj, "size");
    key_path(kp, sizeof kp, path, "size");
    if (!it)
        return psys__parse_fail(p, kp, NULL, "required key missing");
    bool ok = cJSON_IsArray(it) && cJSON_GetArraySize(it) == nd;
    int d = 0;
    for (const cJSON *c = ok ? it->child : NULL; c; c = c->next, d++)
        ok = ok && as_size(c, &n[d]) && c->valuedouble >= 2;
    if (!ok)
        return psys__parse_fail(p, kp, it, "must be an array of %d integers >= 2", nd);
    return PSYS_OK;
}

/* A dim-vector from an array item (as psys__parse_vec does for keys). */
static psys_status vec_item(psys__parse *p, const cJSON *it, const char *kp, int dim, double *out)
{
    return psys__parse_vec_item(p, it, kp, dim, out);
}

/* Optional "axes": an array of nd dim-vectors. */
static psys_status get_axes(psys__parse *p, const cJSON *obj, const char *path, int nd, int dim, double (*axes)[3])
{
    char kp[320], ep[360];
    const cJSON *it = cJSON_GetObjectItemCaseSensitive(obj, "axes");
    if (!it)
        return PSYS_OK;
    key_path(kp, sizeof kp, path, "axes");
    if (!cJSON_IsArray(it) || cJSON_GetArraySize(it) != nd)
        return psys__parse_fail(p, kp, it, "must be an array of %d vectors", nd);
    int d = 0;
    for (const cJSON *c = it->child; c; c = c->next, d++) {
        snprintf(ep, sizeof ep, "%s[%d]", kp, d);
        psys_status st = vec_item(p, c, ep, dim, axes[d]);
        if (st != PSYS_OK)
            return st;
    }
    return PSYS_OK;
}

/* Optional "pin": nd = 1: [i, ...] (wheel: "hub" too, counted in *hub);
 * nd >= 2: [[i, j(, k)], ...]. *pins is malloc'ed (count × nd). */
static psys_status get_pins(psys__parse *p, const cJSON *obj, const char *path, int nd, bool wheel, size_t **pins,
                            size_t *count, bool *hub)
{
    char kp[320], ep[340];
    const cJSON *it = cJSON_GetObjectItemCaseSensitive(obj, "pin");
    *pins = NULL;
    *count = 0;
    if (!it)
        return PSYS_OK;
    key_path(kp, sizeof kp, path, "pin");
    if (!cJSON_IsArray(it))
        return psys__parse_fail(p, kp, it, nd == 1 ? "must be an array of particle indices"
                                                   : "must be an array of grid coordinates");
    size_t n = (size_t)cJSON_GetArraySize(it), m = 0;
    size_t *out = psys__calloc(n * (size_t)nd, sizeof *out);
    if (!out)
        return psys__parse_fail(p, kp, NULL, "out of memory");
    for (const cJSON *c = it->child; c; c = c->next, m++) {
        snprintf(ep, sizeof ep, "%s[%zu]", kp, m);
        if (nd == 1) {
            if (wheel && cJSON_IsString(c) && strcmp(c->valuestring, "hub") == 0) {
                *hub = true;
                out[m] = SIZE_MAX - 1; /* removed below */
                continue;
            }
            if (!as_size(c, &out[m])) {
                free(out);
                return psys__parse_fail(p, ep, c, wheel ? "must be a rim index (integer) or \"hub\""
                                                        : "must be a particle index (integer)");
            }
            continue;
        }
        bool ok = cJSON_IsArray(c) && cJSON_GetArraySize(c) == nd;
        int d = 0;
        for (const cJSON *e = ok ? c->child : NULL; e; e = e->next, d++)
            ok = ok && as_size(e, &out[m * (size_t)nd + (size_t)d]);
        if (!ok) {
            free(out);
            return psys__parse_fail(p, ep, c, "must be grid coordinates [%s] (integers)", nd == 2 ? "i, j" : "i, j, k");
        }
    }
    *pins = out;
    *count = n;
    return PSYS_OK;
}

static psys_status parse_chain(psys__parse *p, const cJSON *obj, const char *path)
{
    static const char *const keys[] = {"type", "id", "from", "to", "count", "mass", "ks", "kd", "pin", "muscle", NULL};
    psys_system *sys = psys__parse_system(p);
    psys_chain_def def = psys_chain_def_default();
    double muscle[4];
    bool has_muscle = false, hub = false;
    size_t *pins = NULL;
    psys_status st = psys__parse_keys(p, obj, path, keys);
    if (st == PSYS_OK) st = get_id(p, obj, path, &def.id);
    if (st == PSYS_OK) st = psys__parse_vec(p, obj, path, "from", NULL, def.from);
    if (st == PSYS_OK) st = psys__parse_vec(p, obj, path, "to", NULL, def.to);
    if (st == PSYS_OK) st = get_count(p, obj, path, "count", 2, &def.count);
    if (st == PSYS_OK) st = psys__parse_number(p, obj, path, "mass", true, 1.0, 0, true, &def.mass);
    if (st == PSYS_OK) st = psys__parse_number(p, obj, path, "ks", false, 0, 0, false, &def.ks);
    if (st == PSYS_OK) st = psys__parse_number(p, obj, path, "kd", true, 0, 0, false, &def.kd);
    if (st == PSYS_OK) st = psys__parse_muscle(p, obj, path, true, &has_muscle, muscle);
    if (st == PSYS_OK) st = get_pins(p, obj, path, 1, false, &pins, &def.pin_count, &hub);
    if (st != PSYS_OK)
        return st;
    if (has_muscle) {
        def.muscle_amplitude = muscle[0];
        def.muscle_omega = muscle[1];
        def.muscle_phase = muscle[2];
        def.muscle_phase_step = muscle[3];
    }
    def.pin = pins;
    problem pb;
    st = scene_report(p, obj, path, "chain", psys__chain_build(sys, &def, &pb), &pb);
    free(pins);
    return st;
}

enum { LATTICE_CLOTH, LATTICE_BEAM, LATTICE_BLOCK };

static psys_status parse_lattice(psys__parse *p, const cJSON *obj, const char *path, int kind)
{
    static const char *const cloth_keys[] = {"type",     "id",       "origin",  "size",    "spacing", "mass",
                                             "ks",       "kd",       "shear",   "bend",    "shear_ks", "shear_kd",
                                             "bend_ks",  "bend_kd",  "axes",    "pin",     NULL};
    static const char *const keys[] = {"type", "id", "origin", "size", "spacing", "mass", "ks", "kd", "axes", "pin",
                                       NULL};
    static const char *const names[] = {"cloth", "beam", "block"};
    psys_system *sys = psys__parse_system(p);
    int dim = sys->dim, nd = kind == LATTICE_BLOCK ? 3 : 2;
    psys_cloth_def c = psys_cloth_def_default();
    psys_block_def b = psys_block_def_default();
    size_t n[3] = {2, 2, 2}, *pins = NULL, npins = 0;
    double zero[3] = {0, 0, 0}, origin[3], spacing, mass, ks, kd, axes[3][3];
    bool hub = false;
    memcpy(axes, b.axes, sizeof axes);
    psys_status st = psys__parse_keys(p, obj, path, kind == LATTICE_CLOTH ? cloth_keys : keys);
    const char *id = NULL;
    if (st == PSYS_OK) st = get_id(p, obj, path, &id);
    if (st == PSYS_OK) st = psys__parse_vec(p, obj, path, "origin", zero, origin);
    if (st == PSYS_OK) st = get_size(p, obj, path, nd, n);
    if (st == PSYS_OK) st = psys__parse_number(p, obj, path, "spacing", false, 0, 0, true, &spacing);
    if (st == PSYS_OK) st = psys__parse_number(p, obj, path, "mass", true, 1.0, 0, true, &mass);
    if (st == PSYS_OK) st = psys__parse_number(p, obj, path, "ks", false, 0, 0, false, &ks);
    if (st == PSYS_OK) st = psys__parse_number(p, obj, path, "kd", true, 0, 0, false, &kd);
    if (kind == LATTICE_CLOTH) {
        if (st == PSYS_OK) st = get_bool(p, obj, path, "shear", &c.shear);
        if (st == PSYS_OK) st = get_bool(p, obj, path, "bend", &c.bend);
        if (st == PSYS_OK) st = psys__parse_number(p, obj, path, "shear_ks", true, -1, 0, false, &c.shear_ks);
        if (st == PSYS_OK) st = psys__parse_number(p, obj, path, "shear_kd", true, -1, 0, false, &c.shear_kd);
        if (st == PSYS_OK) st = psys__parse_number(p, obj, path, "bend_ks", true, -1, 0, false, &c.bend_ks);
        if (st == PSYS_OK) st = psys__parse_number(p, obj, path, "bend_kd", true, -1, 0, false, &c.bend_kd);
    }
    if (st == PSYS_OK) st = get_axes(p, obj, path, nd, dim, axes);
    if (st == PSYS_OK) st = get_pins(p, obj, path, nd, false, &pins, &npins, &hub);
    if (st != PSYS_OK)
        return st;
    problem pb;
    if (kind == LATTICE_BLOCK) {
        b.id = id;
        memcpy(b.origin, origin, sizeof origin);
        b.nx = n[0];
        b.ny = n[1];
        b.nz = n[2];
        b.spacing = spacing;
        b.mass = mass;
        b.ks = ks;
        b.kd = kd;
        memcpy(b.axes, axes, sizeof axes);
        b.pin = pins;
        b.pin_count = npins;
        st = psys__block_build(sys, &b, &pb);
    } else {
        if (kind == LATTICE_BEAM)
            c.bend = false; /* beam: structural + both diagonals, shear springs with ks, kd */
        c.id = id;
        memcpy(c.origin, origin, sizeof origin);
        c.nx = n[0];
        c.ny = n[1];
        c.spacing = spacing;
        c.mass = mass;
        c.ks = ks;
        c.kd = kd;
        memcpy(c.axes, axes, sizeof c.axes);
        c.pin = pins;
        c.pin_count = npins;
        st = psys__cloth_build(sys, &c, &pb);
    }
    st = scene_report(p, obj, path, names[kind], st, &pb);
    free(pins);
    return st;
}

static psys_status parse_cloth(psys__parse *p, const cJSON *obj, const char *path)
{
    return parse_lattice(p, obj, path, LATTICE_CLOTH);
}
static psys_status parse_beam(psys__parse *p, const cJSON *obj, const char *path)
{
    return parse_lattice(p, obj, path, LATTICE_BEAM);
}
static psys_status parse_block(psys__parse *p, const cJSON *obj, const char *path)
{
    return parse_lattice(p, obj, path, LATTICE_BLOCK);
}

static psys_status parse_wheel(psys__parse *p, const cJSON *obj, const char *path)
{
    static const char *const keys[] = {"type", "id", "center", "radius", "count", "mass", "ks", "kd",
                                       "axis", "hub", "brace", "pin", NULL};
    psys_system *sys = psys__parse_system(p);
    psys_wheel_def def = psys_wheel_def_default();
    double zero[3] = {0, 0, 0};
    size_t *pins = NULL;
    char kp[320];
    psys_status st = psys__parse_keys(p, obj, path, keys);
    if (st == PSYS_OK) st = get_id(p, obj, path, &def.id);
    if (st == PSYS_OK) st = psys__parse_vec(p, obj, path, "center", zero, def.center);
    if (st == PSYS_OK) st = psys__parse_number(p, obj, path, "radius", false, 0, 0, true, &def.radius);
    if (st == PSYS_OK) st = get_count(p, obj, path, "count", 3, &def.count);
    if (st == PSYS_OK) st = psys__parse_number(p, obj, path, "mass", true, 1.0, 0, true, &def.mass);
    if (st == PSYS_OK) st = psys__parse_number(p, obj, path, "ks", false, 0, 0, false, &def.ks);
    if (st == PSYS_OK) st = psys__parse_number(p, obj, path, "kd", true, 0, 0, false, &def.kd);
    if (st == PSYS_OK && sys->dim == 2 && cJSON_GetObjectItemCaseSensitive(obj, "axis")) {
        key_path(kp, sizeof kp, path, "axis");
        st = psys__parse_fail(p, kp, cJSON_GetObjectItemCaseSensitive(obj, "axis"),
                              "is only used in 3-D scenes (dim is 2)");
    }
    if (st == PSYS_OK && sys->dim == 3) st = psys__parse_vec(p, obj, path, "axis", def.axis, def.axis);
    if (st == PSYS_OK) st = get_bool(p, obj, path, "hub", &def.hub);
    if (st == PSYS_OK) st = get_bool(p, obj, path, "brace", &def.brace);
    if (st == PSYS_OK) st = get_pins(p, obj, path, 1, true, &pins, &def.pin_count, &def.pin_hub);
    if (st != PSYS_OK)
        return st;
    /* "hub" entries of pin become pin_hub; an error names the entry */
    size_t kept = 0;
    long hub_at = -1;
    for (size_t m = 0; m < def.pin_count; m++) {
        if (pins[m] == SIZE_MAX - 1) {
            if (hub_at < 0)
                hub_at = (long)m;
            continue;
        }
        pins[kept++] = pins[m];
    }
    if (def.pin_hub && !def.hub) {
        snprintf(kp, sizeof kp, "%s.pin[%ld]", path, hub_at);
        st = psys__parse_fail(p, kp, cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(obj, "pin"), (int)hub_at),
                              "there is no hub (hub is false)");
        free(pins);
        return st;
    }
    /* with "hub" entries removed, pin[index] of a problem no longer matches the
     * JSON; map it back */
    def.pin = pins;
    def.pin_count = kept;
    problem pb;
    st = psys__wheel_build(sys, &def, &pb);
    if (st == PSYS_ERR_INVALID && pb.key && strcmp(pb.key, "pin") == 0 && pb.index >= 0) {
        long seen = -1, m = 0;
        for (const cJSON *c = cJSON_GetObjectItemCaseSensitive(obj, "pin")->child; c; c = c->next, m++)
            if (!cJSON_IsString(c) && ++seen == pb.index)
                break;
        pb.index = m;
    }
    st = scene_report(p, obj, path, "wheel", st, &pb);
    free(pins);
    return st;
}

psys_status psys__parse_structure(psys__parse *p, const cJSON *obj, const char *path)
{
    static const struct {
        const char *name;
        psys_status (*parse)(psys__parse *, const cJSON *, const char *);
    } types[] = {{"chain", parse_chain}, {"cloth", parse_cloth}, {"beam", parse_beam},
                 {"block", parse_block}, {"wheel", parse_wheel}};
    char kp[320];
    if (!cJSON_IsObject(obj))
        return psys__parse_fail(p, path, obj, "a structure must be an object");
    const cJSON *type = cJSON_GetObjectItemCaseSensitive(obj, "type");
    key_path(kp, sizeof kp, path, "type");
    if (!type)
        return psys__parse_fail(p, kp, NULL, "required key missing");
    if (!cJSON_IsString(type))
        return psys__parse_fail(p, kp, type, "must be a string");
    for (size_t i = 0; i < sizeof types / sizeof types[0]; i++)
        if (strcmp(types[i].name, type->valuestring) == 0) {
            if (types[i].parse == parse_block && psys__parse_system(p)->dim != 3)
                return psys__parse_fail(p, kp, type, "needs dim 3 (a block is a 3-D lattice; use a beam in 2-D)");
            return types[i].parse(p, obj, path);
        }
    return psys__parse_fail(p, kp, type, "unknown structure type (known: chain, cloth, beam, block, wheel)");
}
