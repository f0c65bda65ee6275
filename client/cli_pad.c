/* client/cli_pad.c — being written (issue 8) */
#include "cli.h"

int cmd_pad(cli *k, int argc, char **argv)
{
    (void)k;
    (void)argc;
    (void)argv;
    return die_usage("pad: not built yet");
}
