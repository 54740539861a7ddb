/* controller/cmd_devices.c -- `isoshape devices`: what is connected and
 * usable, and for anything found but unusable, why and what fixes it. */
#include "internal.h"

#include <stdio.h>
#include <string.h>

#include "iso_dev_enum.h"

static const iso_cli__opt devices_options[] = {{0}};

static int devices_main(int argc, char **argv)
{
    int status = iso_cli__parse(&iso_cli__devices_cmd, argc, argv, NULL, NULL, 0, NULL);
    if (status >= 0)
        return status;
    iso_dev_found f[64];
    size_t n = iso_dev_enumerate(f, 64);
    char built[128];
    printf("backends: %s\n", iso_dev_backends(built, sizeof built));
    size_t usable = 0;
    for (size_t i = 0; i < n; i++) {
        char ids[16] = "";
        if (f[i].vid || f[i].pid)
            snprintf(ids, sizeof ids, " %04x:%04x", f[i].vid, f[i].pid);
        printf("%-10s %-24s %s%s: %s\n", f[i].backend, f[i].path, f[i].what, ids,
               f[i].usable ? "usable" : "not usable");
        if (!f[i].usable && f[i].why[0])
            printf("           %s\n", f[i].why);
        usable += f[i].usable != 0;
    }
    printf("%zu found, %zu usable\n", n, usable);
    return 0;
}

const iso_cli__cmd iso_cli__devices_cmd = {
    .name = "devices",
    .summary = "list input devices, usable or why not",
    .usage = "usage: isoshape devices\n"
             "\n"
             "Lists the input devices this build can see: 3D mice (hidapi, spacenavd),\n"
             "serial adapters (libserialport), GPIO chips (libgpiod) and known USB\n"
             "devices (libusb), each usable or with the reason it is not.\n",
    .opts = devices_options,
    .main = devices_main};
