/* The output files of `psys run`: opened up front, written frame by frame,
 * committed (renamed into place) at the end. */
#include "run_outputs.h"

#include <stdlib.h>
#include <string.h>

/* ---------------------------------------------------------------- frames for pictures */

long long frames_due(frame_clock *c, double t)
{
    long long n = 0;
    while (c->t0 + (double)c->next / c->fps <= t + 1e-9 / c->fps) {
        c->next++;
        n++;
    }
    return n;
}

/* ---------------------------------------------------------------- energy plot */

#define ENERGY_MAX_SAMPLES (1u << 20)

/* Room for one more sample; 0 when out of memory (e->oom set). */
static int energy_grow(energy_series *e)
{
    size_t nc = e->cap ? 2 * e->cap : 1024;
    double *arr[4] = {e->t, e->ke, e->pe, e->total};
    for (int j = 0; j < 4; j++) {
        double *q = realloc(arr[j], nc * sizeof *q);
        if (!q) {
            e->oom = 1;
            return 0;
        }
        arr[j] = q;
        switch (j) {
        case 0: e->t = q; break;
        case 1: e->ke = q; break;
        case 2: e->pe = q; break;
        default: e->total = q; break;
        }
    }
    e->cap = nc;
    return 1;
}

/* A long run's plot keeps a bounded number of samples: when full, every
 * other one is dropped and from then on only every stride-th is taken. */
static void energy_add(energy_series *e, const psys_system *sys)
{
    if (e->oom)
        return;
    if (e->stride > 1 && (e->skip++ % e->stride) != 0)
        return;
    if (e->n == ENERGY_MAX_SAMPLES) { /* keep every other sample from now on */
        size_t k = 0;
        for (size_t i = 0; i < e->n; i += 2, k++) {
            e->t[k] = e->t[i];
            e->ke[k] = e->ke[i];
            e->pe[k] = e->pe[i];
            e->total[k] = e->total[i];
        }
        e->n = k;
        e->stride = e->stride ? 2 * e->stride : 2;
        e->skip = 1;
    }
    if (e->n == e->cap && !energy_grow(e))
        return;
    double ke = psys_system_kinetic_energy(sys), pe = psys_system_potential_energy(sys);
    e->t[e->n] = psys_system_time(sys);
    e->ke[e->n] = ke;
    e->pe[e->n] = pe;
    e->total[e->n] = ke + pe;
    e->n++;
}

static void energy_free(energy_series *e)
{
    free(e->t);
    free(e->ke);
    free(e->pe);
    free(e->total);
    memset(e, 0, sizeof *e);
}

static int energy_plot(energy_series *e, outfile *o, const picture_opts *pic, const char *source)
{
    if (e->oom) {
        cli_error("--plot %s: out of memory", o->path ? o->path : "");
        outfile_abort(o);
        return -1;
    }
    plot_series s[3] = {{"kinetic", e->t, e->ke, e->n}, {"potential", e->t, e->pe, e->n},
                        {"total", e->t, e->total, e->n}};
    char title[300];
    const char *base = strrchr(source, '/') ? strrchr(source, '/') + 1 : source;
    snprintf(title, sizeof title, "%s: energy", base);
    plot_spec spec = {pic->width, pic->height, title, "t (s)", "energy (J)"};
    if (plot_write_png(o->fp, &spec, s, 3) != 0) {
        cli_error("--plot: cannot draw or write the plot");
        outfile_abort(o);
        return -1;
    }
    return outfile_commit(o);
}

/* ---------------------------------------------------------------- opening */

/* Two outputs written to one file would silently clobber each other, and an
 * output naming the scene read would replace it (a checkpoint may: it is a
 * scene, and `--resume ck.json --checkpoint ck.json` goes on in place).
 * -1 (message printed) on such a clash. */
static int check_distinct(const run_opts *o, const char *traj_path, const char *energy_path,
                          const char *render_path)
{
    const char *paths[5] = {traj_path, energy_path, o->checkpoint, render_path, o->plot};
    static const char *const what[5] = {"the trajectory", "the energy file", "the checkpoint", "the picture",
                                        "the plot"};
    const char *inputs[2] = {o->scene && strcmp(o->scene, "-") != 0 ? o->scene : NULL, o->resume};
    for (int i = 0; i < 5; i++) {
        for (int j = i + 1; j < 5; j++)
            if (cli_same_file(paths[i], paths[j])) {
                cli_error("%s: the trajectory, energy, checkpoint, render and plot files must be different files",
                          paths[i]);
                return -1;
            }
        for (int k = 0; k < 2 && i != 2; k++)
            if (cli_same_file(paths[i], inputs[k])) {
                cli_error("%s: %s would replace the %s it reads", paths[i], what[i], k ? "checkpoint" : "scene");
                return -1;
            }
    }
    return 0;
}

/* VTP/VTK: out->stem, and the .pvd series' path into *pvd (to free); -1
 * (message printed) when out of memory. */
static int vtk_paths(run_outputs *out, const char *trajectory, char **pvd)
{
    size_t stem_len = strlen(trajectory) - 4;
    out->stem = malloc(stem_len + 1);
    *pvd = malloc(stem_len + 5);
    if (!out->stem || !*pvd) {
        free(*pvd);
        *pvd = NULL;
        cli_error("out of memory");
        return -1;
    }
    memcpy(out->stem, trajectory, stem_len);
    out->stem[stem_len] = '\0';
    snprintf(*pvd, stem_len + 5, "%s.pvd", out->stem);
    return 0;
}

static void write_headers(run_outputs *out, int dim)
{
    if (out->fmt == TRAJ_CSV)
        psys_csv_write_trajectory_header(out->traj.fp, dim);
    if (out->fmt == TRAJ_VTP || out->fmt == TRAJ_VTK)
        psys_pvd_write_header(out->traj.fp);
    if (out->energy.fp)
        psys_csv_write_energy_header(out->energy.fp);
}

int run_outputs_open(run_outputs *out, const run_opts *o, const psys_settings *set, const picture_opts *pic,
                     int dim)
{
    memset(out, 0, sizeof *out);
    out->pic = pic;
    out->set = set;
    out->fmt = pic->traj;
    out->label = o->out ? "--out" : "output.trajectory";
    out->render_label = run_options_render_label(o);
    const char *traj_path = set->trajectory[0] ? set->trajectory : NULL;
    char *pvd = NULL;
    if ((out->fmt == TRAJ_VTP || out->fmt == TRAJ_VTK) && vtk_paths(out, set->trajectory, &pvd) != 0)
        return -1;
    if (pvd)
        traj_path = pvd;
    const char *render_path = set->render[0] && pic->kind != SINK_PATTERN ? set->render : NULL;
    if (check_distinct(o, traj_path, set->energy[0] ? set->energy : NULL, render_path) != 0) {
        free(pvd);
        return -1;
    }
    const char *energy_label = o->energy ? "--energy" : "output.energy";
    int bad = (traj_path && outfile_open(&out->traj, traj_path, out->label) != 0)
              || (set->energy[0] && outfile_open(&out->energy, set->energy, energy_label) != 0)
              || (o->checkpoint && outfile_open(&out->checkpoint, o->checkpoint, "--checkpoint") != 0)
              || (o->plot && outfile_open(&out->plot_file, o->plot, "--plot") != 0);
    free(pvd);
    if (!bad && set->render[0]
        && !(out->snk = sink_open(set->render, out->render_label, pic->width, pic->height, pic->fps)))
        bad = 1;
    if (bad)
        return -1;
    out->checkpoint_on = o->checkpoint != NULL;
    out->plot_on = o->plot != NULL;
    out->still = out->snk && !sink_takes_frames(out->snk);
    write_headers(out, dim);
    return 0;
}

void run_outputs_abort(run_outputs *out)
{
    outfile_abort(&out->traj);
    outfile_abort(&out->energy);
    outfile_abort(&out->checkpoint);
    outfile_abort(&out->plot_file);
    sink_abort(out->snk);
    out->snk = NULL;
    renderer_destroy(out->ren);
    out->ren = NULL;
    free(out->stem);
    out->stem = NULL;
    energy_free(&out->plot);
}

/* ---------------------------------------------------------------- pictures */

bool run_outputs_takes_frames(const run_outputs *out) { return out->snk && sink_takes_frames(out->snk); }

/* A renderer for the picture options, framing b (or sys's current state when b is NULL or empty). */
static renderer *make_renderer(const picture_opts *pic, const psys_settings *set, const psys_system *sys,
                               const bounds *b)
{
    bounds now;
    if (!b || !b->any) {
        bounds_init(&now, &pic->cam, pic->width, pic->height);
        bounds_add_system(&now, sys);
        b = &now;
    }
    camera cam;
    camera_setup(&cam, &pic->cam, pic->width, pic->height, b);
    double radius = set->render_radius > 0 ? set->render_radius : render_auto_radius(sys, &cam);
    return renderer_create(pic->width, pic->height, &cam, radius);
}

int run_outputs_frame_video(run_outputs *out, const psys_system *sys, const bounds *b)
{
    if (!(out->ren = make_renderer(out->pic, out->set, sys, b))) {
        cli_error("%s: out of memory for a %dx%d picture", out->render_label, out->pic->width, out->pic->height);
        return 1;
    }
    return 0;
}

/* Draw the current state once and hand it to the sink as the next k frames;
 * 1 (message printed) on failure. */
static int draw_frames(renderer *ren, sink *snk, const psys_system *sys, long long k, const char *label)
{
    if (k <= 0)
        return 0;
    if (renderer_draw(ren, sys) != 0) {
        cli_error("%s: out of memory drawing a frame", label);
        return 1;
    }
    for (; k > 0; k--)
        if (sink_frame(snk, ren) != 0)
            return 1;
    return 0;
}

int run_outputs_first_pictures(run_outputs *out, const psys_system *sys)
{
    const picture_opts *pic = out->pic;
    out->clock = (frame_clock){psys_system_time(sys), pic->fps, 0};
    /* The single PNG is framed at the end: by the initial state (fit=start)
     * or by the frames a video would have shown, gathered on the way. */
    bounds_init(&out->still_bounds, &pic->cam, pic->width, pic->height);
    if (out->still) {
        bounds_add_system(&out->still_bounds, sys);
        frames_due(&out->clock, psys_system_time(sys));
    }
    if (out->ren)
        return draw_frames(out->ren, out->snk, sys, frames_due(&out->clock, psys_system_time(sys)),
                           out->render_label);
    return 0;
}

int run_outputs_pictures(run_outputs *out, const psys_system *sys)
{
    if (out->still && !out->pic->cam.fit_start && frames_due(&out->clock, psys_system_time(sys)) > 0)
        bounds_add_system(&out->still_bounds, sys);
    if (out->ren)
        return draw_frames(out->ren, out->snk, sys, frames_due(&out->clock, psys_system_time(sys)),
                           out->render_label);
    return 0;
}

/* The single PNG of the last state, framed by the bounds gathered. */
static int close_still(run_outputs *out, const psys_system *sys)
{
    const picture_opts *pic = out->pic;
    if (!pic->cam.fit_start)
        bounds_add_system(&out->still_bounds, sys);
    out->ren = make_renderer(pic, out->set, sys, &out->still_bounds);
    if (!out->ren || renderer_draw(out->ren, sys) != 0) {
        cli_error("%s: out of memory for a %dx%d picture", out->render_label, pic->width, pic->height);
        sink_abort(out->snk);
        return -1;
    }
    return sink_close(out->snk, out->ren);
}

/* ---------------------------------------------------------------- frames */

/* One VTP/VTK frame file, written under a temporary name and renamed. */
static int write_vtk_frame(run_outputs *out, const psys_system *sys, long long step)
{
    size_t len = strlen(out->stem) + 40;
    char *name = malloc(len);
    if (!name)
        return -1;
    const char *ext = out->fmt == TRAJ_VTP ? "vtp" : "vtk";
    snprintf(name, len, "%s_%06lld.%s", out->stem, out->vtk_frames, ext);
    outfile o;
    int rc = outfile_open(&o, name, out->label);
    if (rc == 0) {
        rc = (out->fmt == TRAJ_VTP ? psys_vtp_write_frame(o.fp, sys, step) : psys_vtk_write_frame(o.fp, sys, step));
        if (rc != 0)
            outfile_abort(&o);
        else
            rc = outfile_commit(&o);
    }
    if (rc == 0) {
        const char *slash = strrchr(name, '/');
        rc = psys_pvd_write_entry(out->traj.fp, psys_system_time(sys), slash ? slash + 1 : name);
        out->vtk_frames++;
    }
    free(name);
    return rc;
}

bool run_outputs_writes_frames(const run_outputs *out)
{
    return out->traj.fp != NULL || out->energy.fp != NULL || out->plot_on;
}

int run_outputs_write_frame(run_outputs *out, const psys_system *sys, long long step)
{
    if (out->traj.fp) {
        int rc = 0;
        switch (out->fmt) {
        case TRAJ_CSV: rc = psys_csv_write_trajectory_frame(out->traj.fp, sys, step); break;
        case TRAJ_XYZ: rc = psys_xyz_write_frame(out->traj.fp, sys, step); break;
        case TRAJ_VTP:
        case TRAJ_VTK: rc = write_vtk_frame(out, sys, step); break;
        case TRAJ_NONE: break;
        }
        if (rc != 0)
            return -1;
    }
    if (out->energy.fp && psys_csv_write_energy_frame(out->energy.fp, sys, step) != 0)
        return -1;
    if (out->plot_on)
        energy_add(&out->plot, sys);
    return 0;
}

/* ---------------------------------------------------------------- committing */

/* The checkpoint file was opened (as a temporary) before the run started,
 * so an unwritable path is a start-up error, not a surprise at the end. */
static int write_checkpoint(outfile *o, const psys_scene *scene, const psys_run *run)
{
    psys_error err;
    psys_resume_state rs = psys_run_resume_state(run);
    char *text = psys_scene_to_string(scene, &rs, &err);
    if (!text) {
        cli_error("--checkpoint %s: %s", o->path, err.message);
        outfile_abort(o);
        return -1;
    }
    fputs(text, o->fp);
    fputc('\n', o->fp);
    free(text);
    return outfile_commit(o);
}

int run_outputs_commit(run_outputs *out, const psys_scene *scene, const psys_run *run, const psys_system *sys,
                       const char *source)
{
    if (out->fmt == TRAJ_VTP || out->fmt == TRAJ_VTK)
        psys_pvd_write_footer(out->traj.fp);
    int rc = outfile_commit(&out->traj);
    rc |= outfile_commit(&out->energy);
    if (out->checkpoint_on)
        rc |= write_checkpoint(&out->checkpoint, scene, run);
    if (out->plot_on)
        rc |= energy_plot(&out->plot, &out->plot_file, out->pic, source);
    if (out->still)
        rc |= close_still(out, sys) != 0;
    else if (out->snk)
        rc |= sink_close(out->snk, out->ren);
    out->snk = NULL;
    renderer_destroy(out->ren);
    out->ren = NULL;
    free(out->stem);
    out->stem = NULL;
    energy_free(&out->plot);
    return rc;
}
