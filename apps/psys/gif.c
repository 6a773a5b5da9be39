/* A minimal GIF89a encoder, used for --render out.gif when ffmpeg is not
 * installed: one fixed palette (a 6×6×6 colour cube and 40 greys, which suit
 * psys's pictures: a light background, grey springs, a few saturated
 * colours), LZW with the usual variable code width, looping forever. */
#include "render.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define HASH_SIZE 8192 /* open addressing, at most 4096 - 258 entries */

struct gif_writer {
    FILE *fp;
    int width, height;
    int bad;
    unsigned char *index; /* width*height palette indices */
    /* LZW state */
    int32_t hkey[HASH_SIZE];
    uint16_t hval[HASH_SIZE];
    uint32_t bitbuf;
    int nbits;
    unsigned char block[255];
    int blen;
};

static void put_byte(gif_writer *g, int c)
{
    if (fputc(c, g->fp) == EOF)
        g->bad = 1;
}

static void put_u16(gif_writer *g, unsigned v)
{
    put_byte(g, (int)(v & 0xff));
    put_byte(g, (int)(v >> 8));
}

gif_writer *gif_begin(FILE *fp, int width, int height)
{
    gif_writer *g = calloc(1, sizeof *g);
    if (!g)
        return NULL;
    g->index = malloc((size_t)width * (size_t)height);
    if (!g->index) {
        free(g);
        return NULL;
    }
    g->fp = fp;
    g->width = width;
    g->height = height;
    fputs("GIF89a", fp);
    put_u16(g, (unsigned)width);
    put_u16(g, (unsigned)height);
    put_byte(g, 0xF7); /* global colour table of 256 entries, 8-bit colour resolution */
    put_byte(g, 0);    /* background colour index */
    put_byte(g, 0);    /* square pixels */
    for (int i = 0; i < 216; i++) {
        put_byte(g, (i / 36) * 51);
        put_byte(g, (i / 6 % 6) * 51);
        put_byte(g, (i % 6) * 51);
    }
    for (int i = 0; i < 40; i++) {
        int v = (i * 255 + 19) / 39;
        put_byte(g, v);
        put_byte(g, v);
        put_byte(g, v);
    }
    /* NETSCAPE2.0 extension: loop forever. */
    static const unsigned char ident[] = "NETSCAPE2.0";
    put_byte(g, 0x21);
    put_byte(g, 0xFF);
    put_byte(g, 0x0B);
    for (int i = 0; i < 11; i++)
        put_byte(g, ident[i]);
    put_byte(g, 0x03);
    put_byte(g, 0x01);
    put_u16(g, 0);
    put_byte(g, 0x00);
    return g;
}

/* Palette index of an opaque pixel. */
static unsigned char quantise(int r, int gr, int b)
{
    int mx = r > gr ? (r > b ? r : b) : (gr > b ? gr : b);
    int mn = r < gr ? (r < b ? r : b) : (gr < b ? gr : b);
    if (mx - mn <= 12)
        return (unsigned char)(216 + ((r + gr + b) * 39 + 382) / 765);
    return (unsigned char)(36 * ((r * 5 + 127) / 255) + 6 * ((gr * 5 + 127) / 255) + (b * 5 + 127) / 255);
}

static void flush_block(gif_writer *g)
{
    if (g->blen == 0)
        return;
    put_byte(g, g->blen);
    if (fwrite(g->block, 1, (size_t)g->blen, g->fp) != (size_t)g->blen)
        g->bad = 1;
    g->blen = 0;
}

static void put_code(gif_writer *g, unsigned code, int width)
{
    g->bitbuf |= (uint32_t)code << g->nbits;
    g->nbits += width;
    while (g->nbits >= 8) {
        g->block[g->blen++] = (unsigned char)(g->bitbuf & 0xff);
        if (g->blen == 255)
            flush_block(g);
        g->bitbuf >>= 8;
        g->nbits -= 8;
    }
}

static void table_clear(gif_writer *g) { memset(g->hkey, 0xff, sizeof g->hkey); }

static unsigned hash_of(int32_t key) { return ((uint32_t)key * 2654435761u) >> 19; /* 13 bits */ }

int gif_frame(gif_writer *g, const unsigned char *bgra, int stride, int delay_cs)
{
    int w = g->width, h = g->height;
    for (int y = 0; y < h; y++) {
        const unsigned char *row = bgra + (size_t)y * (size_t)stride;
        for (int x = 0; x < w; x++)
            g->index[(size_t)y * (size_t)w + (size_t)x] = quantise(row[4 * x + 2], row[4 * x + 1], row[4 * x]);
    }
    /* Graphic control extension: delay, no transparency, "do not dispose". */
    put_byte(g, 0x21);
    put_byte(g, 0xF9);
    put_byte(g, 0x04);
    put_byte(g, 0x04);
    put_u16(g, (unsigned)(delay_cs < 0 ? 0 : delay_cs > 65535 ? 65535 : delay_cs));
    put_byte(g, 0);
    put_byte(g, 0);
    /* Image descriptor: the whole screen, no local colour table. */
    put_byte(g, 0x2C);
    put_u16(g, 0);
    put_u16(g, 0);
    put_u16(g, (unsigned)w);
    put_u16(g, (unsigned)h);
    put_byte(g, 0);
    put_byte(g, 8); /* LZW minimum code size */

    const unsigned clear = 256, eoi = 257;
    int width = 9;
    unsigned next = 258;
    g->bitbuf = 0;
    g->nbits = 0;
    g->blen = 0;
    table_clear(g);
    put_code(g, clear, width);
    size_t n = (size_t)w * (size_t)h;
    unsigned prefix = g->index[0];
    for (size_t i = 1; i < n; i++) {
        unsigned c = g->index[i];
        int32_t key = (int32_t)((prefix << 8) | c);
        unsigned slot = hash_of(key);
        while (g->hkey[slot] != -1 && g->hkey[slot] != key)
            slot = (slot + 1) & (HASH_SIZE - 1);
        if (g->hkey[slot] == key) {
            prefix = g->hval[slot];
            continue;
        }
        put_code(g, prefix, width);
        if (next < 4096) {
            if (next == (1u << width))
                width++;
            g->hkey[slot] = key;
            g->hval[slot] = (uint16_t)next++;
        } else {
            put_code(g, clear, width);
            table_clear(g);
            width = 9;
            next = 258;
        }
        prefix = c;
    }
    put_code(g, prefix, width);
    put_code(g, eoi, width);
    if (g->nbits > 0) {
        g->block[g->blen++] = (unsigned char)(g->bitbuf & 0xff);
        if (g->blen == 255)
            flush_block(g);
        g->nbits = 0;
    }
    flush_block(g);
    put_byte(g, 0); /* end of the image data */
    return g->bad ? -1 : 0;
}

int gif_end(gif_writer *g)
{
    if (!g)
        return -1;
    put_byte(g, 0x3B);
    int bad = g->bad;
    free(g->index);
    free(g);
    return bad ? -1 : 0;
}
