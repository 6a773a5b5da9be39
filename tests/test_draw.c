/* The drawing interface (psys_draw, psys_system_draw), bounds, and the
 * VTP / VTK / PVD / XYZ frame writers of the library. */
#include "check.h"
#include "psys/psys.h"

/* ---------------------------------------------------------------- a recording renderer */

enum { MAXREC = 64 };

typedef struct rec {
    char order[256]; /* one letter per call: b plane g spring l particle e */
    int dim;
    double t;
    int nplane, nspring, nparticle, nlink, nguide;
    double plane_p[MAXREC][3], plane_n[MAXREC][3];
    double spring_a[MAXREC][3], spring_b[MAXREC][3], strain[MAXREC];
    size_t pidx[MAXREC];
    double px[MAXREC][3], radius[MAXREC];
    unsigned flags[MAXREC];
    double link_a[MAXREC][3], link_b[MAXREC][3];
    double guide_p[MAXREC][3], guide_r[MAXREC];
    int guide_has_normal[MAXREC];
} rec;

static void note(rec *r, char c)
{
    size_t n = strlen(r->order);
    if (n + 1 < sizeof r->order) {
        r->order[n] = c;
        r->order[n + 1] = '\0';
    }
}

static void copyv(double *dst, const double *src, int dim)
{
    dst[0] = dst[1] = dst[2] = 0;
    for (int k = 0; k < dim; k++)
        dst[k] = src[k];
}

static void r_begin(void *ctx, int dim, double t)
{
    rec *r = ctx;
    r->dim = dim;
    r->t = t;
    note(r, 'b');
}

static void r_plane(void *ctx, const double *p, const double *n)
{
    rec *r = ctx;
    if (r->nplane < MAXREC) {
        copyv(r->plane_p[r->nplane], p, r->dim);
        copyv(r->plane_n[r->nplane], n, r->dim);
    }
    r->nplane++;
    note(r, 'p');
}

static void r_spring(void *ctx, const double *a, const double *b, double strain)
{
    rec *r = ctx;
    if (r->nspring < MAXREC) {
        copyv(r->spring_a[r->nspring], a, r->dim);
        copyv(r->spring_b[r->nspring], b, r->dim);
        r->strain[r->nspring] = strain;
    }
    r->nspring++;
    note(r, 's');
}

static void r_particle(void *ctx, size_t i, const double *x, double radius, unsigned flags)
{
    rec *r = ctx;
    if (r->nparticle < MAXREC) {
        r->pidx[r->nparticle] = i;
        copyv(r->px[r->nparticle], x, r->dim);
        r->radius[r->nparticle] = radius;
        r->flags[r->nparticle] = flags;
    }
    r->nparticle++;
    note(r, 'x');
}

static void r_end(void *ctx) { note(ctx, 'e'); }

static void r_link(void *ctx, const double *a, const double *b)
{
    rec *r = ctx;
    if (r->nlink < MAXREC) {
        copyv(r->link_a[r->nlink], a, r->dim);
        copyv(r->link_b[r->nlink], b, r->dim);
    }
    r->nlink++;
    note(r, 'l');
}

static void r_guide(void *ctx, const double *p, const double *n, double radius)
{
    rec *r = ctx;
    if (r->nguide < MAXREC) {
        copyv(r->guide_p[r->nguide], p, r->dim);
        r->guide_r[r->nguide] = radius;
        r->guide_has_normal[r->nguide] = n != NULL;
    }
    r->nguide++;
    note(r, 'g');
}

static psys_draw recorder(rec *r, double radius)
{
    memset(r, 0, sizeof *r);
    psys_draw d;
    memset(&d, 0, sizeof d);
    d.ctx = r;
    d.radius = radius;
    d.begin = r_begin;
    d.plane = r_plane;
    d.spring = r_spring;
    d.particle = r_particle;
    d.end = r_end;
    d.link = r_link;
    d.guide = r_guide;
    return d;
}

/* A 2-D system: fixed anchor 0, free 1 (mass 1) and 2 (mass 8), controlled 3;
 * springs 0-1 (rest 1, stretched to 1.5) and 1-2 (at rest); a floor. */
static psys_system *make_system(void)
{
    psys_system *sys = psys_system_create(2, NULL);
    double x0[2] = {0, 0}, x1[2] = {1.5, 0}, x2[2] = {1.5, -2}, x3[2] = {-1, 1};
    CHECK(psys_system_add_particle(sys, x0, NULL, 1, "a", NULL) == PSYS_OK);
    CHECK(psys_system_add_particle(sys, x1, NULL, 1, "b", NULL) == PSYS_OK);
    CHECK(psys_system_add_particle(sys, x2, NULL, 8, "c", NULL) == PSYS_OK);
    CHECK(psys_system_add_particle(sys, x3, NULL, 1, "m", NULL) == PSYS_OK);
    CHECK(psys_system_set_fixed(sys, 0, true) == PSYS_OK);
    double c[2] = {-1, 0};
    CHECK(psys_system_control_circle(sys, 3, c, 1, 1, 0.5 * 3.14159265358979323846, NULL) == PSYS_OK);
    CHECK(psys_system_add_spring(sys, 0, 1, 10, 0, 1.0) == PSYS_OK);
    CHECK(psys_system_add_spring(sys, 1, 2, 10, 0, -1) == PSYS_OK);
    psys_plane_def pl = psys_plane_def_default();
    pl.point[1] = -3;
    pl.normal[0] = 0;
    pl.normal[1] = 2; /* normalised when added */
    CHECK(psys_system_add_plane(sys, &pl) == PSYS_OK);
    return sys;
}

static void test_draw_order_and_values(void)
{
    psys_system *sys = make_system();
    psys_system_set_time(sys, 0.25);
    rec r;
    psys_draw d = recorder(&r, 0.1);
    CHECK(psys_system_draw(sys, &d) == PSYS_OK);
    CHECK_STR(r.order, "bpssxxxxe");
    CHECK(r.dim == 2);
    CHECK(r.t == 0.25);
    CHECK(r.nplane == 1);
    CHECK_NEAR(r.plane_p[0][1], -3, 0);
    CHECK_NEAR(r.plane_n[0][1], 1, 1e-15); /* unit normal */
    CHECK(r.nspring == 2);
    CHECK_NEAR(r.strain[0], 0.5, 1e-15); /* (1.5 - 1)/1 */
    CHECK_NEAR(r.strain[1], 0.0, 1e-15);
    CHECK_NEAR(r.spring_b[0][0], 1.5, 0);
    CHECK(r.nparticle == 4);
    for (int i = 0; i < 4; i++)
        CHECK(r.pidx[i] == (size_t)i);
    CHECK(r.flags[0] == PSYS_PARTICLE_FIXED);
    CHECK(r.flags[1] == 0);
    CHECK(r.flags[3] == PSYS_PARTICLE_CONTROLLED);
    /* masses 1, 1, 8, 1: typical (geometric mean) 8^(1/4); radius ∝ cbrt(m/typical) */
    double typical = pow(8.0, 0.25);
    CHECK_NEAR(r.radius[1], 0.1 * cbrt(1 / typical), 1e-12);
    CHECK_NEAR(r.radius[2], 0.1 * cbrt(8 / typical), 1e-12);
    CHECK(r.radius[2] > r.radius[1]);
    psys_system_destroy(sys);
}

static void test_draw_null_callbacks(void)
{
    psys_system *sys = make_system();
    rec r;
    psys_draw d = recorder(&r, 0);
    d.plane = NULL;
    d.spring = NULL;
    d.begin = NULL;
    d.end = NULL;
    CHECK(psys_system_draw(sys, &d) == PSYS_OK);
    CHECK_STR(r.order, "xxxx");
    CHECK(r.radius[0] == 0); /* radius 0: the renderer chooses */
    psys_draw none;
    memset(&none, 0, sizeof none);
    CHECK(psys_system_draw(sys, &none) == PSYS_OK);
    CHECK(psys_system_draw(NULL, &none) == PSYS_ERR_INVALID);
    CHECK(psys_system_draw(sys, NULL) == PSYS_ERR_INVALID);
    psys_system_destroy(sys);
}

static void test_draw_radius_clamped(void)
{
    psys_system *sys = psys_system_create(3, NULL);
    double x[3] = {0, 0, 0};
    CHECK(psys_system_add_particle(sys, x, NULL, 1e-6, NULL, NULL) == PSYS_OK);
    CHECK(psys_system_add_particle(sys, x, NULL, 1e6, NULL, NULL) == PSYS_OK);
    rec r;
    psys_draw d = recorder(&r, 2.0);
    CHECK(psys_system_draw(sys, &d) == PSYS_OK);
    CHECK_NEAR(r.radius[0], 1.0, 0); /* clamped to radius/2 */
    CHECK_NEAR(r.radius[1], 4.0, 0); /* clamped to 2·radius */
    CHECK(r.dim == 3);
    psys_system_destroy(sys);
}

static void test_draw_behaviours(void)
{
    psys_system *sys = psys_system_create(2, NULL);
    double x0[2] = {0, 0}, x1[2] = {1, 0}, x2[2] = {1, 1};
    CHECK(psys_system_add_particle(sys, x0, NULL, 1, NULL, NULL) == PSYS_OK);
    CHECK(psys_system_add_particle(sys, x1, NULL, 1, NULL, NULL) == PSYS_OK);
    CHECK(psys_system_add_particle(sys, x2, NULL, 1, NULL, NULL) == PSYS_OK);
    psys_behavior_def b = psys_behavior_def_default();
    b.function = PSYS_BEHAVIOR_DISTANCE;
    b.nparticles = 2;
    b.particles[0] = 0;
    b.particles[1] = 1;
    CHECK(psys_system_add_behavior(sys, &b) == PSYS_OK);
    b = psys_behavior_def_default();
    b.function = PSYS_BEHAVIOR_ANGLE;
    b.nparticles = 3;
    b.particles[0] = 0;
    b.particles[1] = 1;
    b.particles[2] = 2;
    CHECK(psys_system_add_behavior(sys, &b) == PSYS_OK);
    b = psys_behavior_def_default();
    b.function = PSYS_BEHAVIOR_POINT_ON_PLANE;
    b.nparticles = 1;
    b.particles[0] = 2;
    b.normal[0] = 0;
    b.normal[1] = 3;
    CHECK(psys_system_add_behavior(sys, &b) == PSYS_OK);
    b = psys_behavior_def_default();
    b.function = PSYS_BEHAVIOR_POINT_ON_SPHERE;
    b.nparticles = 1;
    b.particles[0] = 1;
    b.radius = 1;
    CHECK(psys_system_add_behavior(sys, &b) == PSYS_OK);
    rec r;
    psys_draw d = recorder(&r, 0.1);
    CHECK(psys_system_draw(sys, &d) == PSYS_OK);
    CHECK_STR(r.order, "bgglllxxxe");
    CHECK(r.nlink == 3); /* distance 0-1, angle arms 0-1 and 1-2 */
    CHECK_NEAR(r.link_b[2][1], 1, 0);
    CHECK(r.guide_has_normal[0] && r.guide_r[0] < 0);
    CHECK(!r.guide_has_normal[1] && r.guide_r[1] == 1);
    psys_system_destroy(sys);
}

static void test_bounds(void)
{
    psys_system *sys = make_system();
    double lo[3] = {9, 9, 9}, hi[3] = {9, 9, 9};
    CHECK(psys_system_bounds(sys, lo, hi) == PSYS_OK);
    CHECK_NEAR(lo[0], -1, 1e-15);
    CHECK_NEAR(lo[1], -2, 0);
    CHECK_NEAR(hi[0], 1.5, 0);
    CHECK_NEAR(hi[1], 1, 1e-15);
    CHECK(lo[2] == 9 && hi[2] == 9); /* only dim numbers are written */
    psys_system_destroy(sys);
    psys_system *empty = psys_system_create(3, NULL);
    CHECK(psys_system_bounds(empty, lo, hi) == PSYS_ERR_INVALID);
    CHECK(lo[0] == 0 && hi[2] == 0);
    psys_system_destroy(empty);
}

/* ---------------------------------------------------------------- writers */

static char *write_to_string(int (*fn)(FILE *, const psys_system *, long long), const psys_system *sys,
                             long long step)
{
    char *buf = NULL;
    size_t len = 0;
    FILE *fp = open_memstream(&buf, &len);
    CHECK(fp != NULL);
    CHECK(fn(fp, sys, step) == 0);
    fclose(fp);
    return buf;
}

static int count(const char *s, const char *what)
{
    int n = 0;
    for (const char *p = s; (p = strstr(p, what)) != NULL; p += strlen(what))
        n++;
    return n;
}

static void test_vtp_frame(void)
{
    psys_system *sys = make_system();
    psys_system_set_time(sys, 0.5);
    char *s = write_to_string(psys_vtp_write_frame, sys, 7);
    CHECK(strncmp(s, "<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\"", 46) == 0);
    CHECK(strstr(s, "NumberOfPoints=\"4\" NumberOfVerts=\"4\" NumberOfLines=\"2\"") != NULL);
    CHECK(strstr(s, "Name=\"TimeValue\" NumberOfTuples=\"1\" format=\"ascii\">0.5</DataArray>") != NULL);
    CHECK(strstr(s, "Name=\"step\" NumberOfTuples=\"1\" format=\"ascii\">7</DataArray>") != NULL);
    CHECK(strstr(s, "Name=\"velocity\" NumberOfComponents=\"3\"") != NULL);
    CHECK(strstr(s, "Name=\"mass\"") != NULL);
    CHECK(strstr(s, "1.5 -2 0\n") != NULL); /* 2-D point with z = 0 */
    CHECK(strstr(s, "0 1\n1 2\n") != NULL); /* springs as lines */
    CHECK(count(s, "<DataArray") == count(s, "</DataArray>"));
    CHECK(strstr(s, "</VTKFile>\n") != NULL);
    free(s);
    s = write_to_string(psys_vtk_write_frame, sys, 7);
    CHECK(strncmp(s, "# vtk DataFile Version 3.0\n", 27) == 0);
    CHECK(strstr(s, "POINTS 4 double\n") != NULL);
    CHECK(strstr(s, "LINES 2 6\n2 0 1\n2 1 2\n") != NULL);
    CHECK(strstr(s, "POINT_DATA 4\n") != NULL);
    free(s);
    psys_system_destroy(sys);
}

static void test_pvd_escapes(void)
{
    char *buf = NULL;
    size_t len = 0;
    FILE *fp = open_memstream(&buf, &len);
    CHECK(psys_pvd_write_header(fp) == 0);
    CHECK(psys_pvd_write_entry(fp, 0.25, "a&b<\"c\">'.vtp") == 0);
    CHECK(psys_pvd_write_footer(fp) == 0);
    fclose(fp);
    CHECK(strstr(buf, "timestep=\"0.25\"") != NULL);
    CHECK(strstr(buf, "file=\"a&amp;b&lt;&quot;c&quot;&gt;&apos;.vtp\"") != NULL);
    CHECK(strstr(buf, "</Collection>\n</VTKFile>\n") != NULL);
    free(buf);
}

static void test_xyz_frame(void)
{
    psys_system *sys = make_system();
    psys_system_set_time(sys, 0.125);
    char *s = write_to_string(psys_xyz_write_frame, sys, 3);
    CHECK(strncmp(s, "4\nProperties=species:S:1:pos:R:3:velo:R:3:mass:R:1:id:I:1:flags:I:1 Time=0.125 step=3 ", 86)
          == 0);
    CHECK(strstr(s, "\nX 0 0 0 0 0 0 1 0 1\n") != NULL);   /* fixed particle: flags 1 */
    CHECK(strstr(s, "\nX 1.5 -2 0 0 0 0 8 2 0\n") != NULL); /* z = 0 in 2-D */
    int lines = count(s, "\n");
    CHECK(lines == 6);
    free(s);
    psys_system_destroy(sys);
}

static const check_case cases[] = {
    {"draw_order_and_values", test_draw_order_and_values},
    {"draw_null_callbacks", test_draw_null_callbacks},
    {"draw_radius_clamped", test_draw_radius_clamped},
    {"draw_behaviours", test_draw_behaviours},
    {"bounds", test_bounds},
    {"vtp_frame", test_vtp_frame},
    {"pvd_escapes", test_pvd_escapes},
    {"xyz_frame", test_xyz_frame},
    {NULL, NULL},
};

int main(int argc, char **argv) { return check_main(argc, argv, cases); }
