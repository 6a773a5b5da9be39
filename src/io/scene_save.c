/* Scene saver: the loaded system written back in the scene format, so that
 * loading the result gives the same system to the last bit (cJSON prints
 * numbers with up to 17 significant digits, enough to recover each double). */
#include "io/io.h"
#include "io/scene.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static cJSON *control_json(const psys__controller *c, int d)
{
    cJSON *o = cJSON_CreateObject();
    bool ok = o != NULL;
    switch (c->kind) {
    case PSYS__CONTROL_CIRCLE:
        ok = ok && cJSON_AddStringToObject(o, "type", "circle")
             && cJSON_AddItemToObjectCS(o, "center", psys__vec_json(c->center, d))
             && psys__add_num(o, "radius", c->radius) && psys__add_num(o, "omega", c->omega)
             && psys__add_num(o, "phase", c->phase)
             && (d == 2 || cJSON_AddItemToObjectCS(o, "axis", psys__vec_json(c->given, 3)));
        break;
    case PSYS__CONTROL_OSCILLATE:
        ok = ok && cJSON_AddStringToObject(o, "type", "oscillate")
             && cJSON_AddItemToObjectCS(o, "center", psys__vec_json(c->center, d))
             && cJSON_AddItemToObjectCS(o, "direction", psys__vec_json(c->given, d))
             && psys__add_num(o, "amplitude", c->amplitude) && psys__add_num(o, "omega", c->omega)
             && psys__add_num(o, "phase", c->phase);
        break;
    case PSYS__CONTROL_KEYFRAMES:
        ok = ok && cJSON_AddStringToObject(o, "type", "keyframes")
             && cJSON_AddItemToObjectCS(o, "frames", psys__frames_json(c->frames, c->nframes, d));
        break;
    case PSYS__CONTROL_CALLBACK:
        ok = false;
        break;
    }
    if (!ok) {
        cJSON_Delete(o);
        return NULL;
    }
    return o;
}

static bool add_planes(const psys_system *sys, cJSON *root)
{
    if (!sys->nplanes)
        return true;
    cJSON *arr = cJSON_AddArrayToObject(root, "planes");
    if (!arr)
        return false;
    for (size_t k = 0; k < sys->nplanes; k++) {
        const psys__plane *pl = &sys->planes[k];
        cJSON *o = cJSON_CreateObject();
        if (!o)
            return false;
        cJSON_AddItemToArray(arr, o);
        if (!cJSON_AddItemToObjectCS(o, "point", psys__vec_json(pl->p, sys->dim))
            || !cJSON_AddItemToObjectCS(o, "normal", psys__vec_json(pl->given_n, sys->dim))
            || !psys__add_num(o, "restitution", pl->restitution)
            || !(pl->stick ? cJSON_AddStringToObject(o, "friction", "stick") != NULL
                           : psys__add_num(o, "friction", pl->friction) != NULL)
            || !cJSON_AddStringToObject(o, "response", pl->response == PSYS_RESPONSE_DISPLACE ? "displace" : "rollback"))
            return false;
        bool directional = false;
        for (int c = 0; c < sys->dim; c++)
            directional |= pl->given_forward[c] != 0;
        if (directional && (!cJSON_AddItemToObjectCS(o, "forward", psys__vec_json(pl->given_forward, sys->dim))
                            || !psys__add_num(o, "backward_friction", pl->backward_friction)))
            return false;
    }
    return true;
}

static bool add_particles(const psys_system *sys, cJSON *root)
{
    cJSON *arr = cJSON_AddArrayToObject(root, "particles");
    if (!arr)
        return false;
    int d = sys->dim;
    for (size_t i = 0; i < sys->n; i++) {
        cJSON *o = cJSON_CreateObject();
        if (!o)
            return false;
        cJSON_AddItemToArray(arr, o);
        if ((sys->ids[i] && !cJSON_AddStringToObject(o, "id", sys->ids[i]))
            || !cJSON_AddItemToObjectCS(o, "x", psys__vec_json(sys->x + i * d, d))
            || !cJSON_AddItemToObjectCS(o, "v", psys__vec_json(sys->v + i * d, d))
            || !psys__add_num(o, "mass", sys->mass[i])
            || ((sys->flags[i] & PSYS_PARTICLE_FIXED) && !cJSON_AddTrueToObject(o, "fixed")))
            return false;
        if (i < sys->ncharge && (sys->charge[i] != 0 || signbit(sys->charge[i]))
            && !psys__add_num(o, "charge", sys->charge[i]))
            return false;
        if (sys->flags[i] & PSYS_PARTICLE_CONTROLLED) {
            size_t k = psys__controller_find(sys, i);
            cJSON *c = control_json(&sys->ctrl[k], d);
            if (!c || !cJSON_AddItemToObjectCS(o, "control", c)) {
                cJSON_Delete(c);
                return false;
            }
        }
    }
    return true;
}

static psys_status add_forces(const psys_system *sys, cJSON *root, psys_error *err)
{
    cJSON *arr = cJSON_AddArrayToObject(root, "forces");
    if (!arr)
        return psys__fail(err, PSYS_ERR_NOMEM, "out of memory saving the scene");
    for (size_t i = 0; i < sys->nforces; i++) {
        const psys__force_io *io = NULL;
        for (const psys__force_io *const *t = psys__force_types; *t; t++)
            if ((*t)->cls == sys->forces[i].cls)
                io = *t;
        if (!io)
            return psys__fail(err, PSYS_ERR_UNSUPPORTED,
                              "force \"%s\" was added through the C API and has no scene form",
                              sys->forces[i].cls->name);
        psys_status st = io->save(sys, sys->forces[i].data, arr);
        if (st != PSYS_OK)
            return psys__fail(err, st, "out of memory saving the scene");
    }
    return PSYS_OK;
}

char *psys_scene_to_string(const psys_scene *scene, const psys_resume_state *resume, psys_error *err)
{
    const psys_settings *set = &scene->settings;
    const psys_system *sys = scene->sys;
    psys__ok(err);
    for (size_t k = 0; k < sys->nctrl; k++)
        if (sys->ctrl[k].kind == PSYS__CONTROL_CALLBACK) {
            psys__fail(err, PSYS_ERR_UNSUPPORTED, "particle %zu is driven by a C callback and has no scene form",
                       sys->ctrl[k].particle);
            return NULL;
        }
    cJSON *root = cJSON_CreateObject();
    bool ok = root && psys__add_num(root, "psys", 1) && psys__add_num(root, "dim", sys->dim)
              && cJSON_AddStringToObject(root, "integrator", set->integrator)
              && psys__add_num(root, "dt", set->dt)
              && (set->use_steps ? psys__add_num(root, "steps", (double)set->steps) != NULL
                                 : psys__add_num(root, "duration", set->duration) != NULL)
              && psys__add_num(root, "tolerance", set->tolerance)
              && ((set->cg_tolerance == 1e-6 && set->cg_max_iterations == 1000)
                  || (psys__add_num(root, "cg_tolerance", set->cg_tolerance)
                      && psys__add_num(root, "cg_max_iterations", (double)set->cg_max_iterations)))
              && psys__save_box(sys, root) && add_particles(sys, root);
    if (!ok) {
        cJSON_Delete(root);
        psys__fail(err, PSYS_ERR_NOMEM, "out of memory saving the scene");
        return NULL;
    }
    if (add_forces(sys, root, err) != PSYS_OK || !add_planes(sys, root)) {
        if (err && err->code == PSYS_OK)
            psys__fail(err, PSYS_ERR_NOMEM, "out of memory saving the scene");
        cJSON_Delete(root);
        return NULL;
    }
    if (set->every != 1 || set->trajectory[0] || set->energy[0] || set->render[0] || set->render_radius > 0) {
        cJSON *out = cJSON_AddObjectToObject(root, "output");
        ok = out && psys__add_num(out, "every", (double)set->every)
             && (!set->trajectory[0] || cJSON_AddStringToObject(out, "trajectory", set->trajectory))
             && (!set->energy[0] || cJSON_AddStringToObject(out, "energy", set->energy))
             && (!set->render[0] || cJSON_AddStringToObject(out, "render", set->render))
             && (!(set->render_radius > 0) || psys__add_num(out, "radius", set->render_radius));
    }
    if (ok && resume) {
        cJSON *ck = cJSON_AddObjectToObject(root, "checkpoint");
        ok = ck && psys__add_num(ck, "step", (double)resume->step)
             && psys__add_num(ck, "t", resume->t)
             && psys__add_num(ck, "base_step", (double)resume->base_step)
             && psys__add_num(ck, "base_t", resume->base_t)
             && psys__add_num(ck, "next_h", resume->next_h);
    }
    char *text = ok ? cJSON_Print(root) : NULL;
    cJSON_Delete(root);
    if (!text)
        psys__fail(err, PSYS_ERR_NOMEM, "out of memory saving the scene");
    else
        psys__ok(err);
    return text;
}
