/* actuators/emu_find.c -- where the emulated MCU's two parts are: the
 * qemu-system-arm to run and the firmware ELF to run in it
 * (act_internal.h). */
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "act_internal.h"

/* Where `cmake --install` puts the firmware ELF (actuators/CMakeLists.txt); the
 * build tree is never looked in: a build puts the ELF next to the isoshape
 * command, and its tests name it in $ISO_FB_FIRMWARE. */
#ifndef ISO_FB_FIRMWARE_INSTALLED
#define ISO_FB_FIRMWARE_INSTALLED ""
#endif

static int executable(const char *p)
{
    return p && p[0] && access(p, X_OK) == 0;
}
static int readable(const char *p)
{
    struct stat st;
    return p && p[0] && stat(p, &st) == 0 && S_ISREG(st.st_mode);
}

int iso_act__find_qemu(char *out, size_t cap, char *why, size_t why_cap)
{
    const char *env = getenv("ISO_FB_QEMU");
    if (env) {
        snprintf(out, cap, "%s", env);
        snprintf(why, why_cap, "ISO_FB_QEMU='%s' is %s", env, env[0] ? "not executable" : "empty");
        return executable(env);
    }
    const char *path = getenv("PATH");
    char dirs[4096];
    snprintf(dirs, sizeof dirs, "%s", path ? path : "/usr/bin:/bin");
    for (char *save = NULL, *d = strtok_r(dirs, ":", &save); d; d = strtok_r(NULL, ":", &save)) {
        if ((size_t)snprintf(out, cap, "%s/qemu-system-arm", d) < cap && executable(out))
            return 1;
    }
    snprintf(why, why_cap, "qemu-system-arm is not installed (not on PATH)");
    return 0;
}

int iso_act__find_firmware(char *out, size_t cap, char *why, size_t why_cap)
{
    const char *env = getenv("ISO_FB_FIRMWARE");
    if (env) {
        snprintf(out, cap, "%s", env);
        snprintf(why, why_cap, "ISO_FB_FIRMWARE='%s' is not a file", env);
        return readable(env);
    }
    char exe[PATH_MAX];
    ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1);
    if (n > 0) {
        exe[n] = '\0';
        char *slash = strrchr(exe, '/');
        if (slash) {
            *slash = '\0';
            static const char *const rel[] = {"fb_firmware.elf",
                                              "../share/isoshape/fb_firmware.elf"};
            for (size_t i = 0; i < 2; i++)
                if ((size_t)snprintf(out, cap, "%s/%s", exe, rel[i]) < cap && readable(out))
                    return 1;
        }
    }
    if (readable(ISO_FB_FIRMWARE_INSTALLED)) {
        snprintf(out, cap, "%s", ISO_FB_FIRMWARE_INSTALLED);
        return 1;
    }
    snprintf(why, why_cap,
             "no firmware ELF next to the program, in its ../share/isoshape/ or at '%s' "
             "(built where arm-none-eabi-gcc is installed; ISO_FB_FIRMWARE names one)",
             ISO_FB_FIRMWARE_INSTALLED);
    return 0;
}
