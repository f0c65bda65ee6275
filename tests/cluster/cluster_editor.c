/*
 * cluster_editor — one editor of the cluster tests (tests/cluster/run.py):
 * adds entities at a steady rate through libvantage, across failovers,
 * and logs every edit the cluster acknowledged.
 *
 *   cluster_editor --endpoints LIST --base ID --rate N --seconds S --log FILE
 *
 * Each edit adds entity base+k (a sphere at (k, 0, base/1000)). An
 * acknowledged one is logged "A ID EPOCH MS" (MS: since start). When the
 * connection breaks (the writer died) the editor connects again through
 * the endpoint list (a replica's NOT_WRITER sends it on to the writer) and
 * sends the same entity again: DUPLICATE then means the lost answer's edit
 * was applied ("D ID"). The test checks that every "A" entity is in every
 * daemon's scene at the end. On exit: a summary line on stdout, with the
 * longest time without an acknowledgement (what a failover cost it).
 */
#include "vantage.h"

#include <errno.h>
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

static double now_ms(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec * 1e3 + t.tv_nsec / 1e6;
}

static void nap_ms(int ms)
{
    struct timespec t = {.tv_sec = ms / 1000, .tv_nsec = (long)(ms % 1000) * 1000000L};
    nanosleep(&t, NULL);
}

int main(int argc, char **argv)
{
    const char *eps = NULL, *logpath = NULL;
    unsigned long long base = 1;
    double rate = 20, seconds = 10;
    static const struct option opts[] = {{"endpoints", 1, 0, 'e'}, {"base", 1, 0, 'b'}, {"rate", 1, 0, 'r'},
                                         {"seconds", 1, 0, 's'}, {"log", 1, 0, 'l'}, {0, 0, 0, 0}};
    int o;
    while ((o = getopt_long(argc, argv, "", opts, NULL)) != -1) {
        switch (o) {
        case 'e': eps = optarg; break;
        case 'b': base = strtoull(optarg, NULL, 10); break;
        case 'r': rate = atof(optarg); break;
        case 's': seconds = atof(optarg); break;
        case 'l': logpath = optarg; break;
        default: fprintf(stderr, "usage: cluster_editor --endpoints LIST --base ID --rate N --seconds S --log FILE\n"); return 2;
        }
    }
    if (!eps || !logpath || rate <= 0 || seconds <= 0) {
        fprintf(stderr, "cluster_editor: --endpoints, --log, a rate and seconds > 0 are needed\n");
        return 2;
    }
    FILE *log = fopen(logpath, "w");
    if (!log) {
        fprintf(stderr, "cluster_editor: %s: %s\n", logpath, strerror(errno));
        return 1;
    }
    vtc_connect_opts co = {.endpoints = eps, .role = VP_ROLE_EDITOR, .name = "cluster_editor", .timeout_ms = 4000};
    vtc_client *c = NULL;
    double t0 = now_ms(), last_ack = t0, worst_gap = 0;
    unsigned long acked = 0, dups = 0, reconnects = 0, retries = 0;
    unsigned long long k = 0;
    char err[600];
    while (now_ms() - t0 < seconds * 1000) {
        double due = t0 + (double)k * 1000.0 / rate;
        double wait = due - now_ms();
        if (wait > 0) nap_ms((int)wait);
        if (!c) {
            if (vtc_connect(&co, &c, err, sizeof err)) {
                c = NULL;
                nap_ms(50);
                continue;
            }
            reconnects++;
        }
        uint64_t id = base + k;
        vp_entity e;
        memset(&e, 0, sizeof e);
        e.id = id;
        e.sphere[0] = (double)k;
        e.sphere[2] = (double)(base / 1000);
        e.sphere[3] = 1; /* the box derived from it */
        uint32_t handle;
        uint64_t epoch = 0;
        int rc = vtc_add(c, &e, 1, &handle, &epoch);
        double t = now_ms();
        if (rc == VP_OK || rc == VP_ERR_DUPLICATE) {
            if (rc == VP_OK) {
                fprintf(log, "A %llu %llu %.1f\n", (unsigned long long)id, (unsigned long long)epoch, t - t0);
                acked++;
            } else {
                fprintf(log, "D %llu\n", (unsigned long long)id);
                dups++;
            }
            fflush(log);
            if (t - last_ack > worst_gap) worst_gap = t - last_ack;
            last_ack = t;
            k++;
            continue;
        }
        retries++;
        if (rc == VTC_ERR_IO) { /* the daemon went away (or timed out): another one */
            vtc_close(c);
            c = NULL;
            nap_ms(20);
        } else {
            nap_ms(50); /* NOT_WRITER with no writer yet, BUSY: the same edit again soon */
        }
    }
    vtc_close(c);
    fclose(log);
    printf("editor %llu: %lu acknowledged, %lu applied without an answer, %lu retries, %lu connections, longest "
           "wait %.0f ms\n",
           base, acked, dups, retries, reconnects, worst_gap);
    return 0;
}
