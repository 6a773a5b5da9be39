/* Text for the HUD and the controls panel: DejaVu Sans (fonts-dejavu-core)
 * baked by stb_truetype into a one-channel texture atlas, drawn as textured
 * quads (one buffer upload per frame). */
#include "view_internal.h"

#include <epoxy/gl.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define STB_TRUETYPE_IMPLEMENTATION
#define STBTT_STATIC
#include <stb/stb_truetype.h>

#define ATLAS 512
#define FIRST 32
#define COUNT 95

GLuint vw_gl_program(const char *vs, const char *fs, char *why, size_t cap);

static const char TEXT_VS[] =
    "#version 330 core\n"
    "layout(location = 0) in vec2 a_pos;\n"
    "layout(location = 1) in vec2 a_uv;\n"
    "layout(location = 2) in vec4 a_color;\n"
    "uniform vec2 u_screen;\n"
    "out vec2 v_uv;\n"
    "out vec4 v_color;\n"
    "void main() {\n"
    "  gl_Position = vec4(a_pos.x / u_screen.x * 2.0 - 1.0, 1.0 - a_pos.y / u_screen.y * 2.0, 0.0, 1.0);\n"
    "  v_uv = a_uv;\n"
    "  v_color = a_color;\n"
    "}\n";
static const char TEXT_FS[] =
    "#version 330 core\n"
    "in vec2 v_uv;\n"
    "in vec4 v_color;\n"
    "uniform sampler2D u_tex;\n"
    "out vec4 o_color;\n"
    "void main() { o_color = vec4(v_color.rgb, v_color.a * texture(u_tex, v_uv).r); }\n";

typedef struct tvtx {
    float x, y, u, v;
    uint8_t rgba[4];
} tvtx;

struct vw_text {
    stbtt_bakedchar chars[COUNT];
    float height, ascent;
    GLuint tex, prog, vao, vbo;
    GLint screen;
    tvtx *v;
    size_t n, cap;
};

static unsigned char *read_file(const char *path, size_t *len)
{
    FILE *fp = fopen(path, "rb");
    if (!fp)
        return NULL;
    unsigned char *data = NULL;
    if (fseek(fp, 0, SEEK_END) == 0) {
        long n = ftell(fp);
        if (n > 0 && fseek(fp, 0, SEEK_SET) == 0 && (data = malloc((size_t)n)) != NULL) {
            if (fread(data, 1, (size_t)n, fp) != (size_t)n) {
                free(data);
                data = NULL;
            } else {
                *len = (size_t)n;
            }
        }
    }
    fclose(fp);
    return data;
}

vw_text *vw_text_create(const char *font_path, float pixel_height, char *why, size_t cap)
{
    static const char *const fonts[] = {
        "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
        "/usr/share/fonts/TTF/DejaVuSans.ttf",
        "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    };
    size_t len = 0;
    unsigned char *ttf = NULL;
    const char *used = font_path;
    if (font_path) {
        ttf = read_file(font_path, &len);
    } else {
        for (size_t k = 0; k < sizeof fonts / sizeof *fonts && !ttf; k++)
            ttf = read_file(used = fonts[k], &len);
    }
    if (!ttf) {
        snprintf(why, cap, "cannot read the font %s (install fonts-dejavu-core)", used ? used : fonts[0]);
        return NULL;
    }
    vw_text *t = calloc(1, sizeof *t);
    unsigned char *bitmap = malloc(ATLAS * ATLAS);
    if (!t || !bitmap) {
        free(t);
        free(bitmap);
        free(ttf);
        snprintf(why, cap, "out of memory");
        return NULL;
    }
    int rc = stbtt_BakeFontBitmap(ttf, 0, pixel_height, bitmap, ATLAS, ATLAS, FIRST, COUNT, t->chars);
    stbtt_fontinfo info;
    int ascent = 0, descent = 0, gap = 0;
    if (rc != 0 && stbtt_InitFont(&info, ttf, stbtt_GetFontOffsetForIndex(ttf, 0))) {
        stbtt_GetFontVMetrics(&info, &ascent, &descent, &gap);
        float s = stbtt_ScaleForPixelHeight(&info, pixel_height);
        t->ascent = (float)ascent * s;
    }
    free(ttf);
    if (rc == 0) {
        free(bitmap);
        free(t);
        snprintf(why, cap, "%s: not a font stb_truetype can read", used);
        return NULL;
    }
    t->height = pixel_height;
    t->prog = vw_gl_program(TEXT_VS, TEXT_FS, why, cap);
    if (!t->prog) {
        free(bitmap);
        free(t);
        return NULL;
    }
    t->screen = glGetUniformLocation(t->prog, "u_screen");
    glGenTextures(1, &t->tex);
    glBindTexture(GL_TEXTURE_2D, t->tex);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_R8, ATLAS, ATLAS, 0, GL_RED, GL_UNSIGNED_BYTE, bitmap);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    free(bitmap);
    glGenVertexArrays(1, &t->vao);
    glGenBuffers(1, &t->vbo);
    glBindVertexArray(t->vao);
    glBindBuffer(GL_ARRAY_BUFFER, t->vbo);
    glVertexAttribPointer(0, 2, GL_FLOAT, GL_FALSE, sizeof(tvtx), (void *)offsetof(tvtx, x));
    glVertexAttribPointer(1, 2, GL_FLOAT, GL_FALSE, sizeof(tvtx), (void *)offsetof(tvtx, u));
    glVertexAttribPointer(2, 4, GL_UNSIGNED_BYTE, GL_TRUE, sizeof(tvtx), (void *)offsetof(tvtx, rgba));
    for (GLuint k = 0; k < 3; k++)
        glEnableVertexAttribArray(k);
    glBindVertexArray(0);
    return t;
}

void vw_text_destroy(vw_text *t)
{
    if (!t)
        return;
    glDeleteTextures(1, &t->tex);
    glDeleteBuffers(1, &t->vbo);
    glDeleteVertexArrays(1, &t->vao);
    glDeleteProgram(t->prog);
    free(t->v);
    free(t);
}

float vw_text_line_height(const vw_text *t) { return t->height * 1.3f; }

float vw_text_ascent(const vw_text *t) { return t->ascent; }

float vw_text_width(const vw_text *t, const char *s)
{
    float w = 0;
    for (; *s; s++) {
        int c = (unsigned char)*s;
        if (c < FIRST || c >= FIRST + COUNT)
            c = '?';
        w += t->chars[c - FIRST].xadvance;
    }
    return w;
}

float vw_text_add(vw_text *t, float x, float y, const char *s, const float c[4])
{
    uint8_t col[4];
    for (int k = 0; k < 4; k++)
        col[k] = (uint8_t)(c[k] * 255 + 0.5f);
    for (; *s; s++) {
        int ch = (unsigned char)*s;
        if (ch < FIRST || ch >= FIRST + COUNT)
            ch = '?';
        stbtt_aligned_quad q;
        stbtt_GetBakedQuad(t->chars, ATLAS, ATLAS, ch - FIRST, &x, &y, &q, 1);
        if (ch == ' ')
            continue;
        if (t->n + 6 > t->cap) {
            size_t cap = t->cap ? t->cap * 2 : 1536;
            tvtx *v = realloc(t->v, cap * sizeof *v);
            if (!v)
                return x;
            t->v = v;
            t->cap = cap;
        }
        const float xy[6][4] = {{q.x0, q.y0, q.s0, q.t0}, {q.x1, q.y0, q.s1, q.t0}, {q.x1, q.y1, q.s1, q.t1},
                                {q.x0, q.y0, q.s0, q.t0}, {q.x1, q.y1, q.s1, q.t1}, {q.x0, q.y1, q.s0, q.t1}};
        for (int k = 0; k < 6; k++) {
            tvtx *v = &t->v[t->n++];
            v->x = xy[k][0];
            v->y = xy[k][1];
            v->u = xy[k][2];
            v->v = xy[k][3];
            memcpy(v->rgba, col, 4);
        }
    }
    return x;
}

void vw_text_flush(vw_text *t, const vw_camera *cam)
{
    if (!t->n)
        return;
    glDisable(GL_DEPTH_TEST);
    glEnable(GL_BLEND);
    glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    glUseProgram(t->prog);
    glUniform2f(t->screen, (float)cam->width, (float)cam->height);
    glActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_2D, t->tex);
    glBindVertexArray(t->vao);
    glBindBuffer(GL_ARRAY_BUFFER, t->vbo);
    glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)(t->n * sizeof *t->v), t->v, GL_STREAM_DRAW);
    glDrawArrays(GL_TRIANGLES, 0, (GLsizei)t->n);
    glBindVertexArray(0);
    t->n = 0;
}
