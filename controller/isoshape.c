/* controller/isoshape.c -- the isoshape command: picks the subcommand.
 *
 *   isoshape deform   integrate a deformation from rest to the handle's pose
 *   isoshape field    one field solve at the rest pose
 *   isoshape metrics  distortion between two meshes
 *   isoshape bench    the four benchmark problems, timed against this machine's limits
 *   isoshape run      a scene in real time (controller/iso_loop.h)
 *   isoshape --version
 *
 * Exits: 0 done, 1 failed, 2 a usage error; a run stopped by SIGINT or
 * SIGTERM exits 128 + the signal (130, 143) after shutting down cleanly.
 * SIGPIPE is ignored: a write to a closed pipe (isoshape ... | head) is
 * one error on stderr and exit status 1, the same with or without the
 * display's sockets. */
#include "internal.h"

#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>

static void usage(FILE *f)
{
    fprintf(f, "usage: isoshape <command> [options]\n"
               "\n"
               "Isometry-preserving continuous deformation (Martinez Esturo, Roessl, Theisel "
               "2010).\n"
               "\n"
               "commands:\n");
    for (int i = 0; iso_cli__commands[i]; i++)
        if (iso_cli__commands[i]->summary)
            fprintf(f, "  %-8s %s\n", iso_cli__commands[i]->name, iso_cli__commands[i]->summary);
    fprintf(f, "\n"
               "  isoshape --version     versions, and the CHOLMOD and BLAS this process runs "
               "with\n"
               "  isoshape <command> --help\n");
}

/* The subcommand's status, then stdout's: output lost to a closed pipe or
 * a full disk is an error, said once. */
static int finish(int status)
{
    if (fflush(stdout) != 0 || ferror(stdout)) {
        int e = errno;
        fprintf(stderr, "isoshape: standard output: %s\n", strerror(e ? e : EIO));
        return status ? status : 1;
    }
    return status;
}

static int dispatch(int argc, char **argv);

int main(int argc, char **argv)
{
    signal(SIGPIPE, SIG_IGN); /* EPIPE from write() instead of a silent death */
    return finish(dispatch(argc, argv));
}

static int dispatch(int argc, char **argv)
{
    iso_cli__tune_blas(argv);
    if (argc < 2) {
        usage(stderr);
        return 2;
    }
    const char *cmd = argv[1];
    if (strcmp(cmd, "--help") == 0 || strcmp(cmd, "-h") == 0 || strcmp(cmd, "help") == 0) {
        usage(stdout);
        return 0;
    }
    const iso_cli__cmd *c = iso_cli__command(strcmp(cmd, "--version") == 0 ? "version" : cmd);
    if (c)
        return c->main(argc - 1, argv + 1);
    if (cmd[0] == '-')
        iso_cli__fail(NULL, "unknown option '%s' (see isoshape --help).", cmd);
    else
        iso_cli__fail(NULL, "unknown command '%s': see isoshape --help.", cmd);
    return 2;
}
