/* common/iso_names.c -- see iso_names.h. */
#include "iso_names.h"

#include <stdio.h>
#include <string.h>

int iso_names_find(const char *const *names, const char *word)
{
    for (int i = 0; word && names[i]; i++)
        if (strcmp(names[i], word) == 0)
            return i;
    return -1;
}

const char *iso_names_get(const char *const *names, int value)
{
    for (int i = 0; names[i]; i++)
        if (i == value)
            return names[i];
    return "?";
}

const char *iso_names_join(const char *const *names, const char *sep, const char *last, char *buf,
                           size_t cap)
{
    size_t len = 0;
    if (cap)
        buf[0] = '\0';
    for (int i = 0; names[i] && len < cap; i++) {
        const char *gap = i == 0 ? "" : names[i + 1] ? sep : last;
        int n = snprintf(buf + len, cap - len, "%s%s", gap, names[i]);
        len += n > 0 ? (size_t)n : 0;
    }
    return buf;
}

const char *iso_names_list(const char *const *names, const char *last, char *buf, size_t cap)
{
    return iso_names_join(names, ", ", last, buf, cap);
}
