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
    fprintf(f,
            "usage: isoshape <command> [options]\n"
            "\n"
            "Isometry-preserving continuous deformation (Martinez Esturo, Roessl, Theisel 2010).\n"
            "\n"
            "commands:\n"
            "  deform   integrate the deformation of a mesh as its handle moves to its final pose\n"
            "  field    solve the deformation field once, at the rest pose\n"
            "  metrics  distortion between an original mesh and a deformed copy\n"
            "  bench    time the four benchmark problems against the paper and this machine\n"
            "  record   record live input devices (3D mouse, serial, GPIO) while running them\n"
            "  replay   replay a device recording, deterministically, at any speed\n"
            "  inspect  print a device recording, record by record, decoded\n"
            "  devices  list input devices, usable or why not\n"
            "  check    validate a scene file without running it\n"
            "  run      run a scene: devices or a replay drive the mesh in real time\n"
            "\n"
            "  isoshape --version     versions, and the CHOLMOD and BLAS this process runs with\n"
            "  isoshape <command> --help\n");
}

/* Device commands (controller/cmd_record.c, cmd_replay.c, cmd_inspect.c, cmd_devices.c). */
int iso_cli__record(int argc, char **argv);
int iso_cli__replay(int argc, char **argv);
int iso_cli__inspect(int argc, char **argv);
int iso_cli__devices(int argc, char **argv);
int iso_cli__check(int argc, char **argv);     /* controller/cmd_check.c */
int iso_cli__run_scene(int argc, char **argv); /* controller/cmd_run.c */

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
    if (strcmp(cmd, "--version") == 0 || strcmp(cmd, "version") == 0) {
        iso_cli__print_version();
        return 0;
    }
    if (strcmp(cmd, "deform") == 0)
        return iso_cli__deform(argc - 1, argv + 1);
    if (strcmp(cmd, "field") == 0)
        return iso_cli__field(argc - 1, argv + 1);
    if (strcmp(cmd, "metrics") == 0)
        return iso_cli__metrics(argc - 1, argv + 1);
    if (strcmp(cmd, "bench") == 0)
        return iso_cli__bench_run(argc - 1, argv + 1);
    if (strcmp(cmd, "record") == 0)
        return iso_cli__record(argc - 1, argv + 1);
    if (strcmp(cmd, "replay") == 0)
        return iso_cli__replay(argc - 1, argv + 1);
    if (strcmp(cmd, "inspect") == 0)
        return iso_cli__inspect(argc - 1, argv + 1);
    if (strcmp(cmd, "devices") == 0)
        return iso_cli__devices(argc - 1, argv + 1);
    if (strcmp(cmd, "check") == 0)
        return iso_cli__check(argc - 1, argv + 1);
    if (strcmp(cmd, "run") == 0)
        return iso_cli__run_scene(argc - 1, argv + 1);
    if (cmd[0] == '-')
        iso_cli__fail(NULL, "unknown option '%s' (see isoshape --help).", cmd);
    else
        iso_cli__fail(NULL, "unknown command '%s': see isoshape --help.", cmd);
    return 2;
}
