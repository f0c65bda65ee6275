/*
 * import_child.c — imp_level_import (import.h): a level file on disk, read
 * by assimp in a forked child.
 *
 * assimp is a large C++ parser of untrusted files, and Debian 12's 5.2.4
 * crashes on some malformed glTF (tests/fuzz/known). imp_level_import runs it
 * in a forked child that sends the finished level back over a pipe: a crash
 * or an abort there is an error message here, and nothing was loaded. The
 * level crosses as import_pack.c's bytes, checked as they are read.
 * Cost: a fork, and the level copied once through the pipe.
 */
#include "import_internal.h"

#include <assimp/cimport.h>
#include <assimp/version.h>

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

/* imp_level_import's work, in this process (the child's). */
static int level_import_here(const char *path, imp_level *out, char *err, size_t errlen)
{
    memset(out, 0, sizeof *out);
    const char *dot = strrchr(path, '.');
    if (!dot || !imp_known_format(dot + 1)) {
        snprintf(err, errlen, "%s: unsupported format (Vantage imports glTF 2.0 .gltf/.glb and OBJ .obj)", path);
        return -1;
    }
    FILE *f = fopen(path, "rb");
    if (!f) {
        snprintf(err, errlen, "%s: %s", path, strerror(errno));
        return -1;
    }
    /* a glTF file's JSON, for what assimp does not carry (import_material.c) */
    uint8_t *bytes = NULL;
    size_t n = 0, jl = 0;
    const char *json = NULL;
    if (strcasecmp(dot + 1, "obj") && !fseek(f, 0, SEEK_END)) {
        long len = ftell(f);
        /* a .glb: its header and JSON chunk only, not the binary one */
        uint8_t head[20];
        if (len >= 20 && !fseek(f, 0, SEEK_SET) && fread(head, 1, 20, f) == 20 && !memcmp(head, "glTF", 4) &&
            vp_ld_u32(head + 12) <= (uint64_t)len - 20)
            len = 20 + (long)vp_ld_u32(head + 12);
        if (len > 0 && !fseek(f, 0, SEEK_SET) && (bytes = malloc((size_t)len))) n = fread(bytes, 1, (size_t)len, f);
        if (!imp_gltf_json(bytes, n, &json, &jl)) json = NULL;
    }
    fclose(f);
    const struct aiScene *sc = aiImportFile(path, IMP_FLAGS);
    if (!sc) {
        snprintf(err, errlen, "%s: cannot import: %s", path, aiGetErrorString());
        free(bytes);
        return -1;
    }
    /* external images are read from the level's directory */
    char dir[4096];
    snprintf(dir, sizeof dir, "%s", path);
    char *slash = strrchr(dir, '/');
    if (slash) *slash = 0;
    else snprintf(dir, sizeof dir, ".");
    int rc = imp_level_from_scene(sc, path, dir, json, jl, out, err, errlen);
    free(bytes); /* the child exits after: freed for the sanitizers */
    return rc;
}

static bool write_all(int fd, const void *p, size_t n)
{
    const uint8_t *s = p;
    while (n) {
        ssize_t w = write(fd, s, n);
        if (w < 0 && errno == EINTR) continue;
        if (w <= 0) return false;
        s += w;
        n -= (size_t)w;
    }
    return true;
}

/* The child: import, send 'L' and the level or 'E' and the message, exit. */
static _Noreturn void import_child(int fd, const char *path)
{
    imp_level lv;
    char err[512];
    vp_writer w;
    vp_writer_init_grow(&w);
    uint8_t tag = 'L';
    if (level_import_here(path, &lv, err, sizeof err)) {
        tag = 'E';
        vp_put_bytes(&w, err, strlen(err));
    } else {
        imp_level_pack(&w, &lv);
        if (w.overflow) {
            tag = 'E';
            vp_writer_free(&w);
            vp_writer_init_grow(&w);
            vp_put_bytes(&w, "out of memory", 13);
        }
    }
    bool ok = !w.overflow && write_all(fd, &tag, 1) && write_all(fd, w.p, w.len);
    _exit(ok ? 0 : 1);
}

int imp_level_import(const char *path, imp_level *out, char *err, size_t errlen)
{
    memset(out, 0, sizeof *out);
    int fds[2];
    /* close-on-exec: a process the child starts (a sanitizer's symbolizer
       when assimp crashes under ASan) must not keep the pipe open, or the
       end of the level never arrives here */
    if (pipe2(fds, O_CLOEXEC)) {
        snprintf(err, errlen, "%s: cannot start the importer: %s", path, strerror(errno));
        return -1;
    }
    fflush(NULL); /* nothing buffered is written twice */
    pid_t pid = fork();
    if (pid < 0) {
        snprintf(err, errlen, "%s: cannot start the importer: %s", path, strerror(errno));
        close(fds[0]);
        close(fds[1]);
        return -1;
    }
    if (pid == 0) {
        /* a crash ends the child, whatever handlers the caller set (a
         * test framework's would carry on running the caller's code here) */
        static const int fatal[] = {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT, SIGSYS, SIGPIPE};
        for (size_t i = 0; i < sizeof fatal / sizeof fatal[0]; i++) signal(fatal[i], SIG_DFL);
        close(fds[0]);
        import_child(fds[1], path);
    }
    close(fds[1]);
    vp_writer in; /* what the child sent */
    vp_writer_init_grow(&in);
    uint8_t chunk[1 << 16];
    int read_errno = 0;
    /* a file that sends assimp into an endless loop is an error, not a
       hang: VANTAGE_IMPORT_TIMEOUT seconds (default 300) */
    const char *ts = getenv("VANTAGE_IMPORT_TIMEOUT");
    double limit = ts && atof(ts) > 0 ? atof(ts) : 300.0;
    struct timespec t0;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    bool timed_out = false;
    for (;;) {
        struct timespec now;
        clock_gettime(CLOCK_MONOTONIC, &now);
        double left = limit - ((double)(now.tv_sec - t0.tv_sec) + (now.tv_nsec - t0.tv_nsec) * 1e-9);
        struct pollfd pf = {.fd = fds[0], .events = POLLIN};
        int pr = left > 0 ? poll(&pf, 1, (int)(left * 1000) + 1) : 0;
        if (pr < 0 && errno == EINTR) continue;
        if (pr == 0) {
            timed_out = true;
            kill(pid, SIGKILL);
            break;
        }
        ssize_t r = read(fds[0], chunk, sizeof chunk);
        if (r < 0 && errno == EINTR) continue;
        if (r < 0) read_errno = errno;
        if (r <= 0) break;
        vp_put_bytes(&in, chunk, (size_t)r);
    }
    close(fds[0]);
    int st = 0;
    while (waitpid(pid, &st, 0) < 0 && errno == EINTR) {
    }
    int rc = -1;
    if (timed_out) {
        snprintf(err, errlen, "%s: assimp did not finish reading the file in %g s (VANTAGE_IMPORT_TIMEOUT); "
                 "stopped, nothing was loaded", path, limit);
    } else if (WIFSIGNALED(st)) {
        snprintf(err, errlen,
                 "%s: assimp crashed reading the file (%s); it is malformed or meets a bug in assimp %u.%u; "
                 "nothing was loaded",
                 path, strsignal(WTERMSIG(st)), aiGetVersionMajor(), aiGetVersionMinor());
    } else if (in.overflow || read_errno) {
        snprintf(err, errlen, "%s: cannot take the level from the importer: %s", path,
                 in.overflow ? "out of memory" : strerror(read_errno));
    } else if (!WIFEXITED(st) || WEXITSTATUS(st) || in.len < 1) {
        snprintf(err, errlen, "%s: the importer stopped (exit status %d) before it finished; nothing was loaded",
                 path, WIFEXITED(st) ? WEXITSTATUS(st) : -1);
    } else if (in.p[0] == 'E') {
        size_t n = in.len - 1 < errlen ? in.len - 1 : errlen - 1;
        memcpy(err, in.p + 1, n);
        err[n] = 0;
    } else {
        vp_reader u;
        vp_reader_init(&u, in.p + 1, in.len - 1);
        if (in.p[0] == 'L' && imp_level_unpack(&u, out)) rc = 0;
        else {
            imp_level_free(out);
            snprintf(err, errlen, "%s: the importer sent a damaged level; nothing was loaded", path);
        }
    }
    vp_writer_free(&in);
    return rc;
}
