/* Where --render frames go (docs/cli.md "Rendering"):
 *   out.png           the last frame, written when the run ends;
 *   frames/%04d.png   one PNG per frame, each under a temporary name, renamed when complete;
 *   out.gif, out.mp4  raw BGRA frames piped to ffmpeg (H.264 yuv420p; GIF via
 *                     palettegen/paletteuse), which writes a temporary file that
 *                     is renamed when ffmpeg exits successfully. Without ffmpeg a
 *                     GIF comes from the built-in encoder; MP4 is refused before
 *                     the run starts.
 * Everything that can be checked (format, sizes, directories, ffmpeg) is
 * checked in sink_open, before the first step. */
#include "cli.h"
#include "render.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <signal.h>
#include <spawn.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

extern char **environ;

struct sink {
    sink_kind kind;
    char *label;
    int width, height;
    double fps;
    long long frames;
    outfile out;        /* PNG, GIF, MP4: the temporary file renamed at the end */
    const char *target; /* path ffmpeg writes (out.tmp, or the path itself for a device) */
    char *path;         /* the path as given */
    /* frame pattern: prefix + number (zero-padded to pad digits) + suffix */
    char *prefix, *suffix;
    int pad;
    /* ffmpeg */
    const char *ffmpeg;
    pid_t pid;
    int fd;
    /* built-in GIF */
    gif_writer *gif;
    bool failed; /* a frame could not be written: sink_close keeps nothing */
};

static const char *ext_of(const char *path)
{
    const char *slash = strrchr(path, '/');
    const char *dot = strrchr(slash ? slash : path, '.');
    return dot ? dot : "";
}

/* Split a frame pattern at its one %d / %0Nd; -1 if it is not one. "%%" is a literal %. */
static int split_pattern(const char *path, char **prefix, char **suffix, int *pad)
{
    size_t len = strlen(path);
    char *pre = malloc(len + 1), *suf = malloc(len + 1);
    if (!pre || !suf) {
        free(pre);
        free(suf);
        return -1;
    }
    size_t np = 0, ns = 0;
    int found = 0;
    for (size_t i = 0; i < len; i++) {
        char *dst = found ? suf : pre;
        size_t *nd = found ? &ns : &np;
        if (path[i] != '%') {
            dst[(*nd)++] = path[i];
            continue;
        }
        if (path[i + 1] == '%') {
            dst[(*nd)++] = '%';
            i++;
            continue;
        }
        size_t j = i + 1;
        int width = 0;
        while (path[j] >= '0' && path[j] <= '9' && width < 100)
            width = width * 10 + (path[j++] - '0');
        if (path[j] != 'd' || found || width > 18) {
            free(pre);
            free(suf);
            return -1;
        }
        found = 1;
        *pad = width;
        i = j;
    }
    pre[np] = suf[ns] = '\0';
    if (!found) {
        free(pre);
        free(suf);
        return -1;
    }
    *prefix = pre;
    *suffix = suf;
    return 0;
}

static int has_conversion(const char *path)
{
    for (const char *p = path; (p = strchr(p, '%')) != NULL; p += 2) {
        if (p[1] != '%')
            return 1;
    }
    return 0;
}

int sink_kind_of(const char *path, sink_kind *kind, char *why, size_t cap)
{
    const char *ext = ext_of(path);
    if (has_conversion(path)) {
        char *pre, *suf;
        int pad;
        if (split_pattern(path, &pre, &suf, &pad) != 0) {
            snprintf(why, cap, "a frame pattern needs exactly one %%d or %%0Nd (N up to 18), e.g. frames/%%04d.png");
            return -1;
        }
        int in_dir = strchr(suf, '/') != NULL;
        free(pre);
        free(suf);
        if (in_dir) {
            snprintf(why, cap, "the frame number must be in the file name, not in a directory name");
            return -1;
        }
        if (strcmp(ext, ".png") != 0) {
            snprintf(why, cap, "frame patterns must end in .png (got \"%s\")", ext);
            return -1;
        }
        *kind = SINK_PATTERN;
        return 0;
    }
    if (strcmp(ext, ".png") == 0)
        *kind = SINK_PNG;
    else if (strcmp(ext, ".gif") == 0)
        *kind = SINK_GIF;
    else if (strcmp(ext, ".mp4") == 0)
        *kind = SINK_MP4;
    else {
        snprintf(why, cap, "unknown picture format (got \"%s\"; use .png, a frame pattern such as frames/%%04d.png, .gif or .mp4)",
                 ext);
        return -1;
    }
    return 0;
}

const char *sink_find_ffmpeg(void)
{
    const char *env = getenv("PSYS_FFMPEG");
    if (env && *env)
        return access(env, X_OK) == 0 ? env : NULL;
    const char *path = getenv("PATH");
    if (!path)
        path = "/usr/bin:/bin";
    static char found[4096];
    for (const char *p = path; *p;) {
        const char *colon = strchr(p, ':');
        size_t n = colon ? (size_t)(colon - p) : strlen(p);
        if (n == 0) {
            snprintf(found, sizeof found, "./ffmpeg");
        } else if (n + 8 < sizeof found) {
            memcpy(found, p, n);
            memcpy(found + n, "/ffmpeg", 8);
        } else {
            found[0] = '\0';
        }
        struct stat st;
        if (found[0] && stat(found, &st) == 0 && S_ISREG(st.st_mode) && access(found, X_OK) == 0)
            return found;
        p += n;
        if (*p == ':')
            p++;
    }
    return NULL;
}

static void sink_free(sink *s)
{
    free(s->label);
    free(s->path);
    free(s->prefix);
    free(s->suffix);
    free(s);
}

sink *sink_open(const char *path, const char *label, int width, int height, double fps)
{
    char why[512];
    sink_kind kind;
    if (sink_kind_of(path, &kind, why, sizeof why) != 0) {
        cli_error("%s %s: %s", label, path, why);
        return NULL;
    }
    sink *s = calloc(1, sizeof *s);
    if (!s || !(s->label = strdup(label)) || !(s->path = strdup(path))) {
        cli_error("%s %s: out of memory", label, path);
        if (s)
            sink_free(s);
        return NULL;
    }
    s->kind = kind;
    s->width = width;
    s->height = height;
    s->fps = fps;
    s->fd = -1;
    s->pid = -1;
    if (kind == SINK_MP4 && (width % 2 || height % 2)) {
        cli_error("--size: .mp4 (H.264, yuv420p) needs an even width and height (got %dx%d)", width, height);
        sink_free(s);
        return NULL;
    }
    if (kind == SINK_GIF || kind == SINK_MP4) {
        s->ffmpeg = sink_find_ffmpeg();
        if (!s->ffmpeg && kind == SINK_MP4) {
            cli_error("%s %s: .mp4 needs ffmpeg, which was not found%s (install ffmpeg, or render a .gif or "
                      "PNG frames such as frames/%%04d.png)",
                      label, path, getenv("PSYS_FFMPEG") && *getenv("PSYS_FFMPEG") ? " at $PSYS_FFMPEG" : " on PATH");
            sink_free(s);
            return NULL;
        }
    }
    if (kind == SINK_PATTERN) {
        /* The frames' directory must exist now: a run that cannot write its
         * frames must not start. */
        char *dir = strdup(path);
        if (!dir || split_pattern(path, &s->prefix, &s->suffix, &s->pad) != 0) {
            free(dir);
            cli_error("%s %s: out of memory", label, path);
            sink_free(s);
            return NULL;
        }
        char *slash = strrchr(dir, '/');
        const char *d = slash ? (slash == dir ? "/" : (*slash = '\0', dir)) : ".";
        struct stat st;
        int bad = stat(d, &st) != 0 ? errno : !S_ISDIR(st.st_mode) ? ENOTDIR : access(d, W_OK) != 0 ? errno : 0;
        free(dir);
        if (bad) {
            cli_error("%s %s: cannot create: %s", label, path, strerror(bad));
            sink_free(s);
            return NULL;
        }
        return s;
    }
    if (outfile_open(&s->out, path, label) != 0) {
        sink_free(s);
        return NULL;
    }
    s->target = s->out.tmp ? s->out.tmp : path;
    if (s->ffmpeg)
        signal(SIGPIPE, SIG_IGN); /* a dead ffmpeg is an error from write(), not a silent exit */
    if (kind == SINK_GIF && !s->ffmpeg) {
        if (!(s->gif = gif_begin(s->out.fp, width, height))) {
            cli_error("%s %s: out of memory", label, path);
            outfile_abort(&s->out);
            sink_free(s);
            return NULL;
        }
    }
    return s;
}

bool sink_takes_frames(const sink *s) { return s->kind != SINK_PNG; }

long long sink_frames(const sink *s) { return s->frames; }

static int start_ffmpeg(sink *s)
{
    char size[64], rate[64];
    snprintf(size, sizeof size, "%dx%d", s->width, s->height);
    snprintf(rate, sizeof rate, "%.17g", s->fps);
    const char *argv[40];
    int n = 0;
    const char *head[] = {s->ffmpeg, "-hide_banner", "-loglevel", "error", "-nostats", "-y", "-f", "rawvideo",
                          "-pix_fmt", "bgra", "-s", size, "-framerate", rate, "-i", "-"};
    for (size_t i = 0; i < sizeof head / sizeof *head; i++)
        argv[n++] = head[i];
    if (s->kind == SINK_MP4) {
        const char *tail[] = {"-c:v", "libx264", "-pix_fmt", "yuv420p", "-movflags", "+faststart", "-f", "mp4"};
        for (size_t i = 0; i < sizeof tail / sizeof *tail; i++)
            argv[n++] = tail[i];
    } else {
        const char *tail[] = {"-filter_complex", "[0:v]split[a][b];[a]palettegen[p];[b][p]paletteuse", "-loop", "0",
                              "-f", "gif"};
        for (size_t i = 0; i < sizeof tail / sizeof *tail; i++)
            argv[n++] = tail[i];
    }
    argv[n++] = s->target;
    argv[n] = NULL;

    int fds[2];
    if (pipe(fds) != 0) {
        cli_error("%s %s: cannot start ffmpeg: %s", s->label, s->path, strerror(errno));
        return -1;
    }
    fcntl(fds[1], F_SETFD, FD_CLOEXEC);
    posix_spawn_file_actions_t fa;
    posix_spawnattr_t attr;
    posix_spawn_file_actions_init(&fa);
    posix_spawnattr_init(&attr);
    posix_spawn_file_actions_adddup2(&fa, fds[0], 0);
    if (fds[0] != 0)
        posix_spawn_file_actions_addclose(&fa, fds[0]);
    posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
    /* Its own process group: Ctrl-C reaches psys, which then closes the pipe
     * so ffmpeg finishes the file with the frames so far. */
    posix_spawnattr_setpgroup(&attr, 0);
    sigset_t def;
    sigemptyset(&def);
    sigaddset(&def, SIGPIPE);
    sigaddset(&def, SIGINT);
    sigaddset(&def, SIGTERM);
    posix_spawnattr_setsigdefault(&attr, &def);
    posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETPGROUP | POSIX_SPAWN_SETSIGDEF);
    pid_t pid;
    int rc = posix_spawn(&pid, s->ffmpeg, &fa, &attr, (char *const *)argv, environ);
    posix_spawn_file_actions_destroy(&fa);
    posix_spawnattr_destroy(&attr);
    close(fds[0]);
    if (rc != 0) {
        close(fds[1]);
        cli_error("%s %s: cannot start %s: %s", s->label, s->path, s->ffmpeg, strerror(rc));
        return -1;
    }
    s->pid = pid;
    s->fd = fds[1];
    return 0;
}

static int write_all(int fd, const unsigned char *p, size_t n)
{
    while (n > 0) {
        ssize_t k = write(fd, p, n);
        if (k < 0) {
            if (errno == EINTR)
                continue;
            return -1;
        }
        p += k;
        n -= (size_t)k;
    }
    return 0;
}

/* Wait for ffmpeg; 0 if it exited with status 0. */
static int wait_ffmpeg(sink *s)
{
    if (s->fd >= 0) {
        close(s->fd);
        s->fd = -1;
    }
    if (s->pid < 0)
        return 0;
    int st;
    pid_t r;
    while ((r = waitpid(s->pid, &st, 0)) < 0 && errno == EINTR)
        ;
    s->pid = -1;
    if (r < 0) {
        cli_error("%s %s: ffmpeg: %s", s->label, s->path, strerror(errno));
        return -1;
    }
    if (WIFEXITED(st) && WEXITSTATUS(st) == 0)
        return 0;
    if (WIFEXITED(st))
        cli_error("%s %s: ffmpeg failed (exit status %d)", s->label, s->path, WEXITSTATUS(st));
    else
        cli_error("%s %s: ffmpeg was killed by signal %d", s->label, s->path, WIFSIGNALED(st) ? WTERMSIG(st) : 0);
    return -1;
}

static int write_pattern_frame(sink *s, renderer *r)
{
    size_t n = strlen(s->prefix) + strlen(s->suffix) + 32;
    char *name = malloc(n);
    if (!name) {
        cli_error("%s %s: out of memory", s->label, s->path);
        return -1;
    }
    snprintf(name, n, "%s%0*lld%s", s->prefix, s->pad, s->frames, s->suffix);
    outfile o;
    int rc = outfile_open(&o, name, s->label);
    if (rc == 0) {
        if (renderer_write_png(r, o.fp) != 0) {
            cli_error("%s %s: cannot write the PNG", s->label, name);
            outfile_abort(&o);
            rc = -1;
        } else {
            rc = outfile_commit(&o);
        }
    }
    free(name);
    return rc;
}

static int put_frame(sink *s, renderer *r)
{
    int stride;
    const unsigned char *px;
    switch (s->kind) {
    case SINK_PNG:
        return 0;
    case SINK_PATTERN:
        if (write_pattern_frame(s, r) != 0)
            return -1;
        break;
    case SINK_GIF:
    case SINK_MP4:
        px = renderer_pixels(r, &stride);
        if (s->gif) {
            /* Delays in hundredths of a second, rounded so the total keeps time. */
            long long a = llround(100.0 * (double)s->frames / s->fps), b = llround(100.0 * (double)(s->frames + 1) / s->fps);
            if (gif_frame(s->gif, px, stride, (int)(b - a)) != 0) {
                cli_error("%s %s: cannot write: %s", s->label, s->path, strerror(errno));
                return -1;
            }
            break;
        }
        if (s->pid < 0 && start_ffmpeg(s) != 0)
            return -1;
        int bad = 0;
        if (stride == 4 * s->width) {
            bad = write_all(s->fd, px, (size_t)stride * (size_t)s->height);
        } else {
            for (int y = 0; y < s->height && !bad; y++)
                bad = write_all(s->fd, px + (size_t)y * (size_t)stride, 4 * (size_t)s->width);
        }
        if (bad) {
            int e = errno;
            if (wait_ffmpeg(s) == 0)
                cli_error("%s %s: cannot send frames to ffmpeg: %s", s->label, s->path, strerror(e));
            return -1;
        }
        break;
    }
    s->frames++;
    return 0;
}

int sink_frame(sink *s, renderer *r)
{
    if (s->failed || put_frame(s, r) != 0) {
        s->failed = true;
        return -1;
    }
    return 0;
}

int sink_close(sink *s, renderer *r)
{
    /* After a failed frame ffmpeg may be gone (and reaped) with a file that
     * must not replace the target: nothing is kept. */
    if (s->failed) {
        sink_abort(s);
        return -1;
    }
    int rc = 0;
    switch (s->kind) {
    case SINK_PNG:
        if (renderer_write_png(r, s->out.fp) != 0) {
            cli_error("%s %s: cannot write the PNG", s->label, s->path);
            outfile_abort(&s->out);
            rc = -1;
        } else {
            rc = outfile_commit(&s->out);
        }
        break;
    case SINK_PATTERN:
        break;
    case SINK_GIF:
    case SINK_MP4:
        if (s->gif) {
            rc = gif_end(s->gif);
            s->gif = NULL;
            if (rc != 0) {
                cli_error("%s %s: cannot write: %s", s->label, s->path, strerror(errno));
                outfile_abort(&s->out);
            } else {
                rc = outfile_commit(&s->out);
            }
            break;
        }
        if (wait_ffmpeg(s) != 0 || s->frames == 0) {
            outfile_abort(&s->out);
            rc = -1;
            break;
        }
        /* ffmpeg wrote the temporary file under its own descriptor; ours is
         * unwritten, so closing it adds nothing before the rename. */
        rc = outfile_commit(&s->out);
        break;
    }
    sink_free(s);
    return rc;
}

void sink_abort(sink *s)
{
    if (!s)
        return;
    if (s->pid > 0) {
        kill(s->pid, SIGTERM);
        int st;
        while (waitpid(s->pid, &st, 0) < 0 && errno == EINTR)
            ;
        s->pid = -1;
    }
    if (s->fd >= 0)
        close(s->fd);
    if (s->gif) {
        gif_end(s->gif);
        s->gif = NULL;
    }
    outfile_abort(&s->out);
    sink_free(s);
}
