/* devices/backends_list.c -- which backends this build has. Each optional
 * backend's own file says whether it is compiled in (internal.h), so the
 * list cannot disagree with the code that answers an open. */
#include <stdio.h>
#include <string.h>

#include "internal.h"
#include "iso_dev_enum.h"

static const int always_built = 1;

static const struct {
    const char *name;
    const int *built;
} backends[] = {
    {"fake", &always_built},
    {"replay", &always_built},
    {"tty", &always_built},
    {"tcp", &always_built},
    {"view", &always_built},
    {"hidapi", &iso_dev__hidapi_built},
    {"serialport", &iso_dev__serialport_built},
    {"gpiod", &iso_dev__gpiod_built},
    {"libusb", &iso_dev__libusb_built},
    {"spnav", &iso_dev__spnav_built},
};
#define N_BACKENDS (sizeof backends / sizeof backends[0])

int iso_dev_backend_built(const char *name)
{
    for (size_t i = 0; name && i < N_BACKENDS; i++)
        if (strcmp(backends[i].name, name) == 0)
            return *backends[i].built ? 1 : 0;
    return -1;
}

const char *iso_dev_backends(char *buf, size_t cap)
{
    size_t len = 0;
    if (!cap)
        return buf;
    buf[0] = '\0';
    for (size_t i = 0; i < N_BACKENDS; i++) {
        if (!*backends[i].built)
            continue;
        int n = snprintf(buf + len, cap - len, "%s%s", len ? " " : "", backends[i].name);
        if (n < 0 || (size_t)n >= cap - len) { /* whole names only */
            buf[len] = '\0';
            break;
        }
        len += (size_t)n;
    }
    return buf;
}
