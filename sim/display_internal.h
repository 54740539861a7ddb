/* sim/display_internal.h -- private to sim/: the page's text. */
#ifndef ISO_DISPLAY_INTERNAL_H
#define ISO_DISPLAY_INTERNAL_H

extern const char iso_display__page_html[];
extern const char iso_display__app_js[];

#endif
