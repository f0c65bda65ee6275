/*
 * replay_main.c — runs LLVMFuzzerTestOneInput over saved inputs without
 * libFuzzer, so any compiler and build config (ASan+UBSan in `make test`)
 * can replay the corpus and the saved crashes.
 *
 *   fuzz_<name>_replay [--no-fork] PATH...
 *
 * A PATH is a file or a directory (its regular files, not recursive, in
 * name order). Each input runs in a forked child, so one crash (sanitizer
 * abort, a failed property, a signal) is counted and named and the rest
 * still run; --no-fork runs them in-process (for a debugger). Prints
 * "fuzz replay fuzz_<name>: N inputs, F failures" (the program's name
 * without _replay) and exits 1 if F > 0 or a path could not be read.
 */
#include <dirent.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static int g_fork = 1;
static unsigned g_inputs, g_failures, g_errors;

static uint8_t *read_file(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    size_t cap = 4096, n = 0;
    uint8_t *buf = malloc(cap);
    while (buf) {
        n += fread(buf + n, 1, cap - n, f);
        if (n < cap) break;
        uint8_t *grown = realloc(buf, cap *= 2);
        if (!grown) free(buf);
        buf = grown;
    }
    int bad = ferror(f);
    fclose(f);
    if (bad || !buf) {
        free(buf);
        return NULL;
    }
    /* exactly-sized copy: an overread past the input is an ASan report */
    uint8_t *exact = malloc(n ? n : 1);
    if (exact) memcpy(exact, buf, n);
    free(buf);
    *size = n;
    return exact;
}

static void run_one(const char *path)
{
    size_t size = 0;
    uint8_t *data = read_file(path, &size);
    if (!data) {
        fprintf(stderr, "fuzz replay: cannot read %s\n", path);
        g_errors++;
        return;
    }
    g_inputs++;
    if (!g_fork) {
        fprintf(stderr, "fuzz replay: %s\n", path);
        LLVMFuzzerTestOneInput(data, size);
        free(data);
        return;
    }
    fflush(NULL);
    pid_t pid = fork();
    if (pid < 0) {
        perror("fuzz replay: fork");
        exit(2);
    }
    if (pid == 0) {
        LLVMFuzzerTestOneInput(data, size);
        free(data);
        exit(0); /* exit, not _exit: LeakSanitizer checks at exit */
    }
    free(data);
    int st = 0;
    while (waitpid(pid, &st, 0) < 0) {
        perror("fuzz replay: waitpid");
        exit(2);
    }
    if (WIFEXITED(st) && WEXITSTATUS(st) == 0) return;
    g_failures++;
    if (WIFSIGNALED(st))
        fprintf(stderr, "fuzz replay: FAILED %s (signal %d)\n", path, WTERMSIG(st));
    else
        fprintf(stderr, "fuzz replay: FAILED %s (exit %d)\n", path, WEXITSTATUS(st));
}

static int by_name(const void *a, const void *b)
{
    return strcmp(*(char *const *)a, *(char *const *)b);
}

static void run_dir(const char *dir)
{
    DIR *d = opendir(dir);
    if (!d) {
        fprintf(stderr, "fuzz replay: cannot open %s\n", dir);
        g_errors++;
        return;
    }
    char **names = NULL;
    size_t n = 0, cap = 0;
    struct dirent *e;
    while ((e = readdir(d))) {
        if (e->d_name[0] == '.') continue; /* ., .., .gitkeep and friends */
        size_t len = strlen(dir) + strlen(e->d_name) + 2;
        char *path = malloc(len);
        if (!path) break;
        snprintf(path, len, "%s/%s", dir, e->d_name);
        struct stat sb;
        if (stat(path, &sb) != 0 || !S_ISREG(sb.st_mode)) {
            free(path);
            continue;
        }
        if (n == cap) {
            char **grown = realloc(names, (cap = cap ? 2 * cap : 64) * sizeof *names);
            if (!grown) {
                free(path);
                break;
            }
            names = grown;
        }
        names[n++] = path;
    }
    closedir(d);
    if (n) qsort(names, n, sizeof *names, by_name);
    for (size_t i = 0; i < n; i++) {
        run_one(names[i]);
        free(names[i]);
    }
    free(names);
}

int main(int argc, char **argv)
{
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--no-fork") == 0) {
            g_fork = 0;
            continue;
        }
        struct stat sb;
        if (stat(argv[i], &sb) != 0) {
            fprintf(stderr, "fuzz replay: no such path %s\n", argv[i]);
            g_errors++;
        } else if (S_ISDIR(sb.st_mode)) {
            run_dir(argv[i]);
        } else {
            run_one(argv[i]);
        }
    }
    const char *name = strrchr(argv[0], '/') ? strrchr(argv[0], '/') + 1 : argv[0];
    size_t nl = strlen(name);
    if (nl > 7 && !strcmp(name + nl - 7, "_replay")) nl -= 7;
    printf("fuzz replay %.*s: %u inputs, %u failures\n", (int)nl, name, g_inputs, g_failures);
    return (g_failures || g_errors) ? 1 : 0;
}
