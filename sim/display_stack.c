/* sim/display_stack.c -- gives civetweb's threads a stack they can run on.
 *
 * Debian builds civetweb with its default USE_STACK_SIZE of 102400 bytes
 * and offers no run-time option to change it. glibc carves each thread's
 * static TLS out of that stack, and this library's solver pulls in OpenBLAS
 * (60 KiB of TLS) and METIS (28 KiB), which leaves civetweb's workers about
 * 10 KiB: the first request overflowed it inside getnameinfo(). So the
 * library interposes pthread_attr_setstacksize() and raises any request
 * below ISO_DISPLAY_MIN_STACK to it before calling glibc's. Larger requests
 * pass through unchanged; nothing else in the process asks for stacks this
 * small, and for those that did, more stack only costs address space. */
#ifdef ISO_WITH_CIVETWEB
#define _GNU_SOURCE
#include <dlfcn.h>
#include <pthread.h>
#include <stddef.h>

#define ISO_DISPLAY_MIN_STACK ((size_t)1 << 20)

typedef int (*setstacksize_fn)(pthread_attr_t *, size_t);

int pthread_attr_setstacksize(pthread_attr_t *attr, size_t size)
{
    /* dlsym's result is a constant of the process; looking it up on each call
     * keeps this file free of mutable state (thread creation is rare). */
    setstacksize_fn real;
    *(void **)&real = dlsym(RTLD_NEXT, "pthread_attr_setstacksize");
    if (!real)
        return 22; /* EINVAL: cannot happen with glibc */
    return real(attr, size < ISO_DISPLAY_MIN_STACK ? ISO_DISPLAY_MIN_STACK : size);
}
#else
typedef int iso_display__no_stack_shim; /* ISO C forbids an empty file */
#endif
