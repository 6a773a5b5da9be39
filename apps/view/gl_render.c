/* The viewer's OpenGL 3.3 core renderer: it implements psys_draw (the
 * library's drawing interface, the same one the headless cairo renderer
 * implements), collects planes, springs, links and particles into CPU
 * arrays, uploads them into GPU buffers once per frame and draws them with
 * three small shader programs: flat-coloured lines and triangles, particles
 * as point sprites (shaded spheres in 3-D), and text (hud.c). */
#include "view_internal.h"

#include <epoxy/gl.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct vtx {
    float x, y, z;
    uint8_t rgba[4];
} vtx;

typedef struct pt {
    float x, y, z, r;
    uint8_t rgba[4];
} pt;

/* A growable array of fixed-size items. */
typedef struct buf {
    void *data;
    size_t n, cap, item;
} buf;

static void *buf_push(buf *b, size_t count)
{
    if (b->n + count > b->cap) {
        size_t cap = b->cap ? b->cap : 1024;
        while (cap < b->n + count)
            cap *= 2;
        void *p = realloc(b->data, cap * b->item);
        if (!p)
            return NULL;
        b->data = p;
        b->cap = cap;
    }
    void *at = (char *)b->data + b->n * b->item;
    b->n += count;
    return at;
}

struct vw_renderer {
    GLuint flat, point;
    GLint flat_mvp, point_mvp, point_scale, point_persp, point_range, point_persp_fs;
    GLuint vao[3], vbo[3]; /* 0 lines + triangles (vtx), 1 points (pt), 2 overlay (vtx) */
    buf lines, tris, points, hl_points;
    /* per frame */
    const vw_camera *cam;
    const vw_overlay *ov;
    int dim;
    size_t spring_index;
    float max_point;
    float line_width;
};

/* ------------------------------------------------------------ shaders */

static const char FLAT_VS[] =
    "#version 330 core\n"
    "layout(location = 0) in vec3 a_pos;\n"
    "layout(location = 1) in vec4 a_color;\n"
    "uniform mat4 u_mvp;\n"
    "out vec4 v_color;\n"
    "void main() { gl_Position = u_mvp * vec4(a_pos, 1.0); v_color = a_color; }\n";
static const char FLAT_FS[] =
    "#version 330 core\n"
    "in vec4 v_color;\n"
    "out vec4 o_color;\n"
    "void main() { o_color = v_color; }\n";
static const char POINT_VS[] =
    "#version 330 core\n"
    "layout(location = 0) in vec3 a_pos;\n"
    "layout(location = 1) in float a_radius;\n"
    "layout(location = 2) in vec4 a_color;\n"
    "uniform mat4 u_mvp;\n"
    "uniform float u_scale;\n"  /* 2-D: pixels per unit; 3-D: focal length in pixels */
    "uniform int u_persp;\n"
    "uniform vec2 u_range;\n"   /* smallest and largest radius in pixels */
    "out vec4 v_color;\n"
    "out float v_rpx;\n"
    "void main() {\n"
    "  vec4 c = u_mvp * vec4(a_pos, 1.0);\n"
    "  gl_Position = c;\n"
    "  float r = a_radius * u_scale / (u_persp == 1 ? max(c.w, 1e-6) : 1.0);\n"
    "  r = clamp(r, u_range.x, u_range.y);\n"
    "  v_rpx = r;\n"
    "  gl_PointSize = 2.0 * r + 2.0;\n"
    "  v_color = a_color;\n"
    "}\n";
static const char POINT_FS[] =
    "#version 330 core\n"
    "in vec4 v_color;\n"
    "in float v_rpx;\n"
    "uniform int u_persp;\n"
    "out vec4 o_color;\n"
    "void main() {\n"
    "  float size = 2.0 * v_rpx + 2.0;\n"
    "  vec2 p = (gl_PointCoord * 2.0 - 1.0) * (0.5 * size);\n"
    "  float d = length(p);\n"
    "  if (d > v_rpx + 0.5) discard;\n"
    "  float a = clamp(v_rpx + 0.5 - d, 0.0, 1.0);\n"
    "  vec3 col = v_color.rgb;\n"
    "  if (u_persp == 1) {\n"
    "    vec2 q = p / max(v_rpx, 1.0);\n"
    "    vec3 n = vec3(q.x, -q.y, sqrt(max(1.0 - dot(q, q), 0.0)));\n"
    "    float l = max(dot(n, normalize(vec3(-0.4, 0.6, 0.7))), 0.0);\n"
    "    col = col * (0.35 + 0.75 * l) + vec3(0.35 * pow(l, 24.0));\n"
    "  }\n"
    "  float edge = smoothstep(v_rpx - 1.8, v_rpx - 0.6, d);\n"
    "  col = mix(col, col * 0.3, edge);\n"
    "  o_color = vec4(col, v_color.a * a);\n"
    "}\n";

static GLuint compile(GLenum type, const char *src, char *why, size_t cap)
{
    GLuint s = glCreateShader(type);
    glShaderSource(s, 1, &src, NULL);
    glCompileShader(s);
    GLint ok = 0;
    glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
    if (!ok) {
        char log[512] = "";
        glGetShaderInfoLog(s, sizeof log, NULL, log);
        snprintf(why, cap, "shader compilation failed: %s", log);
        glDeleteShader(s);
        return 0;
    }
    return s;
}

/* A linked program from vertex and fragment sources; 0 with a reason. */
GLuint vw_gl_program(const char *vs, const char *fs, char *why, size_t cap);
GLuint vw_gl_program(const char *vs, const char *fs, char *why, size_t cap)
{
    GLuint v = compile(GL_VERTEX_SHADER, vs, why, cap);
    if (!v)
        return 0;
    GLuint f = compile(GL_FRAGMENT_SHADER, fs, why, cap);
    if (!f) {
        glDeleteShader(v);
        return 0;
    }
    GLuint p = glCreateProgram();
    glAttachShader(p, v);
    glAttachShader(p, f);
    glLinkProgram(p);
    glDeleteShader(v);
    glDeleteShader(f);
    GLint ok = 0;
    glGetProgramiv(p, GL_LINK_STATUS, &ok);
    if (!ok) {
        char log[512] = "";
        glGetProgramInfoLog(p, sizeof log, NULL, log);
        snprintf(why, cap, "shader link failed: %s", log);
        glDeleteProgram(p);
        return 0;
    }
    return p;
}

vw_renderer *vw_renderer_create(char *why, size_t cap)
{
    vw_renderer *r = calloc(1, sizeof *r);
    if (!r) {
        snprintf(why, cap, "out of memory");
        return NULL;
    }
    r->lines.item = r->tris.item = sizeof(vtx);
    r->points.item = r->hl_points.item = sizeof(pt);
    r->flat = vw_gl_program(FLAT_VS, FLAT_FS, why, cap);
    r->point = r->flat ? vw_gl_program(POINT_VS, POINT_FS, why, cap) : 0;
    if (!r->point) {
        vw_renderer_destroy(r);
        return NULL;
    }
    r->flat_mvp = glGetUniformLocation(r->flat, "u_mvp");
    r->point_mvp = glGetUniformLocation(r->point, "u_mvp");
    r->point_scale = glGetUniformLocation(r->point, "u_scale");
    r->point_persp = glGetUniformLocation(r->point, "u_persp");
    r->point_range = glGetUniformLocation(r->point, "u_range");
    glGenVertexArrays(3, r->vao);
    glGenBuffers(3, r->vbo);
    for (int k = 0; k < 3; k++) {
        glBindVertexArray(r->vao[k]);
        glBindBuffer(GL_ARRAY_BUFFER, r->vbo[k]);
        if (k == 1) {
            glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, sizeof(pt), (void *)offsetof(pt, x));
            glVertexAttribPointer(1, 1, GL_FLOAT, GL_FALSE, sizeof(pt), (void *)offsetof(pt, r));
            glVertexAttribPointer(2, 4, GL_UNSIGNED_BYTE, GL_TRUE, sizeof(pt), (void *)offsetof(pt, rgba));
            glEnableVertexAttribArray(2);
        } else {
            glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, sizeof(vtx), (void *)offsetof(vtx, x));
            glVertexAttribPointer(1, 4, GL_UNSIGNED_BYTE, GL_TRUE, sizeof(vtx), (void *)offsetof(vtx, rgba));
        }
        glEnableVertexAttribArray(0);
        glEnableVertexAttribArray(1);
    }
    glBindVertexArray(0);
    GLfloat range[2] = {1, 64};
    glGetFloatv(GL_ALIASED_POINT_SIZE_RANGE, range);
    r->max_point = range[1] > 4 ? range[1] : 4;
    GLfloat lw[2] = {1, 1};
    glGetFloatv(GL_ALIASED_LINE_WIDTH_RANGE, lw);
    r->line_width = lw[1] >= 1.5f ? 1.5f : 1.0f;
    glEnable(GL_PROGRAM_POINT_SIZE);
    return r;
}

void vw_renderer_destroy(vw_renderer *r)
{
    if (!r)
        return;
    if (r->vao[0]) {
        glDeleteVertexArrays(3, r->vao);
        glDeleteBuffers(3, r->vbo);
    }
    if (r->flat)
        glDeleteProgram(r->flat);
    if (r->point)
        glDeleteProgram(r->point);
    free(r->lines.data);
    free(r->tris.data);
    free(r->points.data);
    free(r->hl_points.data);
    free(r);
}

/* ------------------------------------------------------ psys_draw callbacks */

static void rgba(uint8_t *out, float r, float g, float b, float a)
{
    const float c[4] = {r, g, b, a};
    for (int k = 0; k < 4; k++) {
        float v = c[k] < 0 ? 0 : c[k] > 1 ? 1 : c[k];
        out[k] = (uint8_t)(v * 255 + 0.5f);
    }
}

static void put(vtx *v, const double *p, int dim, const uint8_t *c)
{
    v->x = (float)p[0];
    v->y = (float)p[1];
    v->z = dim == 3 ? (float)p[2] : 0.0f;
    memcpy(v->rgba, c, 4);
}

static void add_line(vw_renderer *r, const double *a, const double *b, const uint8_t *c)
{
    vtx *v = buf_push(&r->lines, 2);
    if (!v)
        return;
    put(&v[0], a, r->dim, c);
    put(&v[1], b, r->dim, c);
}

static void add_tri(vw_renderer *r, const double *a, const double *b, const double *c, const uint8_t *col)
{
    vtx *v = buf_push(&r->tris, 3);
    if (!v)
        return;
    put(&v[0], a, r->dim, col);
    put(&v[1], b, r->dim, col);
    put(&v[2], c, r->dim, col);
}

static void on_begin(void *ctx, int dim, double t)
{
    (void)t;
    vw_renderer *r = ctx;
    r->dim = dim;
    r->spring_index = 0;
}

/* Half the window's diagonal in scene units around the view center. */
static double view_reach(const vw_camera *c)
{
    if (c->dim == 2)
        return (c->width + c->height) / c->ppu;
    return c->dist * 1.5;
}

/* Two unit vectors spanning the plane normal to n (3-D). */
static void plane_basis(const double *n, double *a, double *b)
{
    double e[3] = {1, 0, 0};
    if (fabs(n[0]) > 0.9)
        e[0] = 0, e[1] = 1;
    double d = e[0] * n[0] + e[1] * n[1] + e[2] * n[2];
    for (int k = 0; k < 3; k++)
        a[k] = e[k] - d * n[k];
    double l = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    for (int k = 0; k < 3; k++)
        a[k] /= l;
    b[0] = n[1] * a[2] - n[2] * a[1];
    b[1] = n[2] * a[0] - n[0] * a[2];
    b[2] = n[0] * a[1] - n[1] * a[0];
}

static void draw_plane(vw_renderer *r, const double *p, const double *n, bool guide)
{
    const vw_camera *cam = r->cam;
    double L = view_reach(cam);
    uint8_t line[4], fill[4];
    if (guide)
        rgba(line, 0.2f, 0.7f, 0.7f, 0.8f);
    else
        rgba(line, 0.78f, 0.8f, 0.85f, 1.0f);
    if (r->dim == 2) {
        double t[2] = {-n[1], n[0]};
        double s = (cam->center[0] - p[0]) * n[0] + (cam->center[1] - p[1]) * n[1];
        double c0[2] = {cam->center[0] - s * n[0], cam->center[1] - s * n[1]};
        double a[2] = {c0[0] - L * t[0], c0[1] - L * t[1]}, b[2] = {c0[0] + L * t[0], c0[1] + L * t[1]};
        add_line(r, a, b, line);
        if (!guide) {
            rgba(fill, 0.45f, 0.47f, 0.52f, 0.45f);
            double a2[2] = {a[0] - L * n[0], a[1] - L * n[1]}, b2[2] = {b[0] - L * n[0], b[1] - L * n[1]};
            add_tri(r, a, b, b2, fill);
            add_tri(r, a, b2, a2, fill);
        }
        return;
    }
    double u[3], w[3];
    plane_basis(n, u, w);
    double s = 0;
    for (int k = 0; k < 3; k++)
        s += (cam->center[k] - p[k]) * n[k];
    double c0[3];
    for (int k = 0; k < 3; k++)
        c0[k] = cam->center[k] - s * n[k];
    double corner[4][3];
    static const int sg[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
    for (int q = 0; q < 4; q++)
        for (int k = 0; k < 3; k++)
            corner[q][k] = c0[k] + L * (sg[q][0] * u[k] + sg[q][1] * w[k]);
    if (!guide) {
        /* shaded by the angle to the view direction; lit side brighter */
        double facing = fabs(n[0] * cam->f[0] + n[1] * cam->f[1] + n[2] * cam->f[2]);
        double up = n[1] > 0 ? n[1] : 0;
        float shade = (float)(0.22 + 0.18 * facing + 0.12 * up);
        rgba(fill, shade, shade * 1.02f, shade * 1.1f, 1.0f);
        add_tri(r, corner[0], corner[1], corner[2], fill);
        add_tri(r, corner[0], corner[2], corner[3], fill);
    }
    /* a grid on it, for depth */
    rgba(line, guide ? 0.2f : 0.42f, guide ? 0.7f : 0.45f, guide ? 0.7f : 0.5f, 1.0f);
    const int N = 16;
    for (int k = 0; k <= N; k++) {
        double f = -1 + 2.0 * k / N, a[3], b[3], c[3], d[3];
        for (int q = 0; q < 3; q++) {
            a[q] = c0[q] + L * (f * u[q] - w[q]);
            b[q] = c0[q] + L * (f * u[q] + w[q]);
            c[q] = c0[q] + L * (-u[q] + f * w[q]);
            d[q] = c0[q] + L * (u[q] + f * w[q]);
        }
        add_line(r, a, b, line);
        add_line(r, c, d, line);
    }
}

static void on_plane(void *ctx, const double *point, const double *normal)
{
    draw_plane(ctx, point, normal, false);
}

static void on_guide(void *ctx, const double *point, const double *normal, double radius)
{
    vw_renderer *r = ctx;
    if (normal) {
        draw_plane(r, point, normal, true);
        return;
    }
    uint8_t c[4];
    rgba(c, 0.2f, 0.7f, 0.7f, 0.8f);
    const int N = 96;
    double prev[3] = {0, 0, 0}, cur[3] = {0, 0, 0};
    for (int k = 0; k <= N; k++) {
        double a = 6.283185307179586 * k / N, ca = cos(a) * radius, sa = sin(a) * radius;
        if (r->dim == 2) {
            cur[0] = point[0] + ca;
            cur[1] = point[1] + sa;
        } else {
            for (int q = 0; q < 3; q++)
                cur[q] = point[q] + ca * r->cam->r[q] + sa * r->cam->u[q];
        }
        if (k)
            add_line(r, prev, cur, c);
        memcpy(prev, cur, sizeof prev);
    }
}

static void on_spring(void *ctx, const double *a, const double *b, double strain)
{
    vw_renderer *r = ctx;
    uint8_t c[4];
    long k = (long)r->spring_index++;
    if (r->ov && r->ov->hover_spring == k) {
        rgba(c, 1.0f, 0.9f, 0.2f, 1.0f);
    } else {
        /* grey at rest, red stretched, blue compressed, full at ±5% */
        float s = (float)(strain / 0.05);
        s = s > 1 ? 1 : s < -1 ? -1 : s;
        float g[3] = {0.72f, 0.73f, 0.78f}, hot[3] = {1.0f, 0.28f, 0.22f}, cold[3] = {0.25f, 0.5f, 1.0f};
        const float *e = s > 0 ? hot : cold;
        float f = fabsf(s);
        rgba(c, g[0] + (e[0] - g[0]) * f, g[1] + (e[1] - g[1]) * f, g[2] + (e[2] - g[2]) * f, 1.0f);
    }
    add_line(r, a, b, c);
}

static void on_link(void *ctx, const double *a, const double *b)
{
    uint8_t c[4];
    rgba(c, 0.15f, 0.7f, 0.65f, 1.0f);
    add_line(ctx, a, b, c);
}

static void add_point(buf *b, const double *x, int dim, double radius, const uint8_t *c)
{
    pt *p = buf_push(b, 1);
    if (!p)
        return;
    p->x = (float)x[0];
    p->y = (float)x[1];
    p->z = dim == 3 ? (float)x[2] : 0.0f;
    p->r = (float)radius;
    memcpy(p->rgba, c, 4);
}

static void on_particle(void *ctx, size_t i, const double *x, double radius, unsigned flags)
{
    vw_renderer *r = ctx;
    uint8_t c[4];
    if (flags & PSYS_PARTICLE_FIXED)
        rgba(c, 0.92f, 0.3f, 0.26f, 1.0f);
    else if (flags & PSYS_PARTICLE_CONTROLLED)
        rgba(c, 1.0f, 0.62f, 0.15f, 1.0f);
    else
        rgba(c, 0.36f, 0.63f, 1.0f, 1.0f);
    add_point(&r->points, x, r->dim, radius, c);
    const vw_overlay *ov = r->ov;
    if (ov && (ov->hover_particle == (long)i || ov->source_particle == (long)i)) {
        uint8_t h[4];
        if (ov->source_particle == (long)i)
            rgba(h, 0.3f, 1.0f, 0.45f, 1.0f);
        else
            rgba(h, 1.0f, 0.92f, 0.25f, 1.0f);
        add_point(&r->hl_points, x, r->dim, radius * 1.7, h);
    }
}

/* ------------------------------------------------------------------ frame */

static void upload(GLuint vbo, const buf *b)
{
    glBindBuffer(GL_ARRAY_BUFFER, vbo);
    /* orphan and refill: one upload per buffer per frame */
    glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)(b->n * b->item), b->n ? b->data : NULL, GL_STREAM_DRAW);
}

static void draw_points(vw_renderer *r, const vw_camera *cam, const buf *b, float min_px, float max_px)
{
    if (!b->n)
        return;
    glUseProgram(r->point);
    glUniformMatrix4fv(r->point_mvp, 1, GL_FALSE, cam->view_proj);
    glUniform1f(r->point_scale, (float)(cam->dim == 2 ? cam->ppu : cam->focal));
    glUniform1i(r->point_persp, cam->dim == 3);
    float maxr = (r->max_point - 2) / 2;
    glUniform2f(r->point_range, min_px, max_px < maxr ? max_px : maxr);
    glBindVertexArray(r->vao[1]);
    upload(r->vbo[1], b);
    glDrawArrays(GL_POINTS, 0, (GLsizei)b->n);
}

void vw_renderer_draw(vw_renderer *r, const psys_system *sys, const vw_camera *cam, double radius,
                      const vw_overlay *ov)
{
    r->lines.n = r->tris.n = r->points.n = r->hl_points.n = 0;
    r->cam = cam;
    r->ov = ov;
    r->dim = cam->dim;
    psys_draw d;
    memset(&d, 0, sizeof d);
    d.ctx = r;
    d.radius = radius;
    d.begin = on_begin;
    d.plane = on_plane;
    d.guide = on_guide;
    d.spring = on_spring;
    d.link = on_link;
    d.particle = on_particle;
    psys_system_draw(sys, &d);
    if (ov && ov->line) {
        uint8_t c[4];
        rgba(c, 1.0f, 0.92f, 0.3f, 1.0f);
        add_line(r, ov->line_a, ov->line_b, c);
    }

    glViewport(0, 0, cam->width, cam->height);
    glClearColor(0.11f, 0.12f, 0.145f, 1.0f);
    glClearDepth(1.0);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    glEnable(GL_BLEND);
    glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    bool depth = cam->dim == 3;
    if (depth) {
        glEnable(GL_DEPTH_TEST);
        glDepthFunc(GL_LEQUAL);
    } else {
        glDisable(GL_DEPTH_TEST);
    }

    glUseProgram(r->flat);
    glUniformMatrix4fv(r->flat_mvp, 1, GL_FALSE, cam->view_proj);
    glBindVertexArray(r->vao[0]);
    if (r->tris.n) {
        /* planes: pushed back a little so their grid lines win the depth test */
        glEnable(GL_POLYGON_OFFSET_FILL);
        glPolygonOffset(1.0f, 1.0f);
        upload(r->vbo[0], &r->tris);
        glDrawArrays(GL_TRIANGLES, 0, (GLsizei)r->tris.n);
        glDisable(GL_POLYGON_OFFSET_FILL);
    }
    if (r->lines.n) {
        glLineWidth(r->line_width);
        upload(r->vbo[0], &r->lines);
        glDrawArrays(GL_LINES, 0, (GLsizei)r->lines.n);
    }
    /* highlights under the particles (2-D: drawn first; 3-D: depth decides) */
    draw_points(r, cam, &r->hl_points, 5.0f, 40.0f);
    draw_points(r, cam, &r->points, 2.5f, 36.0f);
    glBindVertexArray(0);
    glDisable(GL_DEPTH_TEST);
}

void vw_renderer_rect(vw_renderer *r, const vw_camera *cam, float x0, float y0, float x1, float y1,
                      const float c[4])
{
    /* window pixels (y down) to clip space */
    float m[16] = {0};
    m[0] = 2.0f / (float)cam->width;
    m[5] = -2.0f / (float)cam->height;
    m[10] = 1;
    m[12] = -1;
    m[13] = 1;
    m[15] = 1;
    buf b = {NULL, 0, 0, sizeof(vtx)};
    vtx *v = buf_push(&b, 6);
    if (!v)
        return;
    uint8_t col[4];
    rgba(col, c[0], c[1], c[2], c[3]);
    const float xy[6][2] = {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y0}, {x1, y1}, {x0, y1}};
    for (int k = 0; k < 6; k++) {
        v[k].x = xy[k][0];
        v[k].y = xy[k][1];
        v[k].z = 0;
        memcpy(v[k].rgba, col, 4);
    }
    glDisable(GL_DEPTH_TEST);
    glEnable(GL_BLEND);
    glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    glUseProgram(r->flat);
    glUniformMatrix4fv(r->flat_mvp, 1, GL_FALSE, m);
    glBindVertexArray(r->vao[2]);
    upload(r->vbo[2], &b);
    glDrawArrays(GL_TRIANGLES, 0, 6);
    glBindVertexArray(0);
    free(b.data);
}

unsigned char *vw_renderer_read_pixels(const vw_camera *cam)
{
    int w = cam->width, h = cam->height;
    size_t row = (size_t)w * 3;
    unsigned char *px = malloc(row * (size_t)h), *tmp = malloc(row);
    if (!px || !tmp) {
        free(px);
        free(tmp);
        return NULL;
    }
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadBuffer(GL_BACK);
    glReadPixels(0, 0, w, h, GL_RGB, GL_UNSIGNED_BYTE, px);
    for (int y = 0; y < h / 2; y++) { /* GL rows are bottom to top */
        memcpy(tmp, px + (size_t)y * row, row);
        memcpy(px + (size_t)y * row, px + (size_t)(h - 1 - y) * row, row);
        memcpy(px + (size_t)(h - 1 - y) * row, tmp, row);
    }
    free(tmp);
    return px;
}
