/* psys plot FILE.csv --y COLUMNS [--x COLUMN] [--particle I] [--size WxH]
 *           [--title TEXT] --out FILE.png
 * Plots columns of any psys CSV (trajectory, energy) against another column
 * (docs/cli.md "psys plot"). In a trajectory (a column `i`), each particle is
 * its own line unless --particle picks one. */
#include "cli.h"
#include "render.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define MAX_Y 16

typedef struct plot_opts {
    const char *file, *x, *y, *out, *particle, *size, *title;
} plot_opts;


/* Split line (modified in place) at commas into at most cap fields. */
static int split(char *line, char **fields, int cap)
{
    int n = 0;
    for (char *p = line, *f; (f = strsep(&p, ",")) != NULL;) {
        if (n == cap)
            return cap + 1;
        size_t l = strlen(f);
        if (l && f[l - 1] == '\r')
            f[l - 1] = '\0';
        fields[n++] = f;
    }
    return n;
}

typedef struct column_data {
    double *v;
    size_t n, cap;
} column_data;

static int push(column_data *c, double v)
{
    if (c->n == c->cap) {
        size_t nc = c->cap ? 2 * c->cap : 1024;
        double *nv = realloc(c->v, nc * sizeof *nv);
        if (!nv)
            return -1;
        c->v = nv;
        c->cap = nc;
    }
    c->v[c->n++] = v;
    return 0;
}

static int find_column(char **names, int n, const char *want)
{
    for (int k = 0; k < n; k++)
        if (strcmp(names[k], want) == 0)
            return k;
    return -1;
}

static void list_columns(char *buf, size_t cap, char **names, int n)
{
    buf[0] = '\0';
    for (int k = 0; k < n; k++)
        snprintf(buf + strlen(buf), cap - strlen(buf), "%s%s", k ? ", " : "", names[k]);
}

int cmd_plot(int argc, char **argv)
{
    plot_opts o;
    memset(&o, 0, sizeof o);
    for (int i = 1; i < argc; i++) {
        int bad = 0;
        if (cli_take(argc, argv, &i, "--x", &o.x, &bad) || cli_take(argc, argv, &i, "--y", &o.y, &bad)
            || cli_take(argc, argv, &i, "--out", &o.out, &bad) || cli_take(argc, argv, &i, "--particle", &o.particle, &bad)
            || cli_take(argc, argv, &i, "--size", &o.size, &bad) || cli_take(argc, argv, &i, "--title", &o.title, &bad)) {
            if (bad)
                return EXIT_BAD_INPUT;
        } else if (argv[i][0] == '-' && argv[i][1] != '\0') {
            cli_error("plot: unknown option %s (see psys --help)", argv[i]);
            return EXIT_BAD_INPUT;
        } else if (!o.file) {
            o.file = argv[i];
        } else {
            cli_error("plot: more than one file given (%s and %s)", o.file, argv[i]);
            return EXIT_BAD_INPUT;
        }
    }
    if (!o.file || !o.y || !o.out) {
        cli_error("plot: usage: psys plot FILE.csv --y COLUMN[,COLUMN...] [--x COLUMN] --out FILE.png");
        return EXIT_BAD_INPUT;
    }
    const char *ext = strrchr(o.out, '.');
    if (!ext || strchr(ext, '/') || strcmp(ext, ".png") != 0) {
        cli_error("--out %s: psys plot writes PNG (use a name ending in .png)", o.out);
        return EXIT_BAD_INPUT;
    }
    if (strcmp(o.file, "-") != 0 && cli_same_file(o.file, o.out)) {
        cli_error("%s: --out would replace the file it reads", o.out);
        return EXIT_BAD_INPUT;
    }
    int W = 800, H = 600;
    if (o.size && parse_size(o.size, &W, &H) != 0) {
        cli_error("--size: must be WIDTHxHEIGHT, each from 16 to 8192 (got %s)", o.size);
        return EXIT_BAD_INPUT;
    }
    long long want_particle = -1;
    if (o.particle && parse_int(o.particle, 0, 1000000000000LL, &want_particle) != 0) {
        cli_error("--particle: must be a particle index >= 0 (got %s)", o.particle);
        return EXIT_BAD_INPUT;
    }
    const char *name = strcmp(o.file, "-") == 0 ? "<stdin>" : o.file;
    FILE *fp = strcmp(o.file, "-") == 0 ? stdin : fopen(o.file, "rb");
    if (!fp) {
        cli_error("%s: cannot open: %s", name, strerror(errno));
        return EXIT_BAD_INPUT;
    }
    size_t len;
    char *text = cli_read_all(fp, &len);
    if (fp != stdin)
        fclose(fp);
    if (!text) {
        cli_error("%s: cannot read", name);
        return EXIT_BAD_INPUT;
    }

    int status = EXIT_BAD_INPUT;
    char *ylist = strdup(o.y);
    column_data xs = {0}, is = {0}, ys[MAX_Y];
    memset(ys, 0, sizeof ys);
    plot_series *series = NULL;
    double **bufs = NULL;
    char **labels = NULL;
    size_t nseries = 0;
    if (!ylist) {
        cli_error("out of memory");
        goto done;
    }
    char *p = text;
    char *header = strsep(&p, "\n");
    enum { MAXCOL = 4096 };
    static char *names[MAXCOL + 1];
    int ncol = split(header, names, MAXCOL);
    if (ncol > MAXCOL || ncol < 1 || (ncol == 1 && names[0][0] == '\0')) {
        cli_error("%s: line 1: not a CSV header", name);
        goto done;
    }
    char cols[2048];
    list_columns(cols, sizeof cols, names, ncol);
    int xcol = o.x ? find_column(names, ncol, o.x) : find_column(names, ncol, "t");
    if (xcol < 0 && !o.x)
        xcol = 0;
    if (xcol < 0) {
        cli_error("--x: no column \"%s\" in %s (columns: %s)", o.x, name, cols);
        goto done;
    }
    int ycol[MAX_Y], ny = 0;
    for (char *q = ylist, *c; (c = strsep(&q, ",")) != NULL;) {
        if (ny == MAX_Y) {
            cli_error("--y: at most %d columns", MAX_Y);
            goto done;
        }
        if ((ycol[ny] = find_column(names, ncol, c)) < 0) {
            cli_error("--y: no column \"%s\" in %s (columns: %s)", c, name, cols);
            goto done;
        }
        ny++;
    }
    int icol = find_column(names, ncol, "i");
    if (o.particle && icol < 0) {
        cli_error("--particle: %s has no column \"i\" (it is not a trajectory)", name);
        goto done;
    }
    /* Rows. */
    static char *f[MAXCOL + 1];
    size_t line = 1;
    for (char *row; (row = strsep(&p, "\n")) != NULL;) {
        line++;
        if (row[0] == '\0' || (row[0] == '\r' && row[1] == '\0'))
            continue;
        int nf = split(row, f, MAXCOL);
        if (nf != ncol) {
            cli_error("%s: line %zu: %d fields, the header has %d", name, line, nf > MAXCOL ? MAXCOL : nf, ncol);
            goto done;
        }
        double v[MAX_Y + 2];
        int need[MAX_Y + 2], nn = 0;
        need[nn++] = xcol;
        for (int k = 0; k < ny; k++)
            need[nn++] = ycol[k];
        if (icol >= 0)
            need[nn++] = icol;
        for (int k = 0; k < nn; k++) {
            char *end;
            errno = 0;
            v[k] = cli_strtod(f[need[k]], &end);
            if (end == f[need[k]] || *end) {
                cli_error("%s: line %zu: column \"%s\" is not a number (got \"%s\")", name, line, names[need[k]],
                          f[need[k]]);
                goto done;
            }
        }
        if (icol >= 0 && !(v[nn - 1] >= 0 && v[nn - 1] < 1e9 && v[nn - 1] == floor(v[nn - 1]))) {
            cli_error("%s: line %zu: column \"i\" is not a particle index (got \"%s\")", name, line, f[icol]);
            goto done;
        }
        if (o.particle && v[nn - 1] != (double)want_particle)
            continue;
        int bad = push(&xs, v[0]);
        for (int k = 0; k < ny; k++)
            bad |= push(&ys[k], v[1 + k]);
        if (icol >= 0)
            bad |= push(&is, v[nn - 1]);
        if (bad) {
            cli_error("out of memory");
            goto done;
        }
    }
    if (xs.n == 0) {
        if (o.particle)
            cli_error("--particle: no rows for particle %lld in %s", want_particle, name);
        else
            cli_error("%s: no rows to plot", name);
        goto done;
    }
    /* Groups: one per particle in a trajectory (unless --particle), else one. */
    size_t ngroups = 1;
    size_t *count = NULL;
    if (icol >= 0 && !o.particle) {
        size_t maxi = 0;
        for (size_t r = 0; r < is.n; r++)
            if ((size_t)is.v[r] > maxi)
                maxi = (size_t)is.v[r];
        if (maxi >= 100000) {
            cli_error("%s: %zu particles; pick one with --particle", name, maxi + 1);
            goto done;
        }
        ngroups = maxi + 1;
    }
    count = calloc(ngroups, sizeof *count);
    nseries = ngroups * (size_t)ny;
    series = calloc(nseries, sizeof *series);
    bufs = calloc(2 * nseries, sizeof *bufs);
    labels = calloc(nseries, sizeof *labels);
    if (!count || !series || !bufs || !labels) {
        free(count);
        cli_error("out of memory");
        goto done;
    }
    for (size_t r = 0; r < xs.n; r++)
        count[ngroups > 1 ? (size_t)is.v[r] : 0]++;
    bool oom = false;
    for (size_t g = 0; g < ngroups; g++)
        for (int k = 0; k < ny; k++) {
            size_t sidx = g * (size_t)ny + (size_t)k;
            size_t n = count[g];
            bufs[2 * sidx] = malloc((n ? n : 1) * sizeof(double));
            bufs[2 * sidx + 1] = malloc((n ? n : 1) * sizeof(double));
            labels[sidx] = malloc(strlen(names[ycol[k]]) + 32);
            oom |= !bufs[2 * sidx] || !bufs[2 * sidx + 1] || !labels[sidx];
            if (labels[sidx]) {
                if (ngroups > 1)
                    sprintf(labels[sidx], "%s [i=%zu]", names[ycol[k]], g);
                else if (o.particle)
                    sprintf(labels[sidx], "%s [i=%lld]", names[ycol[k]], want_particle);
                else
                    strcpy(labels[sidx], names[ycol[k]]);
            }
            series[sidx].label = labels[sidx];
            series[sidx].x = bufs[2 * sidx];
            series[sidx].y = bufs[2 * sidx + 1];
        }
    if (oom) {
        free(count);
        cli_error("out of memory");
        goto done;
    }
    for (size_t r = 0; r < xs.n; r++) {
        size_t g = ngroups > 1 ? (size_t)is.v[r] : 0;
        for (int k = 0; k < ny; k++) {
            size_t sidx = g * (size_t)ny + (size_t)k;
            bufs[2 * sidx][series[sidx].n] = xs.v[r];
            bufs[2 * sidx + 1][series[sidx].n++] = ys[k].v[r];
        }
    }
    free(count);
    /* Drop empty groups (particle indices that never occur). */
    size_t kept = 0;
    for (size_t k = 0; k < nseries; k++)
        if (series[k].n)
            series[kept++] = series[k];

    char ylabel[512] = "";
    for (int k = 0; k < ny; k++)
        snprintf(ylabel + strlen(ylabel), sizeof ylabel - strlen(ylabel), "%s%s", k ? ", " : "", names[ycol[k]]);
    const char *base = strrchr(name, '/') ? strrchr(name, '/') + 1 : name;
    plot_spec spec = {W, H, o.title ? o.title : base, names[xcol], ylabel};
    outfile out;
    if (outfile_open(&out, o.out, "--out") != 0)
        goto done;
    if (plot_write_png(out.fp, &spec, series, kept) != 0) {
        cli_error("--out %s: cannot draw or write the plot", o.out);
        outfile_abort(&out);
        status = EXIT_RUN_FAILED;
        goto done;
    }
    status = outfile_commit(&out) == 0 ? EXIT_OK : EXIT_RUN_FAILED;

done:
    if (bufs)
        for (size_t k = 0; k < 2 * nseries; k++)
            free(bufs[k]);
    if (labels)
        for (size_t k = 0; k < nseries; k++)
            free(labels[k]);
    free(bufs);
    free(labels);
    free(series);
    free(xs.v);
    free(is.v);
    for (int k = 0; k < MAX_Y; k++)
        free(ys[k].v);
    free(ylist);
    free(text);
    return status;
}
