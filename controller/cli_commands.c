/* controller/cli_commands.c -- the isoshape command's subcommands, in the
 * order `isoshape --help` lists them: main() dispatches through this table,
 * and test_cli_opts walks it to check every command's --help against its
 * option table. */
#include "internal.h"

#include <string.h>

const iso_cli__cmd *const iso_cli__commands[] = {&iso_cli__deform_cmd,
                                                 &iso_cli__field_cmd,
                                                 &iso_cli__metrics_cmd,
                                                 &iso_cli__bench_cmd,
                                                 &iso_cli__record_cmd,
                                                 &iso_cli__replay_cmd,
                                                 &iso_cli__inspect_cmd,
                                                 &iso_cli__devices_cmd,
                                                 &iso_cli__check_cmd,
                                                 &iso_cli__run_cmd,
                                                 &iso_cli__export_cmd,
                                                 &iso_cli__version_cmd,
                                                 NULL};

const iso_cli__cmd *iso_cli__command(const char *name)
{
    for (int i = 0; iso_cli__commands[i]; i++)
        if (strcmp(iso_cli__commands[i]->name, name) == 0)
            return iso_cli__commands[i];
    return NULL;
}
