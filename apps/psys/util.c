/* Messages, number parsing and atomic output files for the CLI. */
#include "cli.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* Under mpiexec only rank 0 speaks (cmd_run.c sets it); the other ranks
 * meet the same errors in the same places and stay silent. */
int cli_silent = 0;

void cli_error(const char *fmt, ...)
{
    va_list ap;
    if (cli_silent)
        return;
    fputs("psys: ", stderr);
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fputc('\n', stderr);
}

/* path with its directory resolved and, where it exists, links followed
 * (as outfile_open writes through them); NULL if the directory cannot be
 * resolved or out of memory. */
static char *canonical(const char *path)
{
    char *r = realpath(path, NULL);
    if (r)
        return r;
    const char *slash = strrchr(path, '/');
    const char *base = slash ? slash + 1 : path;
    size_t dlen = slash ? (slash == path ? 1 : (size_t)(slash - path)) : 1;
    char *dir = malloc(dlen + 1);
    if (!dir)
        return NULL;
    memcpy(dir, slash ? path : ".", dlen);
    dir[dlen] = '\0';
    char *rd = realpath(dir, NULL);
    free(dir);
    if (!rd)
        return NULL;
    size_t n = strlen(rd) + strlen(base) + 2;
    char *out = malloc(n);
    if (out)
        snprintf(out, n, "%s/%s", strcmp(rd, "/") == 0 ? "" : rd, base);
    free(rd);
    return out;
}

bool cli_same_file(const char *a, const char *b)
{
    if (!a || !b || !a[0] || !b[0])
        return false;
    struct stat sa, sb;
    bool ea = stat(a, &sa) == 0, eb = stat(b, &sb) == 0;
    if ((ea && !S_ISREG(sa.st_mode)) || (eb && !S_ISREG(sb.st_mode)))
        return false; /* /dev/null, a pipe: written directly, never replaced */
    if (ea && eb)
        return sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
    if (strcmp(a, b) == 0)
        return true;
    char *ca = canonical(a), *cb = canonical(b);
    bool same = ca && cb && strcmp(ca, cb) == 0;
    free(ca);
    free(cb);
    return same;
}

int outfile_open(outfile *o, const char *path, const char *what)
{
    memset(o, 0, sizeof *o);
    struct stat st;
    if (stat(path, &st) == 0 && !S_ISREG(st.st_mode)) {
        /* A device or FIFO (/dev/null, a pipe to another program) is written
         * directly: renaming over it would replace it with a regular file. */
        if (S_ISDIR(st.st_mode)) {
            cli_error("%s %s: is a directory", what, path);
            return -1;
        }
        o->fp = fopen(path, "w");
        if (!o->fp) {
            cli_error("%s %s: cannot open: %s", what, path, strerror(errno));
            return -1;
        }
        return 0;
    }
    /* Through a symbolic link, replace the file it points to, not the link. */
    char *resolved = NULL;
    if (lstat(path, &st) == 0 && S_ISLNK(st.st_mode))
        resolved = realpath(path, NULL);
    if (resolved)
        path = resolved;
    size_t len = strlen(path);
    o->path = malloc(len + 1);
    o->tmp = malloc(len + 32);
    if (!o->path || !o->tmp) {
        cli_error("%s %s: out of memory", what, path);
        free(resolved);
        outfile_abort(o);
        return -1;
    }
    memcpy(o->path, path, len + 1);
    free(resolved);
    snprintf(o->tmp, len + 32, "%s.psys-tmp-XXXXXX", o->path);
    int fd = mkstemp(o->tmp);
    if (fd < 0) {
        cli_error("%s %s: cannot create: %s", what, path, strerror(errno));
        free(o->tmp);
        o->tmp = NULL;
        outfile_abort(o);
        return -1;
    }
    o->fp = fdopen(fd, "w");
    if (!o->fp) {
        cli_error("%s %s: cannot open: %s", what, path, strerror(errno));
        close(fd);
        outfile_abort(o);
        return -1;
    }
    /* mkstemp makes 0600 files; give results the usual permissions. */
    mode_t mask = umask(0);
    umask(mask);
    fchmod(fd, 0666 & ~mask);
    return 0;
}

int outfile_commit(outfile *o)
{
    if (!o->fp)
        return 0;
    if (!o->tmp) { /* written directly (a device or FIFO) */
        int bad = ferror(o->fp) | (fclose(o->fp) != 0);
        o->fp = NULL;
        return bad ? -1 : 0;
    }
    int bad = ferror(o->fp) || fflush(o->fp) != 0;
    bad |= fclose(o->fp) != 0;
    o->fp = NULL;
    if (bad || rename(o->tmp, o->path) != 0) {
        cli_error("%s: cannot write: %s", o->path, strerror(errno));
        remove(o->tmp);
        free(o->tmp);
        free(o->path);
        o->tmp = o->path = NULL;
        return -1;
    }
    free(o->tmp);
    free(o->path);
    o->tmp = o->path = NULL;
    return 0;
}

void outfile_abort(outfile *o)
{
    if (o->fp) {
        fclose(o->fp);
        o->fp = NULL;
    }
    if (o->tmp)
        remove(o->tmp);
    free(o->tmp);
    free(o->path);
    o->tmp = o->path = NULL;
}

void cli_stability_warning(const char *source, psys_scene *scene, int quiet)
{
    const psys_settings *set = psys_scene_settings(scene);
    if (quiet || strcmp(set->integrator, "implicit-euler") == 0 || strcmp(set->integrator, "rk45") == 0)
        return;
    double omega = psys_system_stiffest_omega(psys_scene_system(scene));
    if (!(omega > 0) || !(set->dt * omega > 2.0))
        return;
    cli_error("%s: warning: dt = %g is above the stability limit 2/omega_max = %.3g of %s for the stiffest "
              "spring (omega_max = %.4g rad/s); the run may blow up: use --integrator implicit-euler, or "
              "--dt %.2g or smaller",
              source, set->dt, 2.0 / omega, set->integrator, omega, 2.0 / omega);
}

double cli_strtod(const char *s, char **end)
{
    if (isspace((unsigned char)*s) || strpbrk(s, "xX")) {
        *end = (char *)s;
        return 0;
    }
    return strtod(s, end);
}

int parse_nonneg(const char *s, double *out)
{
    char *end;
    errno = 0;
    double v = cli_strtod(s, &end);
    if (end == s || *end || errno || !isfinite(v) || v < 0)
        return -1;
    *out = v;
    return 0;
}

int parse_positive(const char *s, double *out)
{
    double v;
    if (parse_nonneg(s, &v) != 0 || v == 0)
        return -1;
    *out = v;
    return 0;
}

int parse_int(const char *s, long long min, long long max, long long *out)
{
    char *end;
    errno = 0;
    long long v = strtoll(s, &end, 10);
    if (end == s || *end || errno || v < min || v > max)
        return -1;
    *out = v;
    return 0;
}

/* "--name VALUE" or "--name=VALUE"; returns 1 if argv[*i] is this option. */
int cli_take(int argc, char **argv, int *i, const char *name, const char **val, int *bad)
{
    size_t n = strlen(name);
    if (strncmp(argv[*i], name, n) != 0)
        return 0;
    if (argv[*i][n] == '=') {
        *val = argv[*i] + n + 1;
        return 1;
    }
    if (argv[*i][n] != '\0')
        return 0;
    if (*i + 1 >= argc) {
        cli_error("%s needs a value (see psys --help)", name);
        *bad = 1;
        return 1;
    }
    *val = argv[++*i];
    return 1;
}

/* 0 if name is a known solver; else -1 with the --integrator message. */
int cli_check_integrator(const char *name)
{
    if (psys_solver_exists(name))
        return 0;
    char known[256] = "";
    for (size_t i = 0; psys_solver_name_at(i); i++)
        snprintf(known + strlen(known), sizeof known - strlen(known), "%s%s", i ? ", " : "", psys_solver_name_at(i));
    cli_error("--integrator: unknown integrator (got %s; known: %s)", name, known);
    return -1;
}

/* Read all of fp into a NUL-terminated buffer (NULL on failure). */
char *cli_read_all(FILE *fp, size_t *len)
{
    size_t cap = 1 << 16, n = 0;
    char *buf = malloc(cap);
    if (!buf)
        return NULL;
    for (;;) {
        if (n + 1 >= cap) {
            char *nb = cap > ((size_t)-1) / 2 ? NULL : realloc(buf, cap * 2);
            if (!nb) {
                free(buf);
                return NULL;
            }
            buf = nb;
            cap *= 2;
        }
        size_t k = fread(buf + n, 1, cap - n - 1, fp);
        n += k;
        if (k == 0)
            break;
    }
    if (ferror(fp)) {
        free(buf);
        return NULL;
    }
    buf[n] = '\0';
    *len = n;
    return buf;
}
