/* The few thread calls the RLS Embree loop needs, on Win32 or POSIX threads.
 *
 *     RLS_THREAD_ENTRY(name, arg) { ...; RLS_THREAD_RETURN; }   a thread's function
 *     rls_thread_start(&t, name, arg)   1 when the thread started, 0 when it did not
 *     rls_thread_join(t)                waits for it and releases it
 *
 * C11's <threads.h> would do, but neither macOS's libc nor MinGW-w64 has it, so this
 * is the portable way: CreateThread on Windows, pthreads elsewhere (Linux, macOS).
 * RLS_EXPORT marks the functions the shared library exports (everything else is
 * hidden, built with -fvisibility=hidden). */
#ifndef RLS_THREADS_H
#define RLS_THREADS_H

#if defined(_WIN32)
#define WIN32_LEAN_AND_MEAN
#include <windows.h>

#define RLS_EXPORT __declspec(dllexport)
#define RLS_THREAD_ENTRY(name, arg) static DWORD WINAPI name(LPVOID arg)
#define RLS_THREAD_RETURN return 0
typedef HANDLE rls_thread;

static int rls_thread_start(rls_thread *t, LPTHREAD_START_ROUTINE fn, void *arg) {
    *t = CreateThread(NULL, 0, fn, arg, 0, NULL);
    return *t != NULL;
}

static void rls_thread_join(rls_thread t) {
    WaitForSingleObject(t, INFINITE);
    CloseHandle(t);
}

#else
#include <pthread.h>

#if defined(__GLIBC__) && defined(__x86_64__)
/* glibc 2.34 moved the pthread functions into libc under a new version, GLIBC_2.34, and
 * a compiler on such a system binds to it: the library would not load in a Blender on
 * an older glibc (Blender 4.2 needs 2.28). Bind to the first version instead, which
 * every glibc since x86-64's first one has (in libpthread before 2.34, in libc since);
 * tools/build_native.py checks every build needs nothing newer than 2.28. */
__asm__(".symver pthread_create,pthread_create@GLIBC_2.2.5");
__asm__(".symver pthread_join,pthread_join@GLIBC_2.2.5");
#endif

#define RLS_EXPORT __attribute__((visibility("default")))
#define RLS_THREAD_ENTRY(name, arg) static void *name(void *arg)
#define RLS_THREAD_RETURN return NULL
typedef pthread_t rls_thread;

static int rls_thread_start(rls_thread *t, void *(*fn)(void *), void *arg) {
    return pthread_create(t, NULL, fn, arg) == 0;
}

static void rls_thread_join(rls_thread t) {
    pthread_join(t, NULL);
}
#endif

#endif /* RLS_THREADS_H */
