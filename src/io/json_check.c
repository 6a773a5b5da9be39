/* A JSON syntax check that allocates nothing and does not recurse, used by
 * the scene loader only after cJSON has refused a text, to tell why:
 *   - the text is valid: cJSON ran out of memory (PSYS_ERR_NOMEM, not
 *     "malformed JSON" at some random place);
 *   - arrays/objects nest deeper than cJSON's limit (CJSON_NESTING_LIMIT,
 *     1000): say so, instead of "malformed JSON";
 *   - otherwise: a syntax error (the loader reports cJSON's position).
 * It accepts no more than cJSON 1.7 does (a text it calls valid must be one
 * cJSON parses when memory is there, and fuzz/fuzz_scene.c checks that both
 * agree on every input): whitespace is any byte 1..32, numbers are what
 * cJSON's strtod reads (at most 63 characters), \u escapes must form valid
 * UTF-16 (no lone surrogates). */
#include "io/io.h"

#include <string.h>

typedef struct cursor {
    const unsigned char *s;
    size_t n, i;
} cursor;

static void skip_ws(cursor *c)
{
    while (c->i < c->n && c->s[c->i] >= 1 && c->s[c->i] <= 32)
        c->i++;
}

/* cJSON's parse_hex4: four hex digits, or 0 when they are not all hex. */
static unsigned hex4(const unsigned char *h)
{
    unsigned v = 0;
    for (int k = 0; k < 4; k++) {
        v <<= 4;
        if (h[k] >= '0' && h[k] <= '9')
            v |= (unsigned)(h[k] - '0');
        else if (h[k] >= 'a' && h[k] <= 'f')
            v |= (unsigned)(h[k] - 'a' + 10);
        else if (h[k] >= 'A' && h[k] <= 'F')
            v |= (unsigned)(h[k] - 'A' + 10);
        else
            return 0;
    }
    return v;
}

/* A string starting at c->i (the opening quote), read in cJSON's two passes:
 * the end is the first quote not preceded by an escaping backslash; then
 * the escapes in between are decoded (\u: any four bytes, not-hex meaning
 * U+0000, no lone surrogates, at least 6 bytes before the end). */
static int string(cursor *c)
{
    if (c->i >= c->n || c->s[c->i] != '"')
        return 0;
    size_t start = c->i + 1, end = start;
    while (end < c->n && c->s[end] != '"') {
        if (c->s[end] == '\\') {
            if (end + 1 >= c->n)
                return 0;
            end++;
        }
        end++;
    }
    if (end >= c->n)
        return 0;
    for (size_t k = start; k < end;) {
        if (c->s[k] != '\\') {
            k++;
            continue;
        }
        unsigned char e = c->s[k + 1];
        if (e == 'u') {
            if (end - k < 6)
                return 0;
            unsigned u = hex4(c->s + k + 2);
            if (u >= 0xDC00 && u <= 0xDFFF)
                return 0;
            if (u >= 0xD800 && u <= 0xDBFF) { /* a high surrogate needs its low one */
                if (end - (k + 6) < 6 || c->s[k + 6] != '\\' || c->s[k + 7] != 'u')
                    return 0;
                unsigned lo = hex4(c->s + k + 8);
                if (lo < 0xDC00 || lo > 0xDFFF)
                    return 0;
                k += 12;
            } else {
                k += 6;
            }
        } else if (e != '\0' && strchr("\"\\/bfnrt", e)) {
            k += 2;
        } else {
            return 0;
        }
    }
    c->i = end + 1;
    return 1;
}

static int digits(cursor *c)
{
    size_t start = c->i;
    while (c->i < c->n && c->s[c->i] >= '0' && c->s[c->i] <= '9')
        c->i++;
    return c->i > start;
}

/* A number as cJSON reads one: it copies the characters "0123456789+-.eE"
 * (at most 63) and converts them with strtod, so the accepted form is
 * strtod's: -? digits* (. digits*)? with at least one digit, then an
 * exponent only when digits follow the e (leading zeros and "1." pass). */
static int number(cursor *c)
{
    size_t start = c->i;
    if (c->i < c->n && c->s[c->i] == '-')
        c->i++;
    size_t mantissa = c->i;
    digits(c);
    if (c->i < c->n && c->s[c->i] == '.') {
        c->i++;
        digits(c);
    }
    if (c->i - mantissa == 0 || (c->i - mantissa == 1 && c->s[mantissa] == '.'))
        return 0;
    if (c->i < c->n && (c->s[c->i] == 'e' || c->s[c->i] == 'E')) {
        size_t j = c->i + 1;
        if (j < c->n && (c->s[j] == '+' || c->s[j] == '-'))
            j++;
        if (j < c->n && c->s[j] >= '0' && c->s[j] <= '9') {
            c->i = j;
            digits(c);
        }
    }
    /* cJSON 1.7.15 as released reads at most 63 characters (Debian's patched
     * one reads any number): refuse longer ones, the safe side. */
    return c->i - start <= 63;
}

static int literal(cursor *c, const char *word)
{
    size_t len = strlen(word);
    if (c->n - c->i < len || memcmp(c->s + c->i, word, len) != 0)
        return 0;
    c->i += len;
    return 1;
}

/* An object member's name and its colon, with the space after it. */
static int member_name(cursor *c)
{
    if (!string(c))
        return 0;
    skip_ws(c);
    if (c->i >= c->n || c->s[c->i] != ':')
        return 0;
    c->i++;
    skip_ws(c);
    return 1;
}

int psys__json_check(const char *text, size_t len, int max_depth, size_t *where)
{
    enum { MAX_STACK = 4096 };
    char stack[MAX_STACK]; /* '[' or '{' per open level */
    int depth = 0;
    if (max_depth > MAX_STACK)
        max_depth = MAX_STACK;
    cursor c = {(const unsigned char *)text, len, 0};
    int result = 1;
    if (len >= 5 && memcmp(text, "\xEF\xBB\xBF", 3) == 0) /* cJSON: only with 5+ bytes */
        c.i = 3; /* cJSON skips a UTF-8 byte order mark */
    skip_ws(&c);
    for (;;) {
        /* a value at c.i */
        if (c.i >= c.n)
            goto done;
        unsigned char ch = c.s[c.i];
        if (ch == '[' || ch == '{') {
            if (depth >= max_depth) {
                result = 2;
                goto done;
            }
            stack[depth++] = (char)ch;
            c.i++;
            skip_ws(&c);
            if (c.i < c.n && c.s[c.i] == (ch == '[' ? ']' : '}')) {
                c.i++;
                depth--;
            } else {
                if (ch == '{' && !member_name(&c))
                    goto done;
                continue; /* the first element's value */
            }
        } else if (ch == '"') {
            if (!string(&c))
                goto done;
        } else if (ch == '-' || (ch >= '0' && ch <= '9')) {
            if (!number(&c))
                goto done;
        } else if (!literal(&c, "true") && !literal(&c, "false") && !literal(&c, "null")) {
            goto done;
        }
        /* after a value: close containers or go on to the next element */
        for (;;) {
            skip_ws(&c);
            if (depth == 0) {
                result = c.i == c.n ? 0 : 1;
                goto done;
            }
            if (c.i >= c.n)
                goto done;
            char open = stack[depth - 1];
            if (c.s[c.i] == (open == '[' ? ']' : '}')) {
                c.i++;
                depth--;
                continue;
            }
            if (c.s[c.i] != ',')
                goto done;
            c.i++;
            skip_ws(&c);
            if (open == '{' && !member_name(&c))
                goto done;
            break; /* the next element's value */
        }
    }
done:
    if (where)
        *where = c.i;
    return result;
}
