/* client/commander.c — being written (issue 8) */
#include "cli.h"

int cmd_commander(cli *k, int argc, char **argv)
{
    (void)k;
    (void)argc;
    (void)argv;
    return die_usage("commander: not built yet");
}
