/* common/iso_version.h -- which isoshape this is.
 *
 * The three numbers below are the one place the version is written: the
 * build reads them for the project's version (CMakeLists.txt), which the
 * shared library's file name and isoshape.pc carry. The macros say which
 * version a program was compiled against, iso_version() which library it
 * runs with (cf. SQLITE_VERSION and sqlite3_libversion(), UV_VERSION_HEX
 * and uv_version()); a program that needs both to agree compares them. */
#ifndef ISO_VERSION_H
#define ISO_VERSION_H

#include "iso_api.h"

#define ISO_VERSION_MAJOR 0
#define ISO_VERSION_MINOR 1
#define ISO_VERSION_PATCH 0

#define ISO_VERSION__STR(x) #x
#define ISO_VERSION__XSTR(x) ISO_VERSION__STR(x)
/* "MAJOR.MINOR.PATCH" */
#define ISO_VERSION_STRING                                                                         \
    ISO_VERSION__XSTR(ISO_VERSION_MAJOR)                                                           \
    "." ISO_VERSION__XSTR(ISO_VERSION_MINOR) "." ISO_VERSION__XSTR(ISO_VERSION_PATCH)
/* MAJOR * 10000 + MINOR * 100 + PATCH: comparable with < and > */
#define ISO_VERSION_NUMBER (ISO_VERSION_MAJOR * 10000 + ISO_VERSION_MINOR * 100 + ISO_VERSION_PATCH)

/* The library's version, "MAJOR.MINOR.PATCH" (ISO_VERSION_STRING as the
 * library was built). Static storage, never NULL. */
ISO_API const char *iso_version(void);

/* The library's version as ISO_VERSION_NUMBER was when it was built. */
ISO_API int iso_version_number(void);

#endif
