/* Scene loader (docs/scene-format.md): JSON text -> psys_system + psys_settings, with
 * every problem reported as "JSON.PATH: what is wrong (got VALUE)". */
#include "io/io.h"
#include "io/scene.h"

#include <cjson/cJSON.h>
#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* particle "control": circle / oscillate / keyframes
 * (docs/scene-format.md#controlled-particles, docs/semantics.md#controller-paths). */
static psys_status parse_control(psys__parse *p, const cJSON *ctl, const char *path, size_t i)
{
    static const char *const circle_keys[] = {"type", "center", "radius", "omega", "phase", "axis", NULL};
    static const char *const osc_keys[] = {"type", "center", "direction", "amplitude", "omega", "phase", NULL};
    static const char *const key_keys[] = {"type", "frames", "linear", NULL};
    psys_system *sys = p->sys;
    char kp[256];
    if (!cJSON_IsObject(ctl))
        return psys__parse_fail(p, path, ctl, "must be an object");
    const cJSON *type = cJSON_GetObjectItemCaseSensitive(ctl, "type");
    psys__key_path(kp, sizeof kp, path, "type");
    if (!type)
        return psys__parse_fail(p, kp, NULL, "required key missing");
    if (!cJSON_IsString(type))
        return psys__parse_fail(p, kp, type, "must be a string");
    psys_status st;
    double c[3], dir[3], axis[3], zaxis[3] = {0, 0, 1}, r, w, ph, a;
    if (strcmp(type->valuestring, "circle") == 0) {
        if ((st = psys__parse_keys(p, ctl, path, circle_keys)) != PSYS_OK
            || (st = psys__parse_vec(p, ctl, path, "center", NULL, c)) != PSYS_OK
            || (st = psys__parse_number(p, ctl, path, "radius", false, 0, 0, false, &r)) != PSYS_OK
            || (st = psys__parse_number(p, ctl, path, "omega", false, 0, -INFINITY, false, &w)) != PSYS_OK
            || (st = psys__parse_number(p, ctl, path, "phase", true, 0, -INFINITY, false, &ph)) != PSYS_OK)
            return st;
        if (sys->dim == 2 && cJSON_GetObjectItemCaseSensitive(ctl, "axis")) {
            psys__key_path(kp, sizeof kp, path, "axis");
            return psys__parse_fail(p, kp, cJSON_GetObjectItemCaseSensitive(ctl, "axis"),
                                    "is only used in 3-D scenes (dim is 2)");
        }
        if (sys->dim == 3 && (st = psys__parse_vec(p, ctl, path, "axis", zaxis, axis)) != PSYS_OK)
            return st;
        if (sys->dim == 3 && !(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2] > 0)) {
            psys__key_path(kp, sizeof kp, path, "axis");
            return psys__parse_fail(p, kp, cJSON_GetObjectItemCaseSensitive(ctl, "axis"), "must not be zero");
        }
        if (psys_system_control_circle(sys, i, c, r, w, ph, sys->dim == 3 ? axis : NULL) != PSYS_OK)
            return psys__parse_fail(p, path, NULL, "%s", psys_system_last_error(sys));
        return PSYS_OK;
    }
    if (strcmp(type->valuestring, "oscillate") == 0) {
        if ((st = psys__parse_keys(p, ctl, path, osc_keys)) != PSYS_OK
            || (st = psys__parse_vec(p, ctl, path, "center", NULL, c)) != PSYS_OK
            || (st = psys__parse_vec(p, ctl, path, "direction", NULL, dir)) != PSYS_OK
            || (st = psys__parse_number(p, ctl, path, "amplitude", false, 0, -INFINITY, false, &a)) != PSYS_OK
            || (st = psys__parse_number(p, ctl, path, "omega", false, 0, -INFINITY, false, &w)) != PSYS_OK
            || (st = psys__parse_number(p, ctl, path, "phase", true, 0, -INFINITY, false, &ph)) != PSYS_OK)
            return st;
        if (psys_system_control_oscillate(sys, i, c, dir, a, w, ph) != PSYS_OK) {
            if (sys->err.code == PSYS_ERR_NOMEM)
                return psys__parse_fail(p, path, NULL, "%s", psys_system_last_error(sys));
            psys__key_path(kp, sizeof kp, path, "direction");
            return psys__parse_fail(p, kp, cJSON_GetObjectItemCaseSensitive(ctl, "direction"),
                                    "must be a nonzero vector");
        }
        return PSYS_OK;
    }
    if (strcmp(type->valuestring, "keyframes") == 0) {
        bool linear = true;
        double *frames;
        size_t count;
        if ((st = psys__parse_keys(p, ctl, path, key_keys)) != PSYS_OK
            || (st = psys__parse_bool(p, ctl, path, "linear", &linear)) != PSYS_OK)
            return st;
        if (!linear) {
            psys__key_path(kp, sizeof kp, path, "linear");
            return psys__parse_fail(p, kp, cJSON_GetObjectItemCaseSensitive(ctl, "linear"),
                                    "only linear keyframes are supported");
        }
        psys__key_path(kp, sizeof kp, path, "frames");
        if ((st = psys__parse_frames(p, cJSON_GetObjectItemCaseSensitive(ctl, "frames"), kp, &frames, &count))
            != PSYS_OK)
            return st;
        st = psys_system_control_keyframes(sys, i, frames, count);
        free(frames);
        if (st != PSYS_OK)
            return psys__parse_fail(p, path, NULL, "%s", psys_system_last_error(sys));
        return PSYS_OK;
    }
    return psys__parse_fail(p, kp, type, "unknown control type (known: circle, oscillate, keyframes)");
}

static psys_status parse_particle(psys__parse *p, const cJSON *obj, const char *path)
{
    static const char *const keys[] = {"id", "x", "v", "mass", "fixed", "control", "charge", NULL};
    if (!cJSON_IsObject(obj))
        return psys__parse_fail(p, path, obj, "a particle must be an object");
    psys_status st = psys__parse_keys(p, obj, path, keys);
    if (st != PSYS_OK)
        return st;
    char kp[256];
    double x[3], v[3], zero[3] = {0, 0, 0}, mass, charge;
    bool fixed = false;
    const cJSON *id = cJSON_GetObjectItemCaseSensitive(obj, "id");
    psys__key_path(kp, sizeof kp, path, "id");
    if (id && (!cJSON_IsString(id) || id->valuestring[0] == '\0'))
        return psys__parse_fail(p, kp, id, "must be a non-empty string");
    if (id && psys_system_find(p->sys, id->valuestring, NULL) == PSYS_OK)
        return psys__parse_fail(p, kp, id, "duplicate particle id");
    if ((st = psys__parse_vec(p, obj, path, "x", NULL, x)) != PSYS_OK
        || (st = psys__parse_vec(p, obj, path, "v", zero, v)) != PSYS_OK
        || (st = psys__parse_number(p, obj, path, "mass", true, 1.0, 0, true, &mass)) != PSYS_OK
        || (st = psys__parse_bool(p, obj, path, "fixed", &fixed)) != PSYS_OK
        || (st = psys__parse_number(p, obj, path, "charge", true, 0, -INFINITY, false, &charge)) != PSYS_OK)
        return st;
    if (mass < DBL_MIN) { /* subnormal: 1/mass would be infinite */
        char mp[256];
        psys__key_path(mp, sizeof mp, path, "mass");
        return psys__parse_fail(p, mp, cJSON_GetObjectItemCaseSensitive(obj, "mass"),
                                "must be at least %.17g (a normal number, so that 1/mass is finite)", DBL_MIN);
    }
    size_t i;
    if (psys_system_add_particle(p->sys, x, v, mass, id ? id->valuestring : NULL, &i) != PSYS_OK)
        return psys__fail(p->err, p->sys->err.code, "%s: %s", path, psys_system_last_error(p->sys));
    if (cJSON_GetObjectItemCaseSensitive(obj, "charge") && psys_system_set_charge(p->sys, i, charge) != PSYS_OK)
        return psys__fail(p->err, p->sys->err.code, "%s: %s", path, psys_system_last_error(p->sys));
    if (fixed)
        psys_system_set_fixed(p->sys, i, true);
    const cJSON *ctl = cJSON_GetObjectItemCaseSensitive(obj, "control");
    if (ctl) {
        psys__key_path(kp, sizeof kp, path, "control");
        if (fixed)
            return psys__parse_fail(p, kp, NULL, "a particle cannot be both fixed and controlled");
        return parse_control(p, ctl, kp, i);
    }
    return PSYS_OK;
}

static psys_status parse_force(psys__parse *p, const cJSON *obj, const char *path)
{
    char kp[256];
    if (!cJSON_IsObject(obj))
        return psys__parse_fail(p, path, obj, "a force must be an object");
    const cJSON *type = cJSON_GetObjectItemCaseSensitive(obj, "type");
    psys__key_path(kp, sizeof kp, path, "type");
    if (!type)
        return psys__parse_fail(p, kp, NULL, "required key missing");
    if (!cJSON_IsString(type))
        return psys__parse_fail(p, kp, type, "must be a string");
    for (const psys__force_io *const *io = psys__force_types; *io; io++)
        if (strcmp((*io)->type, type->valuestring) == 0)
            return (*io)->parse(p, obj, path);
    char known[256] = "";
    for (const psys__force_io *const *io = psys__force_types; *io; io++)
        snprintf(known + strlen(known), sizeof known - strlen(known), "%s%s", io == psys__force_types ? "" : ", ",
                 (*io)->type);
    return psys__parse_fail(p, kp, type, "unknown force type (known: %s)", known);
}

/* Parse a JSON array at key with one callback per element. */
static psys_status parse_list(psys__parse *p, const cJSON *root, const char *key,
                              psys_status (*each)(psys__parse *, const cJSON *, const char *))
{
    const cJSON *arr = cJSON_GetObjectItemCaseSensitive(root, key);
    if (!arr)
        return PSYS_OK;
    if (!cJSON_IsArray(arr))
        return psys__parse_fail(p, key, arr, "must be an array");
    char ep[64];
    int i = 0;
    for (const cJSON *it = arr->child; it; it = it->next, i++) {
        snprintf(ep, sizeof ep, "%s[%d]", key, i);
        psys_status st = each(p, it, ep);
        if (st != PSYS_OK)
            return st;
    }
    return PSYS_OK;
}

/* planes: {point, normal, restitution, friction (number or "stick"), response} */
static psys_status parse_plane(psys__parse *p, const cJSON *obj, const char *path)
{
    static const char *const keys[] = {"point", "normal", "restitution", "friction", "response",
                                       "forward", "backward_friction", NULL};
    psys_plane_def def = psys_plane_def_default();
    char kp[256];
    psys_status st;
    if (!cJSON_IsObject(obj))
        return psys__parse_fail(p, path, obj, "a plane must be an object");
    if ((st = psys__parse_keys(p, obj, path, keys)) != PSYS_OK
        || (st = psys__parse_vec(p, obj, path, "point", NULL, def.point)) != PSYS_OK
        || (st = psys__parse_vec(p, obj, path, "normal", NULL, def.normal)) != PSYS_OK
        || (st = psys__parse_number(p, obj, path, "restitution", true, 0.5, 0, false, &def.restitution)) != PSYS_OK)
        return st;
    double n2 = 0;
    for (int k = 0; k < p->sys->dim; k++)
        n2 += def.normal[k] * def.normal[k];
    if (!(n2 > 0)) {
        psys__key_path(kp, sizeof kp, path, "normal");
        return psys__parse_fail(p, kp, cJSON_GetObjectItemCaseSensitive(obj, "normal"), "must not be zero");
    }
    if (def.restitution > 1) {
        psys__key_path(kp, sizeof kp, path, "restitution");
        return psys__parse_fail(p, kp, cJSON_GetObjectItemCaseSensitive(obj, "restitution"), "must be from 0 to 1");
    }
    const cJSON *fr = cJSON_GetObjectItemCaseSensitive(obj, "friction");
    if (cJSON_IsString(fr) && strcmp(fr->valuestring, "stick") == 0) {
        def.stick = true;
    } else if (fr && !cJSON_IsNumber(fr)) {
        psys__key_path(kp, sizeof kp, path, "friction");
        return psys__parse_fail(p, kp, fr, "must be a number >= 0 or \"stick\"");
    } else if ((st = psys__parse_number(p, obj, path, "friction", true, 0, 0, false, &def.friction)) != PSYS_OK) {
        return st;
    }
    const cJSON *resp = cJSON_GetObjectItemCaseSensitive(obj, "response");
    if (resp) {
        psys__key_path(kp, sizeof kp, path, "response");
        if (cJSON_IsString(resp) && strcmp(resp->valuestring, "rollback") == 0)
            def.response = PSYS_RESPONSE_ROLLBACK;
        else if (cJSON_IsString(resp) && strcmp(resp->valuestring, "displace") == 0)
            def.response = PSYS_RESPONSE_DISPLACE;
        else
            return psys__parse_fail(p, kp, resp, "must be \"rollback\" or \"displace\"");
    }
    const cJSON *fw = cJSON_GetObjectItemCaseSensitive(obj, "forward");
    const cJSON *bf = cJSON_GetObjectItemCaseSensitive(obj, "backward_friction");
    if (!!fw != !!bf) {
        psys__key_path(kp, sizeof kp, path, fw ? "backward_friction" : "forward");
        return psys__parse_fail(p, kp, NULL, "required key missing (forward and backward_friction go together)");
    }
    if (fw) {
        if (def.stick) {
            psys__key_path(kp, sizeof kp, path, "forward");
            return psys__parse_fail(p, kp, NULL, "directional friction does not apply to a \"stick\" plane");
        }
        if ((st = psys__parse_vec(p, obj, path, "forward", NULL, def.forward)) != PSYS_OK
            || (st = psys__parse_number(p, obj, path, "backward_friction", false, 0, 0, false,
                                        &def.backward_friction)) != PSYS_OK)
            return st;
        double f2 = 0;
        for (int k = 0; k < p->sys->dim; k++)
            f2 += def.forward[k] * def.forward[k];
        double n2f = 0, fdn = 0;
        for (int k = 0; k < p->sys->dim; k++) {
            n2f += def.normal[k] * def.normal[k];
            fdn += def.forward[k] * def.normal[k];
        }
        if (!(f2 > 0) || !(f2 - fdn * fdn / n2f > 1e-24 * f2)) {
            psys__key_path(kp, sizeof kp, path, "forward");
            return psys__parse_fail(p, kp, fw, f2 > 0 ? "must not be along the normal" : "must not be zero");
        }
    }
    if (psys_system_add_plane(p->sys, &def) != PSYS_OK)
        return psys__fail(p->err, p->sys->err.code, "%s: %s", path, psys_system_last_error(p->sys));
    return PSYS_OK;
}

static psys_status parse_output(psys__parse *p, const cJSON *root, psys_settings *set)
{
    static const char *const keys[] = {"every", "trajectory", "energy", "render", "radius", NULL};
    const cJSON *out = cJSON_GetObjectItemCaseSensitive(root, "output");
    if (!out)
        return PSYS_OK;
    if (!cJSON_IsObject(out))
        return psys__parse_fail(p, "output", out, "must be an object");
    psys_status st;
    if ((st = psys__parse_keys(p, out, "output", keys)) != PSYS_OK
        || (st = psys__parse_integer(p, out, "output", "every", 1, &set->every, NULL)) != PSYS_OK
        || (st = psys__parse_string(p, out, "output", "trajectory", set->trajectory, sizeof set->trajectory)) != PSYS_OK
        || (st = psys__parse_string(p, out, "output", "energy", set->energy, sizeof set->energy)) != PSYS_OK
        || (st = psys__parse_string(p, out, "output", "render", set->render, sizeof set->render)) != PSYS_OK
        || (st = psys__parse_number(p, out, "output", "radius", true, 0, 0, true, &set->render_radius)) != PSYS_OK)
        return st;
    return PSYS_OK;
}

static psys_status parse_checkpoint(psys__parse *p, const cJSON *root, psys_resume_state *rs)
{
    static const char *const keys[] = {"step", "t", "base_step", "base_t", "next_h", NULL};
    const cJSON *ck = cJSON_GetObjectItemCaseSensitive(root, "checkpoint");
    if (!ck)
        return PSYS_OK;
    if (!cJSON_IsObject(ck))
        return psys__parse_fail(p, "checkpoint", ck, "must be an object");
    psys_status st;
    bool has_step = false, has_base = false;
    if ((st = psys__parse_keys(p, ck, "checkpoint", keys)) != PSYS_OK
        || (st = psys__parse_integer(p, ck, "checkpoint", "step", 0, &rs->step, &has_step)) != PSYS_OK
        || (st = psys__parse_integer(p, ck, "checkpoint", "base_step", 0, &rs->base_step, &has_base)) != PSYS_OK
        || (st = psys__parse_number(p, ck, "checkpoint", "t", false, 0, -INFINITY, false, &rs->t)) != PSYS_OK
        || (st = psys__parse_number(p, ck, "checkpoint", "base_t", false, 0, -INFINITY, false, &rs->base_t)) != PSYS_OK
        || (st = psys__parse_number(p, ck, "checkpoint", "next_h", true, 0, 0, false, &rs->next_h)) != PSYS_OK)
        return st;
    if (!has_step)
        return psys__parse_fail(p, "checkpoint.step", NULL, "required key missing");
    if (!has_base)
        return psys__parse_fail(p, "checkpoint.base_step", NULL, "required key missing");
    if (rs->base_step > rs->step)
        return psys__parse_fail(p, "checkpoint.base_step", cJSON_GetObjectItemCaseSensitive(ck, "base_step"),
                                "must not exceed checkpoint.step");
    rs->present = true;
    return PSYS_OK;
}

static psys_status parse_root(psys__parse *p, const cJSON *root, psys_scene *scene)
{
    static const char *const keys[] = {"psys", "dim", "integrator", "dt", "duration", "steps", "tolerance",
                                       "particles", "forces", "planes", "structures", "output", "box",
                                       "checkpoint", "cg_tolerance", "cg_max_iterations", NULL};
    psys_settings *set = &scene->settings;
    psys_status st;
    if (!cJSON_IsObject(root))
        return psys__parse_fail(p, "(root)", root, "a scene must be a JSON object");
    if ((st = psys__parse_keys(p, root, "", keys)) != PSYS_OK)
        return st;
    const cJSON *ver = cJSON_GetObjectItemCaseSensitive(root, "psys");
    if (!ver)
        return psys__parse_fail(p, "psys", NULL, "required key missing (a scene starts with \"psys\": 1)");
    if (!cJSON_IsNumber(ver) || ver->valuedouble != 1)
        return psys__parse_fail(p, "psys", ver, "unsupported format version (this psys reads version 1)");
    long long dim = 3;
    if ((st = psys__parse_integer(p, root, "", "dim", 0, &dim, NULL)) != PSYS_OK)
        return st;
    if (dim != 2 && dim != 3)
        return psys__parse_fail(p, "dim", cJSON_GetObjectItemCaseSensitive(root, "dim"), "must be 2 or 3");
    if ((st = psys__parse_string(p, root, "", "integrator", set->integrator, sizeof set->integrator)) != PSYS_OK)
        return st;
    if (!psys_solver_exists(set->integrator)) {
        char known[256] = "";
        for (size_t i = 0; psys_solver_name_at(i); i++)
            snprintf(known + strlen(known), sizeof known - strlen(known), "%s%s", i ? ", " : "",
                     psys_solver_name_at(i));
        return psys__parse_fail(p, "integrator", cJSON_GetObjectItemCaseSensitive(root, "integrator"),
                                "unknown integrator (known: %s)", known);
    }
    bool has_steps = false;
    if ((st = psys__parse_number(p, root, "", "dt", true, set->dt, 0, true, &set->dt)) != PSYS_OK
        || (st = psys__parse_number(p, root, "", "tolerance", true, set->tolerance, 0, true, &set->tolerance)) != PSYS_OK
        || (st = psys__parse_integer(p, root, "", "steps", 0, &set->steps, &has_steps)) != PSYS_OK
        || (st = psys__parse_number(p, root, "", "cg_tolerance", true, set->cg_tolerance, 0, true,
                                    &set->cg_tolerance)) != PSYS_OK
        || (st = psys__parse_integer(p, root, "", "cg_max_iterations", 1, &set->cg_max_iterations, NULL)) != PSYS_OK)
        return st;
    const cJSON *dur = cJSON_GetObjectItemCaseSensitive(root, "duration");
    if (dur && has_steps)
        return psys__parse_fail(p, "duration", dur, "give either duration or steps, not both");
    if ((st = psys__parse_number(p, root, "", "duration", true, set->duration, 0, false, &set->duration)) != PSYS_OK)
        return st;
    set->use_steps = has_steps;
    if (!(p->sys = scene->sys = psys_system_create((int)dim, p->err)))
        return p->err->code;
    /* the box before forces, which check their cutoffs against it */
    if ((st = psys__parse_box(p, root)) != PSYS_OK)
        return st;
    /* structures after the explicit particles and before forces, so that
     * forces can refer to structure particles by id */
    if ((st = parse_list(p, root, "particles", parse_particle)) != PSYS_OK
        || (st = parse_list(p, root, "structures", psys__parse_structure)) != PSYS_OK
        || (st = parse_list(p, root, "forces", parse_force)) != PSYS_OK
        || (st = parse_list(p, root, "planes", parse_plane)) != PSYS_OK
        || (st = parse_output(p, root, set)) != PSYS_OK
        || (st = parse_checkpoint(p, root, &scene->resume)) != PSYS_OK)
        return st;
    if (scene->resume.present) {
        psys_system_set_time(scene->sys, scene->resume.t);
        psys_system_apply_controllers(scene->sys, scene->resume.t);
    }
    return PSYS_OK;
}

psys_settings psys_settings_default(void)
{
    psys_settings s;
    memset(&s, 0, sizeof s);
    snprintf(s.integrator, sizeof s.integrator, "rk4");
    s.dt = 0.001;
    s.duration = 1.0;
    s.tolerance = 1e-6;
    s.every = 1;
    s.cg_tolerance = 1e-6;
    s.cg_max_iterations = 1000;
    return s;
}

/* "line L, column C" of byte offset off in text. */
static void locate(const char *text, size_t off, char *out, size_t cap)
{
    size_t line = 1, col = 1;
    for (size_t i = 0; i < off; i++) {
        if (text[i] == '\n') {
            line++;
            col = 1;
        } else {
            col++;
        }
    }
    snprintf(out, cap, "line %zu, column %zu", line, col);
}

static bool is_space(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r'; }

/* Where a failed cJSON parse really went wrong. cJSON reports an object key
 * that is not a string one character late, and an input that ends too early
 * at its last character rather than at the end. */
static size_t error_offset(const char *text, size_t len, size_t off)
{
    if (off >= len)
        return len;
    if (off > 0 && !is_space(text[off - 1]) && text[off - 1] != ',' && text[off - 1] != '{'
        && text[off - 1] != '"') {
        size_t q = off - 1;
        while (q > 0 && is_space(text[q - 1]))
            q--;
        if (q > 0 && (text[q - 1] == ',' || text[q - 1] == '{'))
            return off - 1;
    }
    if (off == len - 1 && strchr("\"0123456789el", text[off]))
        return len;
    return off;
}

psys_scene *psys_scene_load_string(const char *text, size_t len, psys_error *err)
{
    psys_error local;
    if (!err)
        err = &local;
    psys__ok(err);
    size_t i = 0;
    while (i < len && (text[i] == ' ' || text[i] == '\t' || text[i] == '\n' || text[i] == '\r'))
        i++;
    if (i == len) {
        psys__fail(err, PSYS_ERR_INVALID, "(root): the scene is empty (a scene is a JSON object starting with \"psys\": 1)");
        return NULL;
    }
    if (memchr(text, '\0', len)) {
        psys__fail(err, PSYS_ERR_INVALID, "(root): the scene contains a NUL byte (not a JSON text file)");
        return NULL;
    }
    const char *end = NULL;
    cJSON *root = cJSON_ParseWithLengthOpts(text, len, &end, false);
    if (!root || (size_t)(end - text) < len) {
        size_t off = end ? (size_t)(end - text) : len;
        if (root) { /* trailing garbage after a complete value */
            while (off < len && (text[off] == ' ' || text[off] == '\t' || text[off] == '\n' || text[off] == '\r'))
                off++;
        }
        if (!root || off < len) {
            char where[64], got[40];
            /* cJSON says only "failed": out of memory, too deep, or a syntax error? */
            size_t at = 0;
            int why = root ? 1 : psys__json_check(text, len, CJSON_NESTING_LIMIT, &at);
            if (why == 0) {
                psys__fail(err, PSYS_ERR_NOMEM, "(root): out of memory reading the JSON text");
                return NULL;
            }
            if (why == 2) {
                locate(text, at, where, sizeof where);
                psys__fail(err, PSYS_ERR_INVALID, "%s: JSON nested too deeply (more than %d levels of arrays and objects)",
                           where, CJSON_NESTING_LIMIT);
                return NULL;
            }
            if (!root)
                off = error_offset(text, len, off);
            if (off > len)
                off = len;
            locate(text, off, where, sizeof where);
            size_t n = 0;
            while (n < 20 && off + n < len && text[off + n] != '\n' && text[off + n] != '\r')
                n++;
            snprintf(got, sizeof got, "%.*s", (int)n, text + off);
            if (off >= len)
                psys__fail(err, PSYS_ERR_INVALID, "%s: malformed JSON (got end of file)", where);
            else if (n == 0)
                psys__fail(err, PSYS_ERR_INVALID, "%s: malformed JSON (got end of line)", where);
            else
                psys__fail(err, PSYS_ERR_INVALID, "%s: malformed JSON (got \"%s\")", where, got);
            cJSON_Delete(root);
            return NULL;
        }
    }
    psys_scene *scene = calloc(1, sizeof *scene);
    if (!scene) {
        cJSON_Delete(root);
        psys__fail(err, PSYS_ERR_NOMEM, "(root): out of memory");
        return NULL;
    }
    scene->settings = psys_settings_default();
    psys__parse p = {NULL, err};
    psys_status st = parse_root(&p, root, scene);
    cJSON_Delete(root);
    if (st != PSYS_OK) {
        psys_scene_destroy(scene);
        return NULL;
    }
    return scene;
}

psys_scene *psys_scene_load_file(const char *path, psys_error *err)
{
    FILE *fp = strcmp(path, "-") == 0 ? stdin : fopen(path, "rb");
    if (!fp) {
        psys__fail(err, PSYS_ERR_IO, "cannot open: %s", strerror(errno));
        return NULL;
    }
    size_t cap = 1 << 16, len = 0;
    char *buf = malloc(cap);
    while (buf) {
        size_t got = fread(buf + len, 1, cap - len, fp);
        len += got;
        if (len < cap)
            break;
        char *nb = cap > SIZE_MAX / 2 ? NULL : realloc(buf, cap * 2);
        if (!nb) {
            free(buf);
            buf = NULL;
            break;
        }
        buf = nb;
        cap *= 2;
    }
    bool bad = !buf || ferror(fp);
    int e = errno;
    if (fp != stdin)
        fclose(fp);
    if (bad) {
        bool oom = buf == NULL;
        free(buf);
        psys__fail(err, oom ? PSYS_ERR_NOMEM : PSYS_ERR_IO, "cannot read: %s", oom ? "out of memory" : strerror(e));
        return NULL;
    }
    psys_scene *scene = psys_scene_load_string(buf, len, err);
    free(buf);
    return scene;
}

void psys_scene_destroy(psys_scene *scene)
{
    if (!scene)
        return;
    psys_system_destroy(scene->sys);
    free(scene);
}

psys_system *psys_scene_system(psys_scene *scene) { return scene->sys; }
psys_settings *psys_scene_settings(psys_scene *scene) { return &scene->settings; }
const psys_resume_state *psys_scene_resume_state(const psys_scene *scene) { return &scene->resume; }
