/* The viewer's editable system (notes §5: build by clicking, drag with a
 * mouse spring). The document is the scene itself: additions, pins and
 * motors go straight through the library's API; removals (which the library
 * has no call for) edit the scene's JSON form (psys_scene_to_string) and
 * load it again, which the round-trip contract
 * (docs/scene-format.md#saving-a-scene-back) makes exact.
 * Undo keeps the scene text (and clock) from before each edit. */
#include "view_internal.h"

#include <cjson/cJSON.h>
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define UNDO_MAX 100
static const double TWO_PI = 6.28318530717958647692;
static const char EMPTY_SCENE[] = "{\"psys\": 1, \"dim\": 2}";

/* An undo snapshot: the scene text and the clock it was taken at. */
typedef struct snapshot {
    char *text;
    double t;
} snapshot;

static void say(vw_model *m, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;
static void say(vw_model *m, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(m->message, sizeof m->message, fmt, ap);
    va_end(ap);
}

static char *dupstr(const char *s)
{
    size_t n = strlen(s) + 1;
    char *p = malloc(n);
    if (p)
        memcpy(p, s, n);
    return p;
}

/* ---------------------------------------------------------------- solver */

int vw_model_reset_solver(vw_model *m)
{
    psys_solver_destroy(m->solver);
    m->solver = NULL;
    psys_settings *set = psys_scene_settings(m->scene);
    psys_error err;
    m->solver = psys_system_solver_create(m->sys, set->integrator, &err);
    if (!m->solver) {
        say(m, "%s", err.message);
        return -1;
    }
    psys_solver_set_tolerance(m->solver, set->tolerance);
    psys_solver_set_cg(m->solver, set->cg_tolerance,
                       set->cg_max_iterations > 1000000000 ? 1000000000 : (int)set->cg_max_iterations);
    if (psys_solver_is_adaptive(m->solver))
        psys_solver_set_next_step(m->solver, set->dt);
    return 0;
}

psys_status vw_model_step(vw_model *m, double h, double *taken)
{
    *taken = 0;
    if (m->failed || !m->solver)
        return PSYS_ERR_INVALID;
    psys_status st = psys_system_advance(m->sys, m->solver, h, taken);
    if (st != PSYS_OK) {
        m->failed = true;
        if (st == PSYS_ERR_NONFINITE) {
            size_t k = psys_solver_bad_component(m->solver);
            say(m, "the state became non-finite at t = %.6g s (particle %zu): paused; R resets, Ctrl+Z undoes",
                psys_system_time(m->sys), psys_system_particle_of_component(m->sys, k));
        } else {
            say(m, "the step failed at t = %.6g s: %s", psys_system_time(m->sys), psys_solver_last_error(m->solver));
        }
        return st;
    }
    m->steps++;
    return PSYS_OK;
}

/* ------------------------------------------------------------- documents */

/* Geometric-mean mass and mean spring constants: what new parts get. */
static void default_params(vw_model *m)
{
    size_t n = psys_system_count(m->sys);
    const double *mass = psys_system_masses(m->sys);
    double s = 0;
    for (size_t i = 0; i < n; i++)
        s += log(mass[i]);
    m->params.mass = n ? exp(s / (double)n) : 1.0;
    size_t ns = psys_system_spring_count(m->sys);
    double ks = 0, kd = 0;
    for (size_t k = 0; k < ns; k++) {
        double a, b;
        if (psys_system_spring(m->sys, k, NULL, NULL, &a, &b, NULL) == PSYS_OK)
            ks += a, kd += b;
    }
    if (ns && ks > 0) {
        m->params.ks = ks / (double)ns;
        m->params.kd = kd / (double)ns;
    } else {
        m->params.ks = 100 * m->params.mass;
        m->params.kd = 0.2 * sqrt(m->params.ks * m->params.mass);
    }
}

/* Replace the scene by the one in text, its clock set to t. */
static int rebuild(vw_model *m, const char *text, double t)
{
    psys_error err;
    psys_scene *s = psys_scene_load_string(text, strlen(text), &err);
    if (!s) {
        say(m, "%s", err.message);
        return -1;
    }
    psys_solver_destroy(m->solver);
    m->solver = NULL;
    psys_scene_destroy(m->scene);
    m->scene = s;
    m->sys = psys_scene_system(s);
    psys_system_set_time(m->sys, t);
    psys_system_apply_controllers(m->sys, t);
    m->failed = false;
    return vw_model_reset_solver(m);
}

/* The scene as text without the viewer's mouse spring. */
static char *snapshot_text(vw_model *m)
{
    bool regrab = m->grabbing && !m->grab_kinematic;
    size_t gp = m->grab_particle;
    double target[3];
    memcpy(target, m->grab_target, sizeof target);
    if (regrab)
        vw_model_release(m);
    psys_error err;
    char *text = psys_scene_to_string(m->scene, NULL, &err);
    if (!text)
        say(m, "%s", err.message);
    if (regrab)
        vw_model_grab(m, gp, target);
    return text;
}

static int push_undo(vw_model *m)
{
    vw_model_release(m);
    char *text = snapshot_text(m);
    if (!text)
        return -1;
    snapshot *u = (snapshot *)m->undo;
    if (m->nundo == UNDO_MAX) {
        free(u[0].text);
        memmove(u, u + 1, (UNDO_MAX - 1) * sizeof *u);
        m->nundo--;
    }
    u[m->nundo].text = text;
    u[m->nundo].t = psys_system_time(m->sys);
    m->nundo++;
    return 0;
}

/* An edit failed after push_undo: drop the snapshot again. */
static void drop_undo(vw_model *m)
{
    snapshot *u = (snapshot *)m->undo;
    if (m->nundo) {
        m->nundo--;
        free(u[m->nundo].text);
    }
}

int vw_model_open(vw_model *m, const char *path)
{
    memset(m, 0, sizeof *m);
    m->undo = calloc(UNDO_MAX, sizeof(snapshot));
    if (!m->undo) {
        say(m, "out of memory");
        return -1;
    }
    psys_error err;
    m->scene = path ? psys_scene_load_file(path, &err) : psys_scene_load_string(EMPTY_SCENE, strlen(EMPTY_SCENE), &err);
    if (!m->scene) {
        say(m, "%s", err.message);
        return -1;
    }
    m->sys = psys_scene_system(m->scene);
    m->dim = psys_system_dim(m->sys);
    const psys_resume_state *rs = psys_scene_resume_state(m->scene);
    if (rs->present)
        psys_system_set_time(m->sys, rs->t);
    m->initial = psys_scene_to_string(m->scene, NULL, &err);
    if (!m->initial) {
        say(m, "%s", err.message);
        return -1;
    }
    default_params(m);
    return vw_model_reset_solver(m);
}

void vw_model_close(vw_model *m)
{
    psys_solver_destroy(m->solver);
    psys_scene_destroy(m->scene);
    free(m->initial);
    free(m->gravity_stash);
    snapshot *u = (snapshot *)m->undo;
    for (size_t k = 0; k < m->nundo; k++)
        free(u[k].text);
    free(m->undo);
    memset(m, 0, sizeof *m);
}

/* ---------------------------------------------------------------- edits */

int vw_model_add_particle(vw_model *m, const double *x, size_t *index)
{
    if (push_undo(m) != 0)
        return -1;
    size_t i;
    if (psys_system_add_particle(m->sys, x, NULL, m->params.mass, NULL, &i) != PSYS_OK) {
        say(m, "%s", psys_system_last_error(m->sys));
        drop_undo(m);
        return -1;
    }
    if (index)
        *index = i;
    return vw_model_reset_solver(m);
}

static int add_spring(vw_model *m, size_t a, size_t b)
{
    if (psys_system_add_spring(m->sys, a, b, m->params.ks, m->params.kd, -1) != PSYS_OK) {
        say(m, "%s", psys_system_last_error(m->sys));
        return -1;
    }
    return vw_model_reset_solver(m);
}

int vw_model_add_spring(vw_model *m, size_t a, size_t b)
{
    if (a == b || push_undo(m) != 0)
        return -1;
    if (add_spring(m, a, b) != 0) {
        drop_undo(m);
        return -1;
    }
    return 0;
}

int vw_model_add_connected(vw_model *m, size_t a, const double *x)
{
    if (push_undo(m) != 0)
        return -1;
    size_t i;
    if (psys_system_add_particle(m->sys, x, NULL, m->params.mass, NULL, &i) != PSYS_OK) {
        say(m, "%s", psys_system_last_error(m->sys));
        drop_undo(m);
        return -1;
    }
    return add_spring(m, a, i);
}

int vw_model_toggle_pin(vw_model *m, size_t i)
{
    if (i >= psys_system_count(m->sys) || push_undo(m) != 0)
        return -1;
    psys_status st;
    if (psys_system_is_controlled(m->sys, i)) {
        st = psys_system_release(m->sys, i);
        if (st == PSYS_OK)
            st = psys_system_set_fixed(m->sys, i, true);
    } else {
        st = psys_system_set_fixed(m->sys, i, !psys_system_is_fixed(m->sys, i));
    }
    if (st != PSYS_OK) {
        say(m, "%s", psys_system_last_error(m->sys));
        return -1;
    }
    return vw_model_reset_solver(m);
}

int vw_model_toggle_motor(vw_model *m, size_t i, double radius, const double *axis)
{
    if (i >= psys_system_count(m->sys) || push_undo(m) != 0)
        return -1;
    psys_status st;
    if (psys_system_is_controlled(m->sys, i)) {
        st = psys_system_release(m->sys, i);
    } else {
        if (psys_system_is_fixed(m->sys, i))
            psys_system_set_fixed(m->sys, i, false);
        double c[3] = {0, 0, 0};
        memcpy(c, psys_system_positions(m->sys) + i * (size_t)m->dim, (size_t)m->dim * sizeof *c);
        double t = psys_system_time(m->sys), omega = TWO_PI; /* one turn a second, starting at c + R·u now */
        st = psys_system_control_circle(m->sys, i, c, radius, omega, -omega * t, m->dim == 3 ? axis : NULL);
        if (st == PSYS_OK)
            psys_system_apply_controllers(m->sys, t);
    }
    if (st != PSYS_OK) {
        say(m, "%s", psys_system_last_error(m->sys));
        return -1;
    }
    return vw_model_reset_solver(m);
}

/* Edit the scene's JSON form with fn and load it back (one undo step). */
static int edit_json(vw_model *m, int (*fn)(vw_model *m, cJSON *root, size_t arg), size_t arg)
{
    if (push_undo(m) != 0)
        return -1;
    snapshot *u = (snapshot *)m->undo;
    cJSON *root = cJSON_Parse(u[m->nundo - 1].text);
    if (!root) {
        say(m, "out of memory");
        drop_undo(m);
        return -1;
    }
    int rc = fn(m, root, arg);
    char *text = rc == 0 ? cJSON_PrintUnformatted(root) : NULL;
    cJSON_Delete(root);
    if (!text) {
        if (rc == 0)
            say(m, "out of memory");
        drop_undo(m);
        return -1;
    }
    rc = rebuild(m, text, psys_system_time(m->sys));
    free(text);
    if (rc != 0) { /* back to the snapshot */
        rebuild(m, u[m->nundo - 1].text, u[m->nundo - 1].t);
        drop_undo(m);
        return -1;
    }
    return 0;
}

/* A particle reference (index or id): 1 if it names the removed particle
 * `gone` (whose id is gone_id, may be NULL); later indices move down one. */
static int fix_ref(cJSON *ref, size_t gone, const char *gone_id)
{
    if (cJSON_IsString(ref))
        return gone_id && strcmp(ref->valuestring, gone_id) == 0;
    if (cJSON_IsNumber(ref)) {
        double v = ref->valuedouble;
        if (v == (double)gone)
            return 1;
        if (v > (double)gone)
            cJSON_SetNumberValue(ref, v - 1);
    }
    return 0;
}

static int remove_particle_json(vw_model *m, cJSON *root, size_t i)
{
    cJSON *parts = cJSON_GetObjectItemCaseSensitive(root, "particles");
    cJSON *p = cJSON_GetArrayItem(parts, (int)i);
    if (!p) {
        say(m, "no particle %zu", i);
        return -1;
    }
    cJSON *id = cJSON_GetObjectItemCaseSensitive(p, "id");
    char *gone_id = cJSON_IsString(id) ? dupstr(id->valuestring) : NULL;
    cJSON_DeleteItemFromArray(parts, (int)i);
    cJSON *forces = cJSON_GetObjectItemCaseSensitive(root, "forces");
    static const char *const keys[] = {"a", "b", "particle"};
    for (int k = cJSON_GetArraySize(forces) - 1; k >= 0; k--) {
        cJSON *f = cJSON_GetArrayItem(forces, k);
        int refers = 0;
        for (size_t q = 0; q < sizeof keys / sizeof *keys; q++) {
            cJSON *r = cJSON_GetObjectItemCaseSensitive(f, keys[q]);
            if (r)
                refers |= fix_ref(r, i, gone_id);
        }
        cJSON *list = cJSON_GetObjectItemCaseSensitive(f, "particles");
        cJSON *r;
        cJSON_ArrayForEach(r, list)
        {
            refers |= fix_ref(r, i, gone_id);
        }
        if (refers)
            cJSON_DeleteItemFromArray(forces, k);
    }
    free(gone_id);
    return 0;
}

static int remove_spring_json(vw_model *m, cJSON *root, size_t k)
{
    cJSON *forces = cJSON_GetObjectItemCaseSensitive(root, "forces");
    size_t seen = 0;
    for (int f = 0; f < cJSON_GetArraySize(forces); f++) {
        cJSON *type = cJSON_GetObjectItemCaseSensitive(cJSON_GetArrayItem(forces, f), "type");
        if (cJSON_IsString(type) && strcmp(type->valuestring, "spring") == 0 && seen++ == k) {
            cJSON_DeleteItemFromArray(forces, f);
            return 0;
        }
    }
    say(m, "no spring %zu", k);
    return -1;
}

int vw_model_delete_particle(vw_model *m, size_t i)
{
    return edit_json(m, remove_particle_json, i);
}

int vw_model_delete_spring(vw_model *m, size_t k)
{
    return edit_json(m, remove_spring_json, k);
}

int vw_model_undo(vw_model *m)
{
    if (!m->nundo)
        return 1;
    vw_model_release(m);
    bool gravity = vw_model_has_gravity(m);
    snapshot *u = (snapshot *)m->undo;
    snapshot s = u[m->nundo - 1];
    if (rebuild(m, s.text, s.t) != 0)
        return -1;
    m->nundo--;
    free(s.text);
    /* gravity is a setting, not an edit: keep it as it is now */
    if (vw_model_has_gravity(m) != gravity)
        vw_model_toggle_gravity(m);
    return 0;
}

int vw_model_reset(vw_model *m)
{
    if (push_undo(m) != 0)
        return -1;
    if (rebuild(m, m->initial, 0.0) != 0) {
        drop_undo(m);
        return -1;
    }
    m->steps = 0;
    return 0;
}

bool vw_model_has_gravity(const vw_model *m)
{
    size_t nf = psys_system_force_count(m->sys);
    for (size_t f = 0; f < nf; f++)
        if (psys_system_force_class(m->sys, f) == &psys_gravity_class)
            return true;
    return false;
}

static int toggle_gravity_json(vw_model *m, cJSON *root, size_t unused)
{
    (void)unused;
    cJSON *forces = cJSON_GetObjectItemCaseSensitive(root, "forces");
    if (!forces && !(forces = cJSON_AddArrayToObject(root, "forces"))) {
        say(m, "out of memory");
        return -1;
    }
    cJSON *removed = cJSON_CreateArray();
    if (!removed) {
        say(m, "out of memory");
        return -1;
    }
    for (int f = cJSON_GetArraySize(forces) - 1; f >= 0; f--) {
        cJSON *type = cJSON_GetObjectItemCaseSensitive(cJSON_GetArrayItem(forces, f), "type");
        if (cJSON_IsString(type) && strcmp(type->valuestring, "gravity") == 0)
            cJSON_AddItemToArray(removed, cJSON_DetachItemFromArray(forces, f));
    }
    if (cJSON_GetArraySize(removed) > 0) {
        char *s = cJSON_PrintUnformatted(removed);
        cJSON_Delete(removed);
        if (!s) {
            say(m, "out of memory");
            return -1;
        }
        free(m->gravity_stash);
        m->gravity_stash = s;
        return 0;
    }
    cJSON_Delete(removed);
    cJSON *back = m->gravity_stash ? cJSON_Parse(m->gravity_stash) : cJSON_Parse("[{\"type\": \"gravity\"}]");
    if (!back) {
        say(m, "out of memory");
        return -1;
    }
    cJSON *g;
    while ((g = cJSON_DetachItemFromArray(back, 0)) != NULL)
        cJSON_InsertItemInArray(forces, 0, g);
    cJSON_Delete(back);
    return 0;
}

int vw_model_toggle_gravity(vw_model *m)
{
    /* not an undo step: edit_json's snapshot is dropped again on success */
    if (edit_json(m, toggle_gravity_json, 0) != 0)
        return -1;
    drop_undo(m);
    return 0;
}

int vw_model_set_integrator(vw_model *m, size_t k)
{
    const char *name = psys_solver_name_at(k);
    if (!name)
        return -1;
    psys_settings *set = psys_scene_settings(m->scene);
    snprintf(set->integrator, sizeof set->integrator, "%s", name);
    return vw_model_reset_solver(m);
}

int vw_model_set_dt(vw_model *m, double dt)
{
    if (!(dt > 0) || !isfinite(dt))
        return -1;
    psys_scene_settings(m->scene)->dt = dt;
    if (m->solver && psys_solver_is_adaptive(m->solver))
        psys_solver_set_next_step(m->solver, dt);
    return 0;
}

int vw_model_save(vw_model *m, const char *path)
{
    char *text = snapshot_text(m);
    if (!text)
        return -1;
    size_t n = strlen(path) + 64;
    char *tmp = malloc(n);
    if (!tmp) {
        free(text);
        say(m, "out of memory");
        return -1;
    }
    snprintf(tmp, n, "%s.psys-tmp-%ld", path, (long)getpid());
    FILE *fp = fopen(tmp, "w");
    int rc = -1;
    if (!fp) {
        say(m, "%s: cannot write: %s", path, strerror(errno));
    } else {
        bool ok = fputs(text, fp) >= 0 && fputc('\n', fp) != EOF;
        ok = (fclose(fp) == 0) && ok;
        if (!ok)
            say(m, "%s: write failed: %s", path, strerror(errno));
        else if (rename(tmp, path) != 0)
            say(m, "%s: cannot rename into place: %s", path, strerror(errno));
        else
            rc = 0;
        if (rc != 0)
            remove(tmp);
    }
    free(tmp);
    free(text);
    return rc;
}

/* ------------------------------------------------------------ mouse spring */

int vw_model_grab(vw_model *m, size_t i, const double *target)
{
    vw_model_release(m);
    if (i >= psys_system_count(m->sys))
        return -1;
    memset(m->grab_target, 0, sizeof m->grab_target);
    memcpy(m->grab_target, target, (size_t)m->dim * sizeof *target);
    m->grab_particle = i;
    if (psys_system_is_controlled(m->sys, i)) {
        say(m, "particle %zu is a motor: M releases it first", i);
        return -1;
    }
    if (psys_system_is_fixed(m->sys, i)) {
        /* an anchor is not integrated: moving it directly is safe */
        m->grabbing = m->grab_kinematic = true;
        psys_system_set_particle(m->sys, i, target, NULL);
        return 0;
    }
    /* Stiff enough to pull the particle against its springs, soft enough
     * for an explicit solver at the scene's dt (ω·dt <= 0.5). */
    double mass = psys_system_masses(m->sys)[i];
    double ks = 400 * mass;
    size_t ns = psys_system_spring_count(m->sys);
    double attached = 0;
    for (size_t k = 0; k < ns; k++) {
        size_t a, b;
        double sk;
        if (psys_system_spring(m->sys, k, &a, &b, &sk, NULL, NULL) == PSYS_OK && (a == i || b == i))
            attached += sk;
    }
    if (attached > ks)
        ks = attached;
    double dt = psys_scene_settings(m->scene)->dt;
    double cap = mass * (0.5 / dt) * (0.5 / dt);
    if (ks > cap)
        ks = cap;
    double kd = 1.4 * sqrt(ks * mass);
    if (psys_system_add_mouse_spring(m->sys, i, m->grab_target, ks, kd, &m->grab_handle) != PSYS_OK) {
        say(m, "%s", psys_system_last_error(m->sys));
        return -1;
    }
    m->grab_ks = ks;
    m->grab_kd = kd;
    m->grabbing = true;
    m->grab_kinematic = false;
    return 0;
}

void vw_model_grab_move(vw_model *m, const double *target)
{
    if (!m->grabbing)
        return;
    memcpy(m->grab_target, target, (size_t)m->dim * sizeof *target);
    if (m->grab_kinematic)
        psys_system_set_particle(m->sys, m->grab_particle, target, NULL);
    else
        psys_system_mouse_set_target(m->sys, m->grab_handle, target, NULL);
}

void vw_model_release(vw_model *m)
{
    if (!m->grabbing)
        return;
    if (!m->grab_kinematic)
        psys_system_remove_force(m->sys, m->grab_handle);
    m->grabbing = m->grab_kinematic = false;
}

void vw_model_counts(const vw_model *m, size_t *fixed, size_t *controlled)
{
    size_t n = psys_system_count(m->sys), nf = 0, nc = 0;
    for (size_t i = 0; i < n; i++) {
        nf += psys_system_is_fixed(m->sys, i);
        nc += psys_system_is_controlled(m->sys, i);
    }
    *fixed = nf;
    *controlled = nc;
}
