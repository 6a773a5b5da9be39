/* Runs (docs/semantics.md#steps-and-frames): step counts, exact durations, output frames, rk45
 * landing on output times, and the clock state a checkpoint needs.
 *
 * Fixed-step time is t = base_t + (step - base_step)·dt rather than a running
 * sum, so times print cleanly and a resumed run reproduces them bit for bit. */
#include "io/scene.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

struct psys_run {
    psys_scene *scene;
    psys_system *sys;
    psys_solver *solver;
    double dt;
    long long every;
    long long step, start_step, final_step; /* final_step < 0: until t_end (rk45 by duration) */
    double start_t, t_end;
    bool by_duration;
    long long base_step;
    double base_t;
    bool adaptive;
    double frame_dt;       /* rk45: output spacing every·dt */
    double next_frame_t;   /* rk45: next output time */
    bool frame_now;
#ifdef PSYS_MPI
    psys__domain *dd;      /* the particles spread over MPI ranks (mpi/domain.c); sys is then its local system */
#endif
};

psys_run *psys_run_create(psys_scene *scene, psys_error *err)
{
    const psys_settings *set = &scene->settings;
    if (!(set->dt > 0) || !isfinite(set->dt)) {
        psys__fail(err, PSYS_ERR_INVALID, "dt must be a finite number > 0");
        return NULL;
    }
    if (set->every < 1) {
        psys__fail(err, PSYS_ERR_INVALID, "every must be at least 1");
        return NULL;
    }
    psys_run *r = calloc(1, sizeof *r);
    if (!r) {
        psys__fail(err, PSYS_ERR_NOMEM, "out of memory creating a run");
        return NULL;
    }
    r->scene = scene;
    r->sys = scene->sys;
    if (!(r->solver = psys_system_solver_create(r->sys, set->integrator, err))) {
        free(r);
        return NULL;
    }
    psys_solver_set_tolerance(r->solver, set->tolerance);
    psys_solver_set_cg(r->solver, set->cg_tolerance,
                       set->cg_max_iterations > 1000000000 ? 1000000000 : (int)set->cg_max_iterations);
    r->dt = set->dt;
    r->every = set->every;
    r->adaptive = psys_solver_is_adaptive(r->solver);
    const psys_resume_state *rs = &scene->resume;
    if (rs->present) {
        r->step = rs->step;
        r->base_step = rs->base_step;
        r->base_t = rs->base_t;
        psys_system_set_time(r->sys, rs->t);
        if (r->adaptive && rs->next_h > 0)
            psys_solver_set_next_step(r->solver, rs->next_h);
    } else {
        r->step = 0;
        r->base_step = 0;
        r->base_t = psys_system_time(r->sys);
    }
    if (r->adaptive && !(rs->present && rs->next_h > 0))
        psys_solver_set_next_step(r->solver, r->dt);
    r->start_step = r->step;
    r->start_t = psys_system_time(r->sys);
    r->by_duration = !set->use_steps;
    if (set->use_steps) {
        r->final_step = r->step + set->steps;
    } else {
        r->t_end = r->start_t + set->duration;
        if (r->adaptive) {
            r->final_step = -1;
        } else {
            double q = set->duration / r->dt;
            double n = ceil(q - 1e-9 * q);
            if (!(n <= 1e15)) { /* also NaN: duration/dt = inf makes q - 1e-9·q = inf - inf */
                psys_run_destroy(r);
                psys__fail(err, PSYS_ERR_INVALID, "duration/dt asks for more than 1e15 steps");
                return NULL;
            }
            r->final_step = r->step + (long long)n;
        }
    }
    if (r->adaptive) {
        /* Output times are base_t + j·every·dt; start at the first one after now. */
        r->frame_dt = (double)r->every * r->dt;
        double j = floor((r->start_t - r->base_t) / r->frame_dt + 1e-9) + 1;
        r->next_frame_t = r->base_t + j * r->frame_dt;
    }
    r->frame_now = true;
    psys__ok(err);
    return r;
}

void psys_run_destroy(psys_run *r)
{
    if (!r)
        return;
#ifdef PSYS_MPI
    if (r->dd) {
        psys__domain_free(r->dd); /* its solver and local system */
        free(r);
        return;
    }
#endif
    psys_solver_destroy(r->solver);
    free(r);
}

long long psys_run_step_index(const psys_run *r) { return r->step; }
long long psys_run_final_step(const psys_run *r) { return r->final_step; }
const psys_solver *psys_run_solver(const psys_run *r) { return r->solver; }

bool psys_run_done(const psys_run *r)
{
    if (r->final_step >= 0)
        return r->step >= r->final_step;
    return psys_system_time(r->sys) >= r->t_end;
}

bool psys_run_is_frame(const psys_run *r) { return r->frame_now || psys_run_done(r); }

double psys_run_progress(const psys_run *r)
{
    if (r->final_step >= 0) {
        long long total = r->final_step - r->start_step;
        return total > 0 ? (double)(r->step - r->start_step) / (double)total : 1.0;
    }
    double span = r->t_end - r->start_t;
    return span > 0 ? (psys_system_time(r->sys) - r->start_t) / span : 1.0;
}

static void nonfinite_message(psys_run *r, psys_error *err, double t_from)
{
    size_t p = psys_system_particle_of_component(r->sys, psys_solver_bad_component(r->solver));
    const char *id = psys_system_particle_id(r->sys, p);
#ifdef PSYS_MPI
    if (r->dd) { /* the particle's global index; its id is in the scene's system (rank 0) */
        p = psys__domain_bad_particle(r->dd);
        id = psys_system_particle_id(r->scene->sys, p);
    }
#endif
    char who[300];
    if (id)
        snprintf(who, sizeof who, "particle %zu (\"%s\")", p, id);
    else
        snprintf(who, sizeof who, "particle %zu", p);
    psys__fail(err, PSYS_ERR_NONFINITE,
               "the state became non-finite at step %lld (from t = %.17g), %s; stopped at the last good state",
               r->step + 1, t_from, who);
}

/* One step of the system (psys_system_advance), or of this rank's particles. */
static psys_status advance(psys_run *r, double h_max, double *h_taken)
{
#ifdef PSYS_MPI
    if (r->dd)
        return psys__domain_advance(r->dd, h_max, h_taken);
#endif
    return psys_system_advance(r->sys, r->solver, h_max, h_taken);
}

/* The failed step's message (the domain's when decomposed). */
static const char *step_error(const psys_run *r)
{
#ifdef PSYS_MPI
    if (r->dd)
        return psys__domain_last_error(r->dd);
#endif
    return psys_solver_last_error(r->solver);
}

psys_status psys_run_step(psys_run *r, psys_error *err)
{
    if (psys_run_done(r))
        return psys__fail(err, PSYS_ERR_INVALID, "the run is already complete");
    double t = psys_system_time(r->sys);
    double h;
    r->frame_now = false;
    if (!r->adaptive) {
        bool last_of_duration = r->by_duration && r->step + 1 == r->final_step;
        h = last_of_duration ? r->t_end - t : r->dt;
        if (!(h > 0))
            h = r->dt * 1e-12; /* degenerate: duration ended within rounding of the previous step */
        psys_status st = advance(r, h, NULL);
        if (st == PSYS_ERR_NONFINITE) {
            nonfinite_message(r, err, t);
            return st;
        }
        if (st != PSYS_OK)
            return psys__fail(err, st, "step %lld failed: %s", r->step + 1, step_error(r));
        r->step++;
        if (last_of_duration) {
            psys_system_set_time(r->sys, r->t_end);
            r->base_step = r->step;
            r->base_t = r->t_end;
        } else {
            psys_system_set_time(r->sys, r->base_t + (double)(r->step - r->base_step) * r->dt);
        }
        /* Controlled particles sit exactly on their paths at the printed time
         * (the solver projected them at its own t + h). */
        psys_system_apply_controllers(r->sys, psys_system_time(r->sys));
        r->frame_now = r->step % r->every == 0;
        return PSYS_OK;
    }
    double target = r->next_frame_t;
    if (r->by_duration && r->t_end < target)
        target = r->t_end;
    double h_taken;
    psys_status st = advance(r, target - t, &h_taken);
    if (st == PSYS_ERR_NONFINITE) {
        nonfinite_message(r, err, t);
        return st;
    }
    if (st != PSYS_OK)
        return psys__fail(err, st, "step %lld failed: %s", r->step + 1, step_error(r));
    r->step++;
    if (h_taken >= target - t) {
        psys_system_set_time(r->sys, target); /* land exactly, not t + h rounded */
        psys_system_apply_controllers(r->sys, target);
        if (target == r->next_frame_t) {
            r->frame_now = true;
            double j = floor((target - r->base_t) / r->frame_dt + 0.5) + 1;
            r->next_frame_t = r->base_t + j * r->frame_dt;
        }
    }
    return PSYS_OK;
}

psys_resume_state psys_run_resume_state(const psys_run *r)
{
    psys_resume_state rs;
    memset(&rs, 0, sizeof rs);
    rs.present = true;
    rs.step = r->step;
    rs.t = psys_system_time(r->sys);
    rs.base_step = r->base_step;
    rs.base_t = r->base_t;
    rs.next_h = psys_solver_next_step(r->solver);
    return rs;
}

#ifdef PSYS_MPI
#include "psys/psys_mpi.h"

/* mpi/domain.c (needs MPI_Comm, so not in internal.h) */
psys_status psys__domain_create(psys_system *g, const char *integrator, double tol, double cg_tol, int cg_maxit,
                                double h_next, MPI_Comm comm, psys__domain **out, psys_error *err);

psys_status psys_run_decompose(psys_run *r, MPI_Comm comm, psys_error *err)
{
    int size = 1;
    if (comm == MPI_COMM_NULL || MPI_Comm_size(comm, &size) != MPI_SUCCESS)
        return psys__fail(err, PSYS_ERR_INVALID, "no MPI communicator");
    if (r->dd)
        return psys__fail(err, PSYS_ERR_INVALID, "the run is already decomposed");
    if (size <= 1) {
        psys__ok(err);
        return PSYS_OK;
    }
    const psys_settings *set = &r->scene->settings;
    psys__domain *D = NULL;
    psys_status st = psys__domain_create(r->sys, set->integrator, set->tolerance, set->cg_tolerance,
                                         set->cg_max_iterations > 1000000000 ? 1000000000 : (int)set->cg_max_iterations,
                                         psys_solver_next_step(r->solver), comm, &D, err);
    if (st != PSYS_OK)
        return st;
    psys_solver_destroy(r->solver);
    r->dd = D;
    r->sys = psys__domain_local(D);
    r->solver = psys__domain_solver(D);
    int rank = 0;
    MPI_Comm_rank(comm, &rank);
    if (rank != 0)
        psys__system_release(r->scene->sys); /* only rank 0 keeps the whole system, for output */
    psys__ok(err);
    return PSYS_OK;
}

psys_status psys_run_gather(psys_run *r, psys_error *err)
{
    if (!r->dd) {
        psys__ok(err);
        return PSYS_OK;
    }
    psys_status st = psys__domain_gather(r->dd, r->scene->sys);
    if (st != PSYS_OK)
        return psys__fail(err, st, "%s", psys__domain_last_error(r->dd));
    psys__ok(err);
    return PSYS_OK;
}

void psys_run_domain_counts(const psys_run *r, size_t *owned, size_t *ghosts, size_t *redistributions)
{
    if (owned)
        *owned = r->dd ? psys__domain_owned(r->dd) : 0;
    if (ghosts)
        *ghosts = r->dd ? psys__domain_ghosts(r->dd) : 0;
    if (redistributions)
        *redistributions = r->dd ? psys__domain_redistributions(r->dd) : 0;
}

void psys_run_domain_bonds(const psys_run *r, size_t *computed, size_t *sent)
{
    if (computed)
        *computed = r->dd ? psys__domain_bond_terms(r->dd) : 0;
    if (sent)
        *sent = r->dd ? psys__domain_bond_sent(r->dd) : 0;
}

void psys_run_domain_grid(const psys_run *r, int parts[3])
{
    if (r->dd) {
        psys__domain_parts(r->dd, parts);
        return;
    }
    parts[0] = parts[1] = parts[2] = 1;
}
#endif
