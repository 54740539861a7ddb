/* common/iso_version.c -- the library's version (iso_version.h). */
#include "iso_version.h"

_Static_assert(ISO_VERSION_MINOR < 100 && ISO_VERSION_PATCH < 100,
               "ISO_VERSION_NUMBER keeps two decimal digits each for minor and patch");

const char *iso_version(void)
{
    return ISO_VERSION_STRING;
}

int iso_version_number(void)
{
    return ISO_VERSION_NUMBER;
}
