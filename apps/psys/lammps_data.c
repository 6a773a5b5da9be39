/* Reader of LAMMPS data files for `psys import lammps` (lammps_data.h).
 *
 * The format (LAMMPS manual, read_data): the first line is a title; then
 * header lines ("500 atoms", "1 atom types", "0 8.39 xlo xhi", ...); then
 * sections, each a keyword line ("Atoms # atomic") followed by one line per
 * item. '#' starts a comment anywhere; blank lines are skipped. Only what an
 * atom_style atomic system with pair_style lj/cut holds is accepted;
 * anything else is refused with the line it was found on. */
#include "lammps_data.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MAXTOK 16
#define MAX_TYPES 1000000

typedef struct reader {
    FILE *fp;
    char *line;          /* current line, comment cut off, tokenised in place */
    size_t cap;
    long lineno;
    char shown[96];      /* the current line as read, for (got "...") */
    char comment[64];    /* text after '#', trimmed */
    char *tok[MAXTOK];
    int ntok;            /* tokens on the line (MAXTOK + 1: too many) */
    char *msg;
    size_t msgcap;
} reader;

static int fail(reader *r, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

/* "line N: problem (got "line text")" */
static int fail(reader *r, const char *fmt, ...)
{
    char what[400];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(what, sizeof what, fmt, ap);
    va_end(ap);
    snprintf(r->msg, r->msgcap, "line %ld: %s (got \"%s\")", r->lineno, what, r->shown);
    return -1;
}

/* A problem not tied to one line. */
static int fail_file(reader *r, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;
static int fail_file(reader *r, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(r->msg, r->msgcap, fmt, ap);
    va_end(ap);
    return -1;
}

/* Read the next line: 1 read, 0 end of file, -1 error (message set). The
 * comment is split off and the rest tokenised; ntok may be 0 (blank). */
static int next_line(reader *r)
{
    errno = 0;
    ssize_t len = getline(&r->line, &r->cap, r->fp);
    if (len < 0) {
        if (ferror(r->fp))
            return fail_file(r, "cannot read after line %ld: %s", r->lineno, strerror(errno ? errno : EIO));
        return 0;
    }
    r->lineno++;
    while (len > 0 && (r->line[len - 1] == '\n' || r->line[len - 1] == '\r'))
        r->line[--len] = '\0';
    /* The line as shown in messages: printable, at most 80 characters. */
    size_t k = 0, i = 0;
    while (i < (size_t)len && k < 80) {
        unsigned char c = (unsigned char)r->line[i++];
        r->shown[k++] = (c >= 32 && c < 127 && c != '"') ? (char)c : (c == '"' ? '\'' : '?');
    }
    if (i < (size_t)len) {
        memcpy(r->shown + k, "...", 4);
    } else {
        r->shown[k] = '\0';
    }
    if (strlen(r->line) != (size_t)len)
        return fail(r, "not a text line (it holds a NUL byte)");
    r->comment[0] = '\0';
    char *hash = strchr(r->line, '#');
    if (hash) {
        *hash = '\0';
        char *c = hash + 1;
        while (isspace((unsigned char)*c))
            c++;
        snprintf(r->comment, sizeof r->comment, "%s", c);
        size_t cl = strlen(r->comment);
        while (cl > 0 && isspace((unsigned char)r->comment[cl - 1]))
            r->comment[--cl] = '\0';
    }
    r->ntok = 0;
    char *p = r->line;
    for (;;) {
        while (*p && isspace((unsigned char)*p))
            p++;
        if (!*p)
            break;
        if (r->ntok == MAXTOK) {
            r->ntok = MAXTOK + 1;
            break;
        }
        r->tok[r->ntok++] = p;
        while (*p && !isspace((unsigned char)*p))
            p++;
        if (*p)
            *p++ = '\0';
    }
    return 1;
}

/* The next non-blank line: 1, 0 at end of file, -1 on error. */
static int next_nonblank(reader *r)
{
    int st;
    while ((st = next_line(r)) == 1 && r->ntok == 0)
        ;
    return st;
}

static int to_ll(const char *s, long long *out)
{
    char *end;
    errno = 0;
    long long v = strtoll(s, &end, 10);
    if (end == s || *end || errno)
        return -1;
    *out = v;
    return 0;
}

static int to_double(const char *s, double *out)
{
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    if (end == s || *end || !isfinite(v) || strpbrk(s, "xX")) /* decimal only, as LAMMPS writes */
        return -1;
    /* strtod's ERANGE for subnormal results is fine; overflow gave inf above. */
    *out = v;
    return 0;
}

/* Do tokens from..ntok-1 spell words (space-separated)? */
static bool words_are(const reader *r, int from, const char *words)
{
    int i = from;
    const char *w = words;
    while (*w) {
        size_t n = strcspn(w, " ");
        if (i >= r->ntok || strlen(r->tok[i]) != n || strncmp(r->tok[i], w, n) != 0)
            return false;
        i++;
        w += n;
        while (*w == ' ')
            w++;
    }
    return i == r->ntok;
}

/* Header counts that must be zero in an atomic system. */
static const char *const zero_counts[] = {
    "bonds", "angles", "dihedrals", "impropers", "bond types", "angle types", "dihedral types",
    "improper types", "ellipsoids", "lines", "triangles", "bodies", NULL};
/* Header counts that do not matter here. */
static const char *const ignored_counts[] = {"extra bond per atom", "extra angle per atom", "extra dihedral per atom",
                                              "extra improper per atom", "extra special per atom", NULL};
/* Sections LAMMPS knows that an atomic lj/cut system has no use for. */
static const char *const other_sections[] = {
    "Bonds", "Angles", "Dihedrals", "Impropers", "Ellipsoids", "Lines", "Triangles", "Bodies",
    "Bond Coeffs", "Angle Coeffs", "Dihedral Coeffs", "Improper Coeffs", "BondBond Coeffs", "BondAngle Coeffs",
    "MiddleBondTorsion Coeffs", "EndBondTorsion Coeffs", "AngleTorsion Coeffs", "AngleAngleTorsion Coeffs",
    "BondBond13 Coeffs", "AngleAngle Coeffs", NULL};

enum { SEC_NONE, SEC_MASSES, SEC_PAIR, SEC_PAIRIJ, SEC_ATOMS, SEC_VELOCITIES, SEC_OTHER };

static int section_of(const reader *r)
{
    if (words_are(r, 0, "Masses"))
        return SEC_MASSES;
    if (words_are(r, 0, "Pair Coeffs"))
        return SEC_PAIR;
    if (words_are(r, 0, "PairIJ Coeffs"))
        return SEC_PAIRIJ;
    if (words_are(r, 0, "Atoms"))
        return SEC_ATOMS;
    if (words_are(r, 0, "Velocities"))
        return SEC_VELOCITIES;
    for (int i = 0; other_sections[i]; i++)
        if (words_are(r, 0, other_sections[i]))
            return SEC_OTHER;
    return SEC_NONE;
}

/* A pair style comment is lj/cut, maybe with an accelerator suffix. */
static bool lj_cut_style(const char *s)
{
    static const char *const ok[] = {"lj/cut", "lj/cut/omp", "lj/cut/opt", "lj/cut/gpu", "lj/cut/intel", "lj/cut/kk", NULL};
    for (int i = 0; ok[i]; i++)
        if (strcmp(s, ok[i]) == 0)
            return true;
    return false;
}

typedef struct parse {
    reader r;
    lmp_data *d;
    bool any_coeffs;
    bool have_atoms_count, have_types_count, have_axis[3];
    bool seen[SEC_OTHER];
    long *atom_line;   /* line of each atom, for duplicate ids */
    size_t acap;
    long coeff_line;   /* line of the first coefficient line */
} parse;

static int read_header(parse *p)
{
    reader *r = &p->r;
    lmp_data *d = p->d;
    static const char *const axis_words[3] = {"xlo xhi", "ylo yhi", "zlo zhi"};
    for (;;) {
        int st = next_nonblank(r);
        if (st <= 0)
            return st < 0 ? -1 : fail_file(r, "the file ends after its header: no Atoms section");
        if (r->ntok > MAXTOK || section_of(r) != SEC_NONE || !strchr("0123456789+-.", r->tok[0][0]))
            return 1; /* the first section keyword (or garbage, reported there) */
        bool axis = false;
        for (int k = 0; k < 3; k++)
            if (r->ntok == 4 && words_are(r, 2, axis_words[k])) {
                double lo, hi;
                if (to_double(r->tok[0], &lo) != 0 || to_double(r->tok[1], &hi) != 0)
                    return fail(r, "box bounds must be two finite numbers");
                if (!(hi > lo))
                    return fail(r, "the box's upper bound must be above its lower bound");
                if (p->have_axis[k])
                    return fail(r, "\"%s\" given twice", axis_words[k]);
                d->lo[k] = lo;
                d->hi[k] = hi;
                p->have_axis[k] = true;
                axis = true;
            }
        if (axis)
            continue;
        if (r->ntok == 6 && words_are(r, 3, "xy xz yz")) {
            double t[3];
            for (int k = 0; k < 3; k++)
                if (to_double(r->tok[k], &t[k]) != 0)
                    return fail(r, "tilt factors must be three finite numbers");
            if (t[0] != 0 || t[1] != 0 || t[2] != 0)
                return fail(r, "a triclinic box (non-zero tilt factors xy xz yz) cannot be imported: psys boxes are "
                               "orthogonal");
            continue;
        }
        long long n;
        if (r->ntok < 2 || to_ll(r->tok[0], &n) != 0 || n < 0) {
            return fail(r, "not a header line of a LAMMPS data file (expected a count such as \"500 atoms\", box "
                           "bounds such as \"0 10 xlo xhi\", or a section name such as \"Atoms\")");
        }
        if (words_are(r, 1, "atoms")) {
            if (p->have_atoms_count)
                return fail(r, "\"atoms\" given twice");
            if (n == 0)
                return fail(r, "no atoms: nothing to import");
            if ((unsigned long long)n > SIZE_MAX / (3 * sizeof(double)))
                return fail(r, "too many atoms");
            d->natoms = (size_t)n;
            p->have_atoms_count = true;
            continue;
        }
        if (words_are(r, 1, "atom types")) {
            if (p->have_types_count)
                return fail(r, "\"atom types\" given twice");
            if (n < 1 || n > MAX_TYPES)
                return fail(r, "the number of atom types must be 1 to %d", MAX_TYPES);
            d->ntypes = (int)n;
            d->mass = calloc((size_t)n + 1, sizeof *d->mass);
            if (!d->mass)
                return fail_file(r, "out of memory");
            p->have_types_count = true;
            continue;
        }
        bool known = false;
        for (int i = 0; zero_counts[i] && !known; i++)
            if (words_are(r, 1, zero_counts[i])) {
                if (n != 0)
                    return fail(r, "psys imports atom_style atomic systems only (no %s)", zero_counts[i]);
                known = true;
            }
        for (int i = 0; ignored_counts[i] && !known; i++)
            known = words_are(r, 1, ignored_counts[i]);
        if (!known)
            return fail(r, "unknown header line");
    }
}

static int check_header(parse *p)
{
    reader *r = &p->r;
    static const char *const axis_words[3] = {"xlo xhi", "ylo yhi", "zlo zhi"};
    if (!p->have_atoms_count)
        return fail_file(r, "the header has no \"N atoms\" line");
    if (!p->have_types_count)
        return fail_file(r, "the header has no \"N atom types\" line");
    for (int k = 0; k < 3; k++)
        if (!p->have_axis[k])
            return fail_file(r, "the header has no \"%s\" line (psys needs the box)", axis_words[k]);
    return 0;
}

/* Move past the keyword line to the first item line of a section. */
static int section_first_item(parse *p, const char *name)
{
    reader *r = &p->r;
    int st = next_nonblank(r);
    if (st < 0)
        return -1;
    if (st == 0)
        return fail_file(r, "the file ends in the %s section (before its first line)", name);
    if (r->ntok <= MAXTOK && section_of(r) != SEC_NONE)
        return fail(r, "the %s section is empty", name);
    return 0;
}

/* Move to line i (> 0) of the n lines of a section; a file or section that
 * ends early is reported as such. */
static int section_item(parse *p, const char *name, long long i, long long n, const char *unit)
{
    reader *r = &p->r;
    int st = next_nonblank(r);
    if (st < 0)
        return -1;
    if (st == 0)
        return fail_file(r, "the file ends in the %s section after %lld of %lld %s", name, i, n, unit);
    if (r->ntok <= MAXTOK && section_of(r) != SEC_NONE)
        return fail(r, "the %s section ends after %lld of %lld %s", name, i, n, unit);
    return 0;
}

static int read_masses(parse *p)
{
    reader *r = &p->r;
    lmp_data *d = p->d;
    for (int i = 0; i < d->ntypes; i++) {
        if (i > 0 && section_item(p, "Masses", i, d->ntypes, "atom types") != 0)
            return -1;
        long long t;
        double m;
        if (r->ntok != 2 || to_ll(r->tok[0], &t) != 0 || to_double(r->tok[1], &m) != 0)
            return fail(r, "a Masses line is \"TYPE MASS\" (%d lines, one per atom type)", d->ntypes);
        if (t < 1 || t > d->ntypes)
            return fail(r, "atom type %lld is not between 1 and %d", t, d->ntypes);
        if (!(m > 0))
            return fail(r, "the mass must be > 0");
        if (d->mass[t] != 0)
            return fail(r, "type %lld's mass is given twice", t);
        d->mass[t] = m;
    }
    return 0;
}

/* One coefficient line's epsilon, sigma and optional cutoff, from token k on. */
static int read_coeffs(parse *p, int k, const char *name, const char *form)
{
    reader *r = &p->r;
    lmp_data *d = p->d;
    double c[3];
    int nc = r->ntok - k;
    if (nc < 2 || nc > 3)
        return fail(r, "a %s line is \"%s\" (pair_style lj/cut)", name, form);
    for (int i = 0; i < nc; i++)
        if (to_double(r->tok[k + i], &c[i]) != 0)
            return fail(r, "\"%s\" is not a finite number", r->tok[k + i]);
    if (c[0] < 0)
        return fail(r, "epsilon must be >= 0");
    if (!(c[1] > 0))
        return fail(r, "sigma must be > 0");
    if (nc == 3 && !(c[2] > 0))
        return fail(r, "the cutoff must be > 0");
    if (p->coeff_line == 0) {
        d->epsilon = c[0];
        d->sigma = c[1];
        d->have_cutoff = nc == 3;
        d->cutoff = nc == 3 ? c[2] : 0;
        d->have_coeffs = true;
        p->coeff_line = r->lineno;
        return 0;
    }
    if (p->any_coeffs)
        return 0;
    if (c[0] != d->epsilon || c[1] != d->sigma)
        return fail(r, "these lj/cut coefficients (epsilon %.17g, sigma %.17g) differ from those of line %ld (epsilon "
                       "%.17g, sigma %.17g): psys has one Lennard-Jones law for all atoms (give --epsilon and "
                       "--sigma to use one)",
                    c[0], c[1], p->coeff_line, d->epsilon, d->sigma);
    if ((nc == 3) != d->have_cutoff || (nc == 3 && c[2] != d->cutoff))
        return fail(r, "this cutoff differs from that of line %ld: psys has one cutoff for all atoms (give --cutoff "
                       "to use one)",
                    p->coeff_line);
    return 0;
}

static int read_pair(parse *p, bool ij)
{
    reader *r = &p->r;
    lmp_data *d = p->d;
    const char *name = ij ? "PairIJ Coeffs" : "Pair Coeffs";
    if (r->comment[0] && !lj_cut_style(r->comment))
        return fail(r, "pair style %s cannot be imported: psys imports pair_style lj/cut only", r->comment);
    if (section_first_item(p, name) != 0)
        return -1;
    long long lines = ij ? (long long)d->ntypes * (d->ntypes + 1) / 2 : d->ntypes;
    unsigned char *seen = NULL;
    if (!ij) {
        seen = calloc((size_t)d->ntypes + 1, 1);
        if (!seen)
            return fail_file(r, "out of memory");
    }
    for (long long i = 0; i < lines; i++) {
        if (i > 0 && section_item(p, name, i, lines, "lines") != 0) {
            free(seen);
            return -1;
        }
        long long a, b;
        int bad = 0;
        if (r->ntok < 1 || to_ll(r->tok[0], &a) != 0 || (ij && (r->ntok < 2 || to_ll(r->tok[1], &b) != 0))) {
            bad = fail(r, "a %s line is \"%s\" (pair_style lj/cut)", name,
                       ij ? "TYPE TYPE EPSILON SIGMA [CUTOFF]" : "TYPE EPSILON SIGMA [CUTOFF]");
        } else if (a < 1 || a > d->ntypes || (ij && (b < a || b > d->ntypes))) {
            bad = fail(r, ij ? "the atom types must be I J with 1 <= I <= J <= %d" : "atom type is not between 1 and %d",
                       d->ntypes);
        } else if (!ij && seen[a]) {
            bad = fail(r, "type %lld's coefficients are given twice", a);
        } else {
            if (!ij)
                seen[a] = 1;
            bad = read_coeffs(p, ij ? 2 : 1, name, ij ? "TYPE TYPE EPSILON SIGMA [CUTOFF]" : "TYPE EPSILON SIGMA [CUTOFF]");
        }
        if (bad) {
            free(seen);
            return -1;
        }
    }
    free(seen);
    return 0;
}

static int cmp_atom(const void *a, const void *b)
{
    long long x = *(const long long *)a, y = *(const long long *)b;
    return (x > y) - (x < y);
}

static int read_atoms(parse *p)
{
    reader *r = &p->r;
    lmp_data *d = p->d;
    if (r->comment[0] && strcmp(r->comment, "atomic") != 0)
        return fail(r, "atom style %s cannot be imported: psys imports atom_style atomic only", r->comment);
    if (section_first_item(p, "Atoms") != 0)
        return -1;
    size_t n = d->natoms, cap = 0;
    /* Sorted below through an index: records of (id, position in file). */
    long long(*rec)[2] = NULL;
    for (size_t i = 0; i < n; i++) {
        if (i > 0 && section_item(p, "Atoms", (long long)i, (long long)n, "atoms") != 0)
            goto bad;
        if (i == cap) { /* grow as lines come: the header's count is not trusted for memory */
            size_t nc = cap ? (cap * 2 < n ? cap * 2 : n) : (n < 4096 ? n : 4096);
            void *a = realloc(rec, nc * sizeof *rec), *b = realloc(d->type, nc * sizeof *d->type);
            if (b)
                d->type = b;
            void *c = a && b ? realloc(d->x, nc * 3 * sizeof *d->x) : NULL;
            void *e = c ? realloc(p->atom_line, nc * sizeof *p->atom_line) : NULL;
            if (a)
                rec = a;
            if (c)
                d->x = c;
            if (e)
                p->atom_line = e;
            if (!e) {
                fail_file(r, "out of memory reading %zu atoms", n);
                goto bad;
            }
            cap = nc;
        }
        long long id, t, img;
        double x[3];
        if (r->ntok != 5 && r->ntok != 8) {
            fail(r, "an Atoms line of atom_style atomic is \"ID TYPE X Y Z\" or \"ID TYPE X Y Z IX IY IZ\"");
            goto bad;
        }
        if (to_ll(r->tok[0], &id) != 0 || id < 1) {
            fail(r, "the atom id must be an integer >= 1");
            goto bad;
        }
        if (to_ll(r->tok[1], &t) != 0 || t < 1 || t > d->ntypes) {
            fail(r, "the atom type must be an integer between 1 and %d", d->ntypes);
            goto bad;
        }
        for (int k = 0; k < 3; k++)
            if (to_double(r->tok[2 + k], &x[k]) != 0) {
                fail(r, "the position must be three finite numbers");
                goto bad;
            }
        for (int k = 5; k < r->ntok; k++)
            if (to_ll(r->tok[k], &img) != 0 || img < INT32_MIN || img > INT32_MAX) {
                fail(r, "image flags must be three integers");
                goto bad;
            }
        rec[i][0] = id;
        rec[i][1] = (long long)i;
        d->type[i] = (int)t;
        memcpy(d->x + 3 * i, x, sizeof x);
        p->atom_line[i] = r->lineno;
    }
    /* Sort by id: (id, index) pairs, then permute. */
    qsort(rec, n, sizeof *rec, cmp_atom);
    int *type = malloc(n * sizeof *type);
    double *x = malloc(n * 3 * sizeof *x);
    long long *id = malloc(n * sizeof *id);
    if (!type || !x || !id) {
        free(type);
        free(x);
        free(id);
        fail_file(r, "out of memory reading %zu atoms", n);
        goto bad;
    }
    for (size_t i = 0; i < n; i++) {
        size_t j = (size_t)rec[i][1];
        if (i > 0 && rec[i][0] == rec[i - 1][0]) {
            long a = p->atom_line[(size_t)rec[i - 1][1]], b = p->atom_line[j];
            snprintf(r->msg, r->msgcap, "line %ld: atom id %lld is used twice (also on line %ld)", a > b ? a : b,
                     rec[i][0], a > b ? b : a);
            free(type);
            free(x);
            free(id);
            goto bad;
        }
        id[i] = rec[i][0];
        type[i] = d->type[j];
        memcpy(x + 3 * i, d->x + 3 * j, 3 * sizeof *x);
    }
    free(rec);
    free(d->type);
    free(d->x);
    d->type = type;
    d->x = x;
    d->id = id;
    d->v = calloc(n * 3, sizeof *d->v);
    if (!d->v)
        return fail_file(r, "out of memory reading %zu atoms", n);
    return 0;
bad:
    free(rec);
    return -1;
}

static int read_velocities(parse *p)
{
    reader *r = &p->r;
    lmp_data *d = p->d;
    if (!p->seen[SEC_ATOMS])
        return fail(r, "the Velocities section must come after the Atoms section");
    if (section_first_item(p, "Velocities") != 0)
        return -1;
    size_t n = d->natoms;
    unsigned char *seen = calloc(n, 1);
    if (!seen)
        return fail_file(r, "out of memory");
    for (size_t i = 0; i < n; i++) {
        if (i > 0 && section_item(p, "Velocities", (long long)i, (long long)n, "atoms") != 0) {
            free(seen);
            return -1;
        }
        long long id = 0;
        double v[3];
        int bad = 0;
        if (r->ntok != 4 || to_ll(r->tok[0], &id) != 0) {
            bad = fail(r, "a Velocities line of atom_style atomic is \"ID VX VY VZ\"");
        } else {
            for (int k = 0; k < 3 && !bad; k++)
                if (to_double(r->tok[1 + k], &v[k]) != 0)
                    bad = fail(r, "the velocity must be three finite numbers");
        }
        const long long *hit = bad ? NULL : bsearch(&id, d->id, n, sizeof *d->id, cmp_atom);
        if (!bad && !hit)
            bad = fail(r, "no atom has id %lld", id);
        if (!bad) {
            size_t j = (size_t)(hit - d->id);
            if (seen[j]) {
                bad = fail(r, "atom %lld's velocity is given twice", id);
            } else {
                seen[j] = 1;
                memcpy(d->v + 3 * j, v, sizeof v);
            }
        }
        if (bad) {
            free(seen);
            return -1;
        }
    }
    free(seen);
    d->have_velocities = true;
    return 0;
}

static const char *const section_names[] = {"", "Masses", "Pair Coeffs", "PairIJ Coeffs", "Atoms", "Velocities"};

int lmp_data_read(const char *path, bool any_coeffs, lmp_data *d, char *msg, size_t cap)
{
    memset(d, 0, sizeof *d);
    parse p;
    memset(&p, 0, sizeof p);
    p.d = d;
    p.any_coeffs = any_coeffs;
    p.r.msg = msg;
    p.r.msgcap = cap;
    msg[0] = '\0';
    bool is_stdin = strcmp(path, "-") == 0;
    p.r.fp = is_stdin ? stdin : fopen(path, "r");
    if (!p.r.fp) {
        snprintf(msg, cap, "cannot open: %s", strerror(errno));
        return -1;
    }
    int rc = -1;
    int st = next_line(&p.r); /* the title */
    if (st == 0)
        fail_file(&p.r, "empty file (a LAMMPS data file starts with a title line, then its header)");
    if (st <= 0)
        goto done;
    st = read_header(&p);
    if (st < 0 || check_header(&p) != 0)
        goto done;
    /* p.r holds the first section line. */
    for (;;) {
        int sec = section_of(&p.r);
        if (p.r.ntok > MAXTOK || sec == SEC_NONE) {
            fail(&p.r, "not a section of a LAMMPS data file (expected Masses, Pair Coeffs, PairIJ Coeffs, Atoms or "
                       "Velocities)");
            goto done;
        }
        if (sec == SEC_OTHER) {
            fail(&p.r, "this section cannot be imported: psys imports atom_style atomic systems with pair_style "
                       "lj/cut");
            goto done;
        }
        if (p.seen[sec]) {
            fail(&p.r, "the %s section appears twice", section_names[sec]);
            goto done;
        }
        if ((sec == SEC_PAIR && p.seen[SEC_PAIRIJ]) || (sec == SEC_PAIRIJ && p.seen[SEC_PAIR])) {
            fail(&p.r, "both Pair Coeffs and PairIJ Coeffs sections");
            goto done;
        }
        int bad;
        switch (sec) {
        case SEC_MASSES:
            bad = section_first_item(&p, "Masses") != 0 || read_masses(&p) != 0;
            break;
        case SEC_PAIR:
            bad = read_pair(&p, false) != 0;
            break;
        case SEC_PAIRIJ:
            bad = read_pair(&p, true) != 0;
            break;
        case SEC_ATOMS:
            bad = read_atoms(&p) != 0;
            break;
        default:
            bad = read_velocities(&p) != 0;
            break;
        }
        if (bad)
            goto done;
        p.seen[sec] = true;
        st = next_nonblank(&p.r);
        if (st < 0)
            goto done;
        if (st == 0)
            break;
    }
    if (!p.seen[SEC_ATOMS]) {
        fail_file(&p.r, "no Atoms section");
        goto done;
    }
    if (!p.seen[SEC_MASSES]) {
        fail_file(&p.r, "no Masses section (atom_style atomic needs a mass for each atom type)");
        goto done;
    }
    for (int t = 1; t <= d->ntypes; t++)
        if (d->mass[t] == 0) {
            fail_file(&p.r, "the Masses section gives no mass for atom type %d", t);
            goto done;
        }
    rc = 0;
done:
    if (!is_stdin)
        fclose(p.r.fp);
    free(p.r.line);
    free(p.atom_line);
    if (rc != 0)
        lmp_data_free(d);
    return rc;
}

void lmp_data_free(lmp_data *d)
{
    free(d->mass);
    free(d->id);
    free(d->type);
    free(d->x);
    free(d->v);
    memset(d, 0, sizeof *d);
}
