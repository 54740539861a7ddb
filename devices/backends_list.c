/* devices/backends_list.c -- which backends this build has (CMake says). */
#include "iso_dev.h"

#ifndef ISO_DEV_BACKEND_LIST
#define ISO_DEV_BACKEND_LIST "fake replay tty tcp"
#endif

const char *iso_dev_backends(void)
{
    return ISO_DEV_BACKEND_LIST;
}
