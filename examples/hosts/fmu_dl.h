/* Loading an FMU's binary in a C host, on Linux and on Windows: dlopen/dlsym/dlclose there,
 * LoadLibrary/GetProcAddress/FreeLibrary under _WIN32 (mingw-w64 or MSVC), the FMU's
 * binaries folder and file suffix of the platform, and the resource location of an
 * extracted FMU as a file URI. Header only; used by fmi2_host.c and the test hosts.
 *
 *   char path[4096], uri[4200];
 *   fmu_binary_path(dir, model, path, sizeof path);   dir/binaries/<platform>/<model><suffix>
 *   fmu_resource_uri(dir, uri, sizeof uri);           file:///<dir>/resources
 *   fmu_lib lib = fmu_dlopen(path);                   NULL: fmu_dlerror() says why
 *   void *f = fmu_dlsym(lib, "fmi2Instantiate");
 *   fmu_dlclose(lib);                                 0 when unloaded
 */
#ifndef FMU_DL_H
#define FMU_DL_H

#include <stdio.h>
#include <string.h>

#ifdef _WIN32
#include <windows.h>

#define FMU_PLATFORM "win64"
#define FMU_SUFFIX ".dll"
typedef HMODULE fmu_lib;

static const char *fmu_dl_error;
static char fmu_dl_buf[512];

static inline void fmu_dl_fail(const char *what) {
    DWORD code = GetLastError();
    int n = snprintf(fmu_dl_buf, sizeof fmu_dl_buf, "%s: Windows error %lu ", what,
                     (unsigned long)code);
    if (n > 0 && (size_t)n < sizeof fmu_dl_buf)
        FormatMessageA(FORMAT_MESSAGE_FROM_SYSTEM | FORMAT_MESSAGE_IGNORE_INSERTS, NULL, code,
                       0, fmu_dl_buf + n, (DWORD)(sizeof fmu_dl_buf - (size_t)n), NULL);
    fmu_dl_error = fmu_dl_buf;
}

/* The DLL's own folder is searched for what it needs (LOAD_WITH_ALTERED_SEARCH_PATH). */
static inline fmu_lib fmu_dlopen(const char *path) {
    fmu_lib lib = LoadLibraryExA(path, NULL, LOAD_WITH_ALTERED_SEARCH_PATH);
    if (!lib) fmu_dl_fail("LoadLibrary");
    return lib;
}

static inline void *fmu_dlsym(fmu_lib lib, const char *name) {
    FARPROC f = GetProcAddress(lib, name);
    void *p;
    if (!f) fmu_dl_fail(name);
    memcpy(&p, &f, sizeof p); /* a function's address as the data pointer dlsym returns */
    return p;
}

static inline int fmu_dlclose(fmu_lib lib) {
    if (FreeLibrary(lib)) return 0;
    fmu_dl_fail("FreeLibrary");
    return -1;
}

static inline const char *fmu_dlerror(void) {
    const char *e = fmu_dl_error;
    fmu_dl_error = NULL;
    return e ? e : "no error";
}
#else
#include <dlfcn.h>

#define FMU_PLATFORM "linux64"
#define FMU_SUFFIX ".so"
typedef void *fmu_lib;

static inline fmu_lib fmu_dlopen(const char *path) {
    return dlopen(path, RTLD_NOW | RTLD_LOCAL);
}
static inline void *fmu_dlsym(fmu_lib lib, const char *name) { return dlsym(lib, name); }
static inline int fmu_dlclose(fmu_lib lib) { return dlclose(lib); }
static inline const char *fmu_dlerror(void) {
    const char *e = dlerror();
    return e ? e : "no error";
}
#endif

/* dir/binaries/<platform>/<model><suffix> */
static inline void fmu_binary_path(const char *dir, const char *model, char *out, size_t n) {
    snprintf(out, n, "%s/binaries/%s/%s%s", dir, FMU_PLATFORM, model, FMU_SUFFIX);
}

/* The resources folder of the extracted FMU in dir (an absolute path) as a file URI:
 * file:///abs/resources, on Windows file:///C:/abs/resources (backslashes as slashes). */
static inline void fmu_resource_uri(const char *dir, char *out, size_t n) {
    snprintf(out, n, "file://%s%s/resources", dir[0] == '/' ? "" : "/", dir);
    for (char *p = out; *p; p++)
        if (*p == '\\') *p = '/';
}

#endif
