/* common/iso_api.h -- what libisoshape exports.
 *
 * The library is compiled with hidden visibility: a function is visible to a
 * program that links the shared library only when its declaration in an
 * installed header carries ISO_API (cf. SQLITE_API, UV_EXTERN). The
 * internal functions that a part's files share (iso_<module>__<name>,
 * declared in the part's internal.h) stay inside; white-box tests reach them
 * by linking the library's static form, isoshape_internal, which is not
 * installed. Every installed header includes this one, directly or through
 * iso_err.h. */
#ifndef ISO_API_H
#define ISO_API_H

#if defined(__GNUC__)
#define ISO_API __attribute__((visibility("default")))
#else
#define ISO_API
#endif

#endif
