/* psys view: options, the SDL2 window with an OpenGL 3.3 core context, the
 * event loop (construction, mouse springs, camera), the fixed-rate
 * simulation clock and the HUD (docs/cli.md "psys view"). */
#define SDL_MAIN_HANDLED
#include "view.h"
#include "view_internal.h"
#include "../psys/cli.h"

#include <SDL.h>
#include <cairo.h>
#include <epoxy/gl.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int parse_size(const char *s, int *w, int *h); /* apps/psys/camera.c */

#define FPS_CAP 60.0
#define PICK_PX 14.0     /* picking radius around the cursor, pixels */
#define CLICK_PX 5       /* a press that moves less than this is a click */
#define UNSAVED_NAME "untitled.json"

/* The bindings, as the controls panel lists them (docs/cli.md has the same table). */
static const char *const CONTROLS[][2] = {
    {"left click", "add a particle"},
    {"left drag A to B", "spring from A to B (rest = distance)"},
    {"left drag A to empty", "new particle on a spring from A"},
    {"right / Shift+left drag", "grab with a mouse spring"},
    {"P", "pin / unpin particle under cursor"},
    {"M", "circle motor on / off"},
    {"Delete", "remove particle or spring"},
    {"Ctrl+Z", "undo the last edit"},
    {"Space", "run / pause"},
    {"N", "single step (repeats while held)"},
    {"R", "reset to the loaded state"},
    {"1 - 7", "solver"},
    {"[  ]", "halve / double dt (repeats while held)"},
    {"G", "gravity on / off"},
    {"Ctrl+S", "save the scene"},
    {"wheel", "zoom"},
    {"middle drag", "pan (2-D) / orbit (3-D)"},
    {"Shift+middle drag", "pan (3-D)"},
    {"F", "frame all"},
    {"H", "show / hide this list"},
    {"Esc / Q", "quit"},
};

typedef enum drag_kind {
    DRAG_NONE,
    DRAG_CLICK,   /* left press on empty space: a click adds a particle */
    DRAG_CONNECT, /* left press on a particle: release on another joins them */
    DRAG_GRAB,    /* mouse spring */
    DRAG_PAN,
    DRAG_ORBIT
} drag_kind;

typedef struct app {
    SDL_Window *win;
    SDL_GLContext gl;
    vw_camera cam;
    vw_model m;
    vw_renderer *ren;
    vw_text *text;
    const char *scene_path;
    const char *save_path;
    bool running, help, quit;
    int mx, my;                /* cursor, window pixels */
    drag_kind drag;
    int drag_button;
    int down_x, down_y, last_x, last_y;
    long drag_particle;
    double pick_point[3];      /* 3-D: the view plane of new particles goes through it */
    double grab_point[3];      /* 3-D: the view plane of the grab target goes through it */
    char status[512];
    Uint64 status_until;
    double accum;              /* real time not yet simulated */
    double speed;              /* simulated seconds per real second (smoothed) */
    double fps;
} app;

static void status(app *a, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;
static void status(app *a, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(a->status, sizeof a->status, fmt, ap);
    va_end(ap);
    a->status_until = SDL_GetTicks64() + 5000;
}

static int usage_error(const char *fmt, const char *arg)
{
    char msg[512];
    snprintf(msg, sizeof msg, fmt, arg);
    cli_error("view: %s (see psys --help)", msg);
    return EXIT_BAD_INPUT;
}

/* ---------------------------------------------------------------- picking */

static const double *pos(const app *a, size_t i)
{
    return psys_system_positions(a->m.sys) + i * (size_t)a->m.dim;
}

/* The particle nearest the pixel (sx, sy) on screen within PICK_PX (or its
 * drawn radius), nearest the eye among equals; -1 if none. */
static long pick_particle(const app *a, double sx, double sy)
{
    size_t n = psys_system_count(a->m.sys);
    long best = -1;
    double bd2 = INFINITY, bdepth = INFINITY;
    for (size_t i = 0; i < n; i++) {
        double px, py, depth;
        if (!vw_camera_project(&a->cam, pos(a, i), &px, &py, &depth))
            continue;
        double d2 = (px - sx) * (px - sx) + (py - sy) * (py - sy);
        double rpx = a->m.radius * vw_camera_ppu_at(&a->cam, pos(a, i)) + 3;
        double lim = rpx > PICK_PX ? rpx : PICK_PX;
        if (d2 > lim * lim)
            continue;
        if (d2 < bd2 - 1 || (d2 < bd2 + 1 && depth < bdepth)) {
            best = (long)i;
            bd2 = d2;
            bdepth = depth;
        }
    }
    return best;
}

/* The spring nearest the pixel within 6 pixels; -1 if none. */
static long pick_spring(const app *a, double sx, double sy)
{
    size_t ns = psys_system_spring_count(a->m.sys);
    long best = -1;
    double bd = 6.0;
    for (size_t k = 0; k < ns; k++) {
        size_t i, j;
        if (psys_system_spring(a->m.sys, k, &i, &j, NULL, NULL, NULL) != PSYS_OK)
            continue;
        double x0, y0, x1, y1;
        if (!vw_camera_project(&a->cam, pos(a, i), &x0, &y0, NULL)
            || !vw_camera_project(&a->cam, pos(a, j), &x1, &y1, NULL))
            continue;
        double dx = x1 - x0, dy = y1 - y0, l2 = dx * dx + dy * dy;
        double t = l2 > 0 ? ((sx - x0) * dx + (sy - y0) * dy) / l2 : 0;
        t = t < 0 ? 0 : t > 1 ? 1 : t;
        double d = hypot(x0 + t * dx - sx, y0 + t * dy - sy);
        if (d < bd) {
            bd = d;
            best = (long)k;
        }
    }
    return best;
}

/* The scene point under the cursor on the view plane through `through` (3-D). */
static void world_at(const app *a, double sx, double sy, const double *through, double *out)
{
    vw_camera_unproject(&a->cam, sx, sy, through, out);
}

static void remember_pick(app *a, long i)
{
    if (i >= 0 && a->m.dim == 3)
        memcpy(a->pick_point, pos(a, (size_t)i), 3 * sizeof(double));
}

/* ------------------------------------------------------------------ view */

static void frame_all(app *a)
{
    double lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
    if (psys_system_bounds(a->m.sys, lo, hi) != PSYS_OK) {
        /* nothing to frame: the default 4 units around the origin */
        vw_camera_init(&a->cam, a->m.dim, a->cam.width, a->cam.height);
        return;
    }
    /* keep at least a little room around a single particle */
    double span = 0;
    for (int k = 0; k < a->m.dim; k++)
        span = fmax(span, hi[k] - lo[k]);
    double pad = span > 0 ? 0 : fmax(a->m.radius * 10, 1e-3);
    for (int k = 0; k < a->m.dim; k++)
        lo[k] -= pad, hi[k] += pad;
    vw_camera_frame(&a->cam, lo, hi);
    memcpy(a->pick_point, a->cam.center, sizeof a->pick_point);
}

/* Particle radius for drawing: the scene's output.radius, else 0.15 of the
 * shortest spring, at most 1/45 of the view's height (as psys run --render). */
static double auto_radius(const app *a)
{
    const psys_settings *set = psys_scene_settings(a->m.scene);
    if (set->render_radius > 0)
        return set->render_radius;
    double extent = a->cam.dim == 2 ? a->cam.height / a->cam.ppu : 2 * a->cam.dist * tan(a->cam.fov / 2);
    double limit = extent / 45.0, shortest = INFINITY;
    size_t ns = psys_system_spring_count(a->m.sys);
    for (size_t k = 0; k < ns; k++) {
        double rest;
        if (psys_system_spring(a->m.sys, k, NULL, NULL, NULL, NULL, &rest) == PSYS_OK && rest > 0 && rest < shortest)
            shortest = rest;
    }
    if (!psys_system_count(a->m.sys))
        limit = extent / 80.0;
    double r = isfinite(shortest) ? fmin(0.15 * shortest, limit) : limit;
    return r > 0 && isfinite(r) ? r : 0.05;
}

/* ------------------------------------------------------------------ saving */

static const char *save_target(const app *a)
{
    if (a->save_path)
        return a->save_path;
    if (a->scene_path && strcmp(a->scene_path, "-") != 0)
        return a->scene_path;
    return UNSAVED_NAME;
}

static void save(app *a)
{
    const char *path = save_target(a);
    if (vw_model_save(&a->m, path) != 0) {
        status(a, "save failed: %s", a->m.message);
        cli_error("view: %s", a->m.message);
        return;
    }
    status(a, "saved %s", path);
    printf("saved %s: %zu particles, %zu springs\n", path, psys_system_count(a->m.sys),
           psys_system_spring_count(a->m.sys));
    fflush(stdout);
}

/* --------------------------------------------------------------- events */

static void end_drag(app *a)
{
    if (a->drag == DRAG_GRAB)
        vw_model_release(&a->m);
    a->drag = DRAG_NONE;
    a->drag_particle = -1;
    SDL_CaptureMouse(SDL_FALSE);
}

static void after_edit(app *a, int rc, const char *done)
{
    if (rc == 0)
        status(a, "%s", done);
    else
        status(a, "%s", a->m.message[0] ? a->m.message : "could not do that");
}

static void start_grab(app *a, long i, int button)
{
    if (i < 0)
        return;
    memcpy(a->grab_point, pos(a, (size_t)i), (size_t)a->m.dim * sizeof(double));
    double target[3];
    world_at(a, a->mx, a->my, a->grab_point, target);
    if (vw_model_grab(&a->m, (size_t)i, target) != 0) {
        status(a, "%s", a->m.message);
        return;
    }
    remember_pick(a, i);
    a->drag = DRAG_GRAB;
    a->drag_button = button;
    a->drag_particle = i;
}

static void mouse_down(app *a, const SDL_MouseButtonEvent *e)
{
    a->mx = e->x, a->my = e->y;
    if (a->drag != DRAG_NONE)
        return;
    a->down_x = a->last_x = e->x;
    a->down_y = a->last_y = e->y;
    bool shift = (SDL_GetModState() & KMOD_SHIFT) != 0;
    SDL_CaptureMouse(SDL_TRUE);
    if (e->button == SDL_BUTTON_LEFT) {
        long i = pick_particle(a, e->x, e->y);
        if (shift) {
            start_grab(a, i, e->button);
        } else if (i >= 0) {
            a->drag = DRAG_CONNECT;
            a->drag_button = e->button;
            a->drag_particle = i;
            remember_pick(a, i);
        } else {
            a->drag = DRAG_CLICK;
            a->drag_button = e->button;
        }
    } else if (e->button == SDL_BUTTON_RIGHT) {
        start_grab(a, pick_particle(a, e->x, e->y), e->button);
    } else if (e->button == SDL_BUTTON_MIDDLE) {
        a->drag = a->m.dim == 3 && !shift ? DRAG_ORBIT : DRAG_PAN;
        a->drag_button = e->button;
    }
}

static void mouse_up(app *a, const SDL_MouseButtonEvent *e)
{
    a->mx = e->x, a->my = e->y;
    if (a->drag == DRAG_NONE || e->button != a->drag_button)
        return;
    bool moved = abs(e->x - a->down_x) >= CLICK_PX || abs(e->y - a->down_y) >= CLICK_PX;
    if (a->drag == DRAG_CLICK && !moved) {
        double x[3];
        world_at(a, e->x, e->y, a->pick_point, x);
        size_t i;
        int rc = vw_model_add_particle(&a->m, x, &i);
        char msg[64];
        snprintf(msg, sizeof msg, "added particle %zu", i);
        after_edit(a, rc, msg);
    } else if (a->drag == DRAG_CONNECT) {
        long src = a->drag_particle, dst = pick_particle(a, e->x, e->y);
        if (dst >= 0 && dst != src) {
            after_edit(a, vw_model_add_spring(&a->m, (size_t)src, (size_t)dst), "added a spring");
            remember_pick(a, dst);
        } else if (dst < 0 && moved) {
            double x[3];
            world_at(a, e->x, e->y, pos(a, (size_t)src), x);
            after_edit(a, vw_model_add_connected(&a->m, (size_t)src, x), "added a particle on a spring");
        }
    }
    end_drag(a);
}

static void mouse_move(app *a, const SDL_MouseMotionEvent *e)
{
    a->mx = e->x, a->my = e->y;
    int dx = e->x - a->last_x, dy = e->y - a->last_y;
    a->last_x = e->x, a->last_y = e->y;
    switch (a->drag) {
    case DRAG_PAN:
        vw_camera_pan(&a->cam, dx, dy);
        break;
    case DRAG_ORBIT:
        vw_camera_orbit(&a->cam, dx, dy);
        break;
    case DRAG_GRAB: {
        double target[3];
        world_at(a, e->x, e->y, a->grab_point, target);
        vw_model_grab_move(&a->m, target);
        break;
    }
    default:
        break;
    }
}

static void key_down(app *a, const SDL_KeyboardEvent *e)
{
    SDL_Keycode k = e->keysym.sym;
    bool ctrl = (e->keysym.mod & KMOD_CTRL) != 0;
    vw_model *m = &a->m;
    /* A held key repeats; only stepping and the time step act again: a
     * repeated toggle would reverse the press, a repeated delete or undo
     * would remove or undo more than asked (there is no redo). */
    if (e->repeat && (ctrl || (k != SDLK_n && k != SDLK_LEFTBRACKET && k != SDLK_RIGHTBRACKET)))
        return;
    if (ctrl && k == SDLK_s) {
        save(a);
        return;
    }
    if (ctrl && k == SDLK_z) {
        end_drag(a);
        int rc = vw_model_undo(m);
        status(a, "%s", rc == 0 ? "undone" : rc > 0 ? "nothing to undo" : m->message);
        return;
    }
    if (ctrl || (e->keysym.mod & KMOD_ALT))
        return;
    long under = pick_particle(a, a->mx, a->my);
    switch (k) {
    case SDLK_ESCAPE:
    case SDLK_q:
        a->quit = true;
        break;
    case SDLK_SPACE:
        a->running = !a->running;
        a->accum = 0;
        if (m->failed)
            status(a, "%s", m->message);
        break;
    case SDLK_n: {
        a->running = false;
        double taken;
        if (vw_model_step(m, psys_scene_settings(m->scene)->dt, &taken) != PSYS_OK)
            status(a, "%s", m->message);
        break;
    }
    case SDLK_r:
        end_drag(a);
        after_edit(a, vw_model_reset(m), "reset to the loaded state (Ctrl+Z undoes)");
        a->accum = 0;
        break;
    case SDLK_1: case SDLK_2: case SDLK_3: case SDLK_4: case SDLK_5: case SDLK_6: case SDLK_7: {
        size_t idx = (size_t)(k - SDLK_1);
        if (idx < psys_solver_count()) {
            if (vw_model_set_integrator(m, idx) == 0)
                status(a, "solver %s", psys_solver_name_at(idx));
            else
                status(a, "%s", m->message);
        }
        break;
    }
    case SDLK_LEFTBRACKET:
    case SDLK_RIGHTBRACKET: {
        double dt = psys_scene_settings(m->scene)->dt * (k == SDLK_LEFTBRACKET ? 0.5 : 2.0);
        if (dt >= 1e-7 && dt <= 1.0 && vw_model_set_dt(m, dt) == 0)
            status(a, "dt = %g s", dt);
        break;
    }
    case SDLK_g:
        end_drag(a);
        if (vw_model_toggle_gravity(m) == 0)
            status(a, "gravity %s", vw_model_has_gravity(m) ? "on" : "off");
        else
            status(a, "%s", m->message);
        break;
    case SDLK_f:
        frame_all(a);
        break;
    case SDLK_h:
        a->help = !a->help;
        break;
    case SDLK_p:
        if (under >= 0) {
            end_drag(a);
            int rc = vw_model_toggle_pin(m, (size_t)under);
            after_edit(a, rc, psys_system_is_fixed(m->sys, (size_t)under) ? "pinned" : "unpinned");
        }
        break;
    case SDLK_m:
        if (under >= 0) {
            end_drag(a);
            double r = 30.0 / vw_camera_ppu_at(&a->cam, pos(a, (size_t)under));
            int rc = vw_model_toggle_motor(m, (size_t)under, r, a->cam.f);
            after_edit(a, rc, psys_system_is_controlled(m->sys, (size_t)under) ? "circle motor on" : "motor off");
        }
        break;
    case SDLK_DELETE:
    case SDLK_BACKSPACE:
        end_drag(a);
        if (under >= 0) {
            after_edit(a, vw_model_delete_particle(m, (size_t)under), "removed a particle");
        } else {
            long s = pick_spring(a, a->mx, a->my);
            if (s >= 0)
                after_edit(a, vw_model_delete_spring(m, (size_t)s), "removed a spring");
        }
        break;
    default:
        break;
    }
}

static void handle_event(app *a, const SDL_Event *e)
{
    switch (e->type) {
    case SDL_QUIT:
        a->quit = true;
        break;
    case SDL_WINDOWEVENT:
        if (e->window.event == SDL_WINDOWEVENT_SIZE_CHANGED) {
            int w, h;
            SDL_GL_GetDrawableSize(a->win, &w, &h);
            vw_camera_resize(&a->cam, w, h);
        }
        break;
    case SDL_MOUSEBUTTONDOWN:
        mouse_down(a, &e->button);
        break;
    case SDL_MOUSEBUTTONUP:
        mouse_up(a, &e->button);
        break;
    case SDL_MOUSEMOTION:
        mouse_move(a, &e->motion);
        break;
    case SDL_MOUSEWHEEL: {
        int y = e->wheel.direction == SDL_MOUSEWHEEL_FLIPPED ? -e->wheel.y : e->wheel.y;
        if (y)
            vw_camera_zoom(&a->cam, pow(1.15, y), a->mx, a->my);
        break;
    }
    case SDL_KEYDOWN:
        key_down(a, &e->key);
        break;
    default:
        break;
    }
}

/* ------------------------------------------------------------ simulation */

/* Simulate the real time that passed (at most 0.25 s) in steps of the
 * scene's dt, for at most `budget` seconds of wall time; what does not fit
 * is dropped (the run goes slower than real time, never stutters). */
static void simulate(app *a, double real_dt, double budget)
{
    vw_model *m = &a->m;
    if (!a->running || m->failed) {
        a->speed = 0;
        return;
    }
    Uint64 t0 = SDL_GetPerformanceCounter();
    double freq = (double)SDL_GetPerformanceFrequency();
    double dt = psys_scene_settings(m->scene)->dt;
    bool adaptive = psys_solver_is_adaptive(m->solver);
    a->accum += fmin(real_dt, 0.25);
    double simulated = 0;
    int steps = 0;
    while (a->accum > (adaptive ? 1e-12 : dt * (1 - 1e-9))) {
        double taken = 0;
        double h = adaptive ? a->accum : dt;
        if (vw_model_step(m, h, &taken) != PSYS_OK) {
            a->running = false;
            status(a, "%s", m->message);
            a->accum = 0;
            break;
        }
        a->accum -= taken;
        simulated += taken;
        steps++;
        if ((double)(SDL_GetPerformanceCounter() - t0) / freq > budget) {
            a->accum = 0;
            break;
        }
    }
    if (a->accum < 0)
        a->accum = 0;
    double inst = real_dt > 0 ? simulated / real_dt : 1;
    a->speed = a->speed > 0 ? 0.9 * a->speed + 0.1 * inst : inst;
}

/* ------------------------------------------------------------------- HUD */

static const float WHITE[4] = {0.93f, 0.94f, 0.96f, 1.0f};
static const float DIM[4] = {0.7f, 0.74f, 0.8f, 1.0f};
static const float KEY[4] = {1.0f, 0.85f, 0.35f, 1.0f};
static const float PANEL[4] = {0.0f, 0.0f, 0.0f, 0.55f};

static const char *mode_name(const app *a)
{
    switch (a->drag) {
    case DRAG_CONNECT: return "connecting (release on a particle)";
    case DRAG_GRAB: return a->m.grab_kinematic ? "moving a pinned particle" : "dragging (mouse spring)";
    case DRAG_PAN: return "panning";
    case DRAG_ORBIT: return "orbiting";
    default: return "build (click: particle, drag: spring)";
    }
}

static void draw_hud(app *a)
{
    vw_text *t = a->text;
    if (!t)
        return;
    vw_model *m = &a->m;
    const psys_settings *set = psys_scene_settings(m->scene);
    size_t fixed, ctrl;
    vw_model_counts(m, &fixed, &ctrl);
    size_t idx = 0;
    for (size_t k = 0; k < psys_solver_count(); k++)
        if (strcmp(psys_solver_name_at(k), set->integrator) == 0)
            idx = k;
    double ke = psys_system_kinetic_energy(m->sys), pe = psys_system_potential_energy(m->sys);
    char lines[5][256];
    char run[96];
    if (m->failed)
        snprintf(run, sizeof run, "STOPPED (non-finite state)");
    else if (!a->running)
        snprintf(run, sizeof run, "paused");
    else if (a->speed < 0.97)
        snprintf(run, sizeof run, "running at %.2fx real time", a->speed);
    else
        snprintf(run, sizeof run, "running");
    snprintf(lines[0], sizeof lines[0], "t = %.3f s   %s", psys_system_time(m->sys), run);
    snprintf(lines[1], sizeof lines[1], "%zu particles (%zu pinned, %zu motors)   %zu springs   gravity %s",
             psys_system_count(m->sys), fixed, ctrl, psys_system_spring_count(m->sys),
             vw_model_has_gravity(m) ? "on" : "off");
    snprintf(lines[2], sizeof lines[2], "integrator %s (%zu of %zu)   dt = %g s", set->integrator, idx + 1,
             psys_solver_count(), set->dt);
    snprintf(lines[3], sizeof lines[3], "energy %.6g J   (kinetic %.6g, potential %.6g)", ke + pe, ke, pe);
    snprintf(lines[4], sizeof lines[4], "mode: %s   %.0f fps", mode_name(a), a->fps);
    float lh = vw_text_line_height(t), asc = vw_text_ascent(t), w = 0;
    for (int k = 0; k < 5; k++)
        w = fmaxf(w, vw_text_width(t, lines[k]));
    vw_renderer_rect(a->ren, &a->cam, 0, 0, w + 20, lh * 5 + 12, PANEL);
    for (int k = 0; k < 5; k++)
        vw_text_add(t, 10, 8 + lh * (float)k + asc, lines[k], k == 0 ? WHITE : DIM);
    /* status line and the help hint at the bottom */
    float H = (float)a->cam.height, W = (float)a->cam.width;
    if (a->status[0] && SDL_GetTicks64() < a->status_until) {
        float sw = vw_text_width(t, a->status);
        vw_renderer_rect(a->ren, &a->cam, 0, H - lh - 10, sw + 20, H, PANEL);
        vw_text_add(t, 10, H - 10 - lh * 0.25f, a->status, KEY);
    }
    const char *hint = a->help ? "H: hide controls" : "H: controls";
    vw_text_add(t, W - vw_text_width(t, hint) - 10, H - 10 - lh * 0.25f, hint, DIM);
    vw_text_flush(t, &a->cam);
    if (!a->help)
        return;
    size_t nc = sizeof CONTROLS / sizeof *CONTROLS;
    float kw = 0, dw = 0;
    for (size_t k = 0; k < nc; k++) {
        kw = fmaxf(kw, vw_text_width(t, CONTROLS[k][0]));
        dw = fmaxf(dw, vw_text_width(t, CONTROLS[k][1]));
    }
    float pw = kw + dw + 40, ph = lh * (float)(nc + 1) + 16;
    float x0 = W - pw - 8, y0 = 8;
    vw_renderer_rect(a->ren, &a->cam, x0, y0, x0 + pw, y0 + ph, PANEL);
    vw_text_add(t, x0 + 12, y0 + 8 + asc, "Controls", WHITE);
    for (size_t k = 0; k < nc; k++) {
        float y = y0 + 8 + lh * (float)(k + 1) + asc;
        vw_text_add(t, x0 + 12, y, CONTROLS[k][0], KEY);
        vw_text_add(t, x0 + 28 + kw, y, CONTROLS[k][1], WHITE);
    }
    vw_text_flush(t, &a->cam);
}

/* ----------------------------------------------------------- screenshots */

static int write_png(const app *a, const char *path)
{
    int w = a->cam.width, h = a->cam.height;
    unsigned char *px = vw_renderer_read_pixels(&a->cam);
    if (!px) {
        cli_error("view: out of memory reading the frame");
        return -1;
    }
    cairo_surface_t *s = cairo_image_surface_create(CAIRO_FORMAT_RGB24, w, h);
    int rc = -1;
    if (cairo_surface_status(s) == CAIRO_STATUS_SUCCESS) {
        cairo_surface_flush(s);
        unsigned char *data = cairo_image_surface_get_data(s);
        int stride = cairo_image_surface_get_stride(s);
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                const unsigned char *p = px + ((size_t)y * (size_t)w + (size_t)x) * 3;
                unsigned char *q = data + (size_t)y * (size_t)stride + 4 * (size_t)x;
                q[0] = p[2], q[1] = p[1], q[2] = p[0], q[3] = 255;
            }
        cairo_surface_mark_dirty(s);
        size_t n = strlen(path) + 32;
        char *tmp = malloc(n);
        if (tmp) {
            snprintf(tmp, n, "%s.psys-tmp-png", path);
            if (cairo_surface_write_to_png(s, tmp) == CAIRO_STATUS_SUCCESS && rename(tmp, path) == 0)
                rc = 0;
            else
                remove(tmp);
            free(tmp);
        }
    }
    cairo_surface_destroy(s);
    free(px);
    if (rc != 0)
        cli_error("view: --screenshot: cannot write %s", path);
    return rc;
}

/* ------------------------------------------------------------------ main */

int psys_view_main(int argc, char **argv)
{
    const char *scene_path = NULL, *save_path = NULL, *shot = NULL, *integrator = NULL;
    int width = 960, height = 720;
    long long frames = -1;
    double dt = 0;
    bool paused = false, help = false, help_given = false;
    for (int i = 1; i < argc; i++) {
        const char *arg = argv[i];
        if (arg[0] != '-' || strcmp(arg, "-") == 0) {
            if (scene_path) {
                cli_error("view: more than one scene given (%s and %s)", scene_path, arg);
                return EXIT_BAD_INPUT;
            }
            scene_path = arg;
            continue;
        }
        if (strcmp(arg, "--help") == 0 || strcmp(arg, "-h") == 0) {
            printf("usage: psys view [SCENE] [options]   (psys --help lists the options)\n\ncontrols:\n");
            for (size_t k = 0; k < sizeof CONTROLS / sizeof *CONTROLS; k++)
                printf("  %-26s %s\n", CONTROLS[k][0], CONTROLS[k][1]);
            return EXIT_OK;
        }
        if (strcmp(arg, "--paused") == 0) {
            paused = true;
            continue;
        }
        if (strcmp(arg, "--controls") == 0 || strcmp(arg, "--no-controls") == 0) {
            help = arg[2] == 'c';
            help_given = true;
            continue;
        }
        static const char *const with_value[] = {"--save", "--size", "--frames", "--screenshot", "--dt",
                                                 "--integrator"};
        const char *val = NULL;
        size_t which = 0;
        for (; which < sizeof with_value / sizeof *with_value; which++) {
            size_t l = strlen(with_value[which]);
            if (strcmp(arg, with_value[which]) == 0) {
                if (i + 1 >= argc) {
                    cli_error("%s needs a value (see psys --help)", arg);
                    return EXIT_BAD_INPUT;
                }
                val = argv[++i];
                break;
            }
            if (strncmp(arg, with_value[which], l) == 0 && arg[l] == '=') {
                val = arg + l + 1;
                break;
            }
        }
        if (!val)
            return usage_error("unknown option %s", arg);
        const char *name = with_value[which];
        if (strcmp(name, "--save") == 0 || strcmp(name, "--screenshot") == 0) {
            if (!val[0]) {
                cli_error("%s: path must not be empty", name);
                return EXIT_BAD_INPUT;
            }
            if (name[2] == 's' && name[3] == 'a')
                save_path = val;
            else
                shot = val;
        } else if (strcmp(name, "--size") == 0) {
            if (parse_size(val, &width, &height) != 0) {
                cli_error("--size must be WxH with each 16 to 8192 (got %s)", val);
                return EXIT_BAD_INPUT;
            }
        } else if (strcmp(name, "--frames") == 0) {
            if (parse_int(val, 1, 1000000000, &frames) != 0) {
                cli_error("--frames must be a whole number >= 1 (got %s)", val);
                return EXIT_BAD_INPUT;
            }
        } else if (strcmp(name, "--dt") == 0) {
            if (parse_positive(val, &dt) != 0) {
                cli_error("--dt must be a number > 0 (got %s)", val);
                return EXIT_BAD_INPUT;
            }
        } else {
            if (!psys_solver_exists(val)) {
                cli_error("--integrator: unknown solver \"%s\" (known: euler, midpoint, rk4, symplectic-euler, "
                          "verlet, rk45, implicit-euler)",
                          val);
                return EXIT_BAD_INPUT;
            }
            integrator = val;
        }
    }
    if (shot && frames < 0)
        frames = 1;

    app *a = calloc(1, sizeof *a);
    if (!a) {
        cli_error("view: out of memory");
        return EXIT_RUN_FAILED;
    }
    a->scene_path = scene_path;
    a->save_path = save_path;
    a->drag_particle = -1;
    const char *name = scene_path ? (strcmp(scene_path, "-") == 0 ? "<stdin>" : scene_path) : NULL;
    if (vw_model_open(&a->m, scene_path) != 0) {
        cli_error("%s: %s", name ? name : "view", a->m.message);
        vw_model_close(&a->m);
        free(a);
        return EXIT_BAD_INPUT;
    }
    if (integrator) {
        snprintf(psys_scene_settings(a->m.scene)->integrator, sizeof psys_scene_settings(a->m.scene)->integrator,
                 "%s", integrator);
        vw_model_reset_solver(&a->m);
    }
    if (dt > 0)
        vw_model_set_dt(&a->m, dt);
    a->running = !paused;
    a->help = help_given ? help : scene_path == NULL;

    int status_code = EXIT_OK;
    SDL_SetHint(SDL_HINT_MOUSE_FOCUS_CLICKTHROUGH, "1");
    SDL_SetHint(SDL_HINT_VIDEO_X11_NET_WM_BYPASS_COMPOSITOR, "0");
    if (SDL_Init(SDL_INIT_VIDEO) != 0) {
        cli_error("view: cannot open a window: %s (is DISPLAY set?)", SDL_GetError());
        vw_model_close(&a->m);
        free(a);
        return EXIT_RUN_FAILED;
    }
    SDL_GL_SetAttribute(SDL_GL_CONTEXT_MAJOR_VERSION, 3);
    SDL_GL_SetAttribute(SDL_GL_CONTEXT_MINOR_VERSION, 3);
    SDL_GL_SetAttribute(SDL_GL_CONTEXT_PROFILE_MASK, SDL_GL_CONTEXT_PROFILE_CORE);
    SDL_GL_SetAttribute(SDL_GL_DOUBLEBUFFER, 1);
    SDL_GL_SetAttribute(SDL_GL_DEPTH_SIZE, 24);
    char title[1100];
    snprintf(title, sizeof title, "psys - %s", name ? name : "new 2-D scene");
    a->win = SDL_CreateWindow(title, SDL_WINDOWPOS_CENTERED, SDL_WINDOWPOS_CENTERED, width, height,
                              SDL_WINDOW_OPENGL | SDL_WINDOW_RESIZABLE | SDL_WINDOW_ALLOW_HIGHDPI);
    if (a->win)
        a->gl = SDL_GL_CreateContext(a->win);
    if (!a->win || !a->gl) {
        cli_error("view: cannot create an OpenGL 3.3 core window: %s", SDL_GetError());
        status_code = EXIT_RUN_FAILED;
        goto done;
    }
    SDL_GL_MakeCurrent(a->win, a->gl);
    SDL_GL_SetSwapInterval(1);
    SDL_StopTextInput();
    if (epoxy_gl_version() < 33) {
        cli_error("view: OpenGL 3.3 is needed (this context has %d.%d)", epoxy_gl_version() / 10,
                  epoxy_gl_version() % 10);
        status_code = EXIT_RUN_FAILED;
        goto done;
    }
    char why[600];
    if (!(a->ren = vw_renderer_create(why, sizeof why))) {
        cli_error("view: %s", why);
        status_code = EXIT_RUN_FAILED;
        goto done;
    }
    if (!(a->text = vw_text_create(NULL, 15.0f, why, sizeof why)))
        cli_error("view: no text: %s", why); /* the viewer still works without its HUD */
    int dw, dh;
    SDL_GL_GetDrawableSize(a->win, &dw, &dh);
    vw_camera_init(&a->cam, a->m.dim, dw, dh);
    frame_all(a);
    a->m.radius = auto_radius(a);
    if (psys_system_count(a->m.sys))
        frame_all(a);

    Uint64 freq = SDL_GetPerformanceFrequency(), last = SDL_GetPerformanceCounter();
    long long frame = 0;
    while (!a->quit) {
        Uint64 start = SDL_GetPerformanceCounter();
        SDL_Event e;
        while (SDL_PollEvent(&e))
            handle_event(a, &e);
        if (a->quit)
            break;
        Uint64 now = SDL_GetPerformanceCounter();
        double real_dt = (double)(now - last) / (double)freq;
        last = now;
        if (real_dt > 0)
            a->fps = a->fps > 0 ? 0.95 * a->fps + 0.05 / real_dt : 1 / real_dt;
        simulate(a, real_dt, 0.6 / FPS_CAP);

        vw_overlay ov = {-1, -1, -1, false, {0, 0, 0}, {0, 0, 0}};
        if (!shot && (a->drag == DRAG_NONE || a->drag == DRAG_CONNECT)) { /* screenshots: no hover marks */
            ov.hover_particle = pick_particle(a, a->mx, a->my);
            if (ov.hover_particle < 0 && a->drag == DRAG_NONE)
                ov.hover_spring = pick_spring(a, a->mx, a->my);
        }
        if (a->drag == DRAG_CONNECT && a->drag_particle >= 0) {
            ov.source_particle = a->drag_particle;
            ov.line = true;
            memcpy(ov.line_a, pos(a, (size_t)a->drag_particle), (size_t)a->m.dim * sizeof(double));
            world_at(a, a->mx, a->my, ov.line_a, ov.line_b);
        } else if (a->drag == DRAG_GRAB && a->m.grabbing && !a->m.grab_kinematic) {
            ov.source_particle = (long)a->m.grab_particle;
            ov.line = true;
            memcpy(ov.line_a, pos(a, a->m.grab_particle), (size_t)a->m.dim * sizeof(double));
            memcpy(ov.line_b, a->m.grab_target, sizeof ov.line_b);
        }
        vw_renderer_draw(a->ren, a->m.sys, &a->cam, a->m.radius, &ov);
        if (!shot)
            draw_hud(a);
        frame++;
        if (frames > 0 && frame >= frames) {
            if (shot) {
                if (write_png(a, shot) != 0) {
                    status_code = EXIT_RUN_FAILED;
                } else {
                    /* where each particle is in the picture, for scripts */
                    size_t n = psys_system_count(a->m.sys);
                    printf("screenshot %s %d %d\n", shot, a->cam.width, a->cam.height);
                    for (size_t i = 0; i < n; i++) {
                        double sx, sy;
                        if (vw_camera_project(&a->cam, pos(a, i), &sx, &sy, NULL))
                            printf("particle %zu %.0f %.0f\n", i, floor(sx), floor(sy));
                    }
                }
            }
            break;
        }
        SDL_GL_SwapWindow(a->win);
        double spent = (double)(SDL_GetPerformanceCounter() - start) / (double)freq;
        if (spent < 1.0 / FPS_CAP)
            SDL_Delay((Uint32)((1.0 / FPS_CAP - spent) * 1000));
    }

done:
    vw_text_destroy(a->text);
    vw_renderer_destroy(a->ren);
    if (a->gl)
        SDL_GL_DeleteContext(a->gl);
    if (a->win)
        SDL_DestroyWindow(a->win);
    SDL_Quit();
    vw_model_close(&a->m);
    free(a);
    return status_code;
}
