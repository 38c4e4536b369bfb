/* The Python slave of the FMU: the scipy reference engine (engine = 1) runs in pythonfmu's
 * library (shipped beside this binary as MODEL_INNER_LIB) and the slave fmu_src/GearPair.py,
 * in a Python interpreter. Only this engine needs Python; this file loads it when an
 * instance chooses it, and forwards the instance's values, steps and states to the slave.
 *
 * - which Python: in a host without one, the interpreter recorded in resources/python.txt
 *   or named by GEARPAIR_PYTHON is loaded (`ensure_python`), and the packages the slave
 *   needs are checked before pythonfmu imports it (`check_python`): one message, no
 *   traceback;
 * - the embedded interpreter's lifetime (see `ensure_python`): exit and dlclose are safe;
 * - the slave cannot return fmi2Error itself (pythonfmu turns a Python exception into
 *   fmi2Fatal), so it logs a refusal with status error and returns normally; a call during
 *   which the slave logged an error returns fmi2Error here (`settle`);
 * - calls after the host's interpreter finalized are answered here (`py_slave_gone`).
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <pthread.h>
#include <spawn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>
#include <wchar.h>

#include "python_slave.h"

/* -- pythonfmu's library ---------------------------------------------------------------- */
static struct {
    fmi2InstantiateTYPE *instantiate;
    fmi2FreeInstanceTYPE *free_instance;
    fmi2SetupExperimentTYPE *setup;
    fmi2ComponentCallTYPE *enter, *exit_init;
    fmi2GetRealTYPE *get_real;
    fmi2GetIntegerTYPE *get_int;
    fmi2SetRealTYPE *set_real;
    fmi2SetIntegerTYPE *set_int;
    fmi2SetBooleanTYPE *set_bool;
    fmi2GetFMUstateTYPE *get_state;
    fmi2SetFMUstateTYPE *set_state;
    fmi2FreeFMUstateTYPE *free_state;
    fmi2SerializedFMUstateSizeTYPE *state_size;
    fmi2SerializeFMUstateTYPE *serialize;
    fmi2DeSerializeFMUstateTYPE *deserialize;
    fmi2DoStepTYPE *do_step;
    void (*release_guard)(void); /* pythonfmu's finalizePythonInterpreter */
} inner;
static pthread_mutex_t g_lock = PTHREAD_MUTEX_INITIALIZER; /* loading, instantiate, free */
static int g_loaded;
static int (*g_py_is_init)(void), (*g_py_finalizing)(void); /* see `py_gone` */

struct PySlave {
    Instance *inst;
    fmi2Component c;
    fmi2CallbackFunctions mine; /* given to pythonfmu: our logger, the host's memory */
    fmi2Status worst;           /* worst status the slave logged during the current call */
    int late_said;              /* the message about a finalized interpreter was given */
};

/* pythonfmu's logger callback: remember the worst status, pass the message on (pythonfmu
 * hands over a printf format, as FMI 2.0 allows). */
static void inner_logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                         fmi2String category, fmi2String message, ...) {
    (void)instance;
    PySlave *p = (PySlave *)env;
    if (!p || !message) return;
    if (status > p->worst) p->worst = status;
    char small[2048], *buf = small;
    va_list ap;
    va_start(ap, message);
    int n = vsnprintf(small, sizeof small, message, ap);
    va_end(ap);
    if (n >= (int)sizeof small) {
        char *big = malloc((size_t)n + 1);
        if (big) {
            va_start(ap, message);
            vsnprintf(big, (size_t)n + 1, message, ap);
            va_end(ap);
            buf = big;
        }
    }
    fmu_emit(p->inst, status, category, buf);
    if (buf != small) free(buf);
}

static void *load_sym(void *lib, const char *name, char *err, size_t n) {
    void *f = dlsym(lib, name);
    if (!f && !err[0]) snprintf(err, n, "%s has no function %s", MODEL_INNER_LIB, name);
    return f;
}

/* -- which Python ---------------------------------------------------------------------------
 * A host that is not Python has no interpreter: the layer loads one itself. Which one is
 * written in the FMU's resources (python.txt, by build_fmu.py: the Python that built it),
 * unless GEARPAIR_PYTHON names a python executable, which is then asked the same questions
 * (resources/gearpair_python.py prints them). Nothing in the host's environment is set. */
#define PY_FIELD 1024
typedef struct {
    char version[64], libpython[PY_FIELD], home[PY_FIELD], executable[PY_FIELD];
    char sites[8 * PY_FIELD]; /* package folders, one per line */
    char origin[PY_FIELD + 64]; /* how it was chosen, for messages */
} PyChoice;
static PyChoice g_py;
static int g_py_started; /* the interpreter is this layer's (not the host's) */

static void parse_choice(const char *text, PyChoice *c) {
    c->version[0] = c->libpython[0] = c->home[0] = c->executable[0] = c->sites[0] = 0;
    for (const char *line = text; line && *line;) {
        const char *nl = strchr(line, '\n'), *eq = strchr(line, '=');
        size_t len = nl ? (size_t)(nl - line) : strlen(line);
        if (eq && eq < line + len && line[0] != '#') {
            size_t k = (size_t)(eq - line), vlen = len - k - 1;
            char *dst = !strncmp(line, "version", k) && k == 7 ? c->version
                        : !strncmp(line, "libpython", k) && k == 9 ? c->libpython
                        : !strncmp(line, "home", k) && k == 4 ? c->home
                        : !strncmp(line, "executable", k) && k == 10 ? c->executable : NULL;
            size_t cap = dst == c->version ? sizeof c->version : PY_FIELD;
            if (dst && vlen < cap) {
                memcpy(dst, eq + 1, vlen);
                dst[vlen] = 0;
            } else if (k == 4 && !strncmp(line, "site", 4)) {
                size_t used = strlen(c->sites);
                if (used + vlen + 2 < sizeof c->sites)
                    snprintf(c->sites + used, sizeof c->sites - used, "%.*s\n", (int)vlen,
                             eq + 1);
            }
        }
        line = nl ? nl + 1 : NULL;
    }
}

static int read_text(const char *path, char *buf, size_t n) {
    FILE *f = fopen(path, "rb");
    if (!f) return -1;
    size_t got = fread(buf, 1, n - 1, f);
    buf[got] = 0;
    fclose(f);
    return 0;
}

/* Run `python script` and read what it prints (its stderr goes to /dev/null). */
static int ask_python(const char *python, const char *script, char *out, size_t n, char *err,
                      size_t en) {
    extern char **environ;
    int fds[2];
    if (pipe(fds)) {
        snprintf(err, en, "pipe failed: %s", strerror(errno));
        return -1;
    }
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_adddup2(&fa, fds[1], 1);
    posix_spawn_file_actions_addclose(&fa, fds[0]);
    posix_spawn_file_actions_addopen(&fa, 2, "/dev/null", O_WRONLY, 0);
    char *argv[] = {(char *)python, (char *)script, NULL};
    pid_t pid;
    int rc = posix_spawnp(&pid, python, &fa, NULL, argv, environ); /* a bare name: PATH */
    posix_spawn_file_actions_destroy(&fa);
    close(fds[1]);
    if (rc) {
        close(fds[0]);
        snprintf(err, en, "cannot run it: %s", strerror(rc));
        return -1;
    }
    size_t got = 0;
    ssize_t r;
    while ((r = read(fds[0], out + got, n - 1 - got)) > 0 || (r < 0 && errno == EINTR))
        if (r > 0 && (got += (size_t)r) >= n - 1) break;
    out[got] = 0;
    close(fds[0]);
    int status = 0;
    while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
    }
    if (!WIFEXITED(status) || WEXITSTATUS(status) || !strstr(out, "libpython=")) {
        snprintf(err, en, "it did not describe itself (exit status %d; is it Python 3?)",
                 WIFEXITED(status) ? WEXITSTATUS(status) : -1);
        return -1;
    }
    return 0;
}

static const char FIX[] =
    "Fix: set GEARPAIR_PYTHON to the python executable of an environment with numpy, scipy "
    "and pythonfmu whose Python has a shared libpython (a venv of such a Python "
    "works), or build the FMU on this machine (python build_fmu.py); see docs/hosts.md";

/* Fill g_py from GEARPAIR_PYTHON or the FMU's record. */
static int choose_python(const char *folder, char *err, size_t n) {
    static char text[16 * PY_FIELD];
    const char *over = getenv("GEARPAIR_PYTHON");
    char script[4200], why[512];
    snprintf(script, sizeof script, "%s/gearpair_python.py", folder);
    if (over && *over) {
        if (ask_python(over, script, text, sizeof text, why, sizeof why)) {
            snprintf(err, n, "GEARPAIR_PYTHON=%s: %s. Set it to a python executable (e.g. "
                     "<venv>/bin/python) or unset it to use the Python that built the FMU",
                     over, why);
            return -1;
        }
        snprintf(g_py.origin, sizeof g_py.origin, "GEARPAIR_PYTHON=%s", over);
    } else {
        char rec[4200];
        snprintf(rec, sizeof rec, "%s/python.txt", folder);
        if (read_text(rec, text, sizeof text)) {
            snprintf(err, n, "this FMU records no Python (%s is missing). %s", rec, FIX);
            return -1;
        }
        snprintf(g_py.origin, sizeof g_py.origin, "the Python that built this FMU, recorded "
                 "in its resources");
    }
    parse_choice(text, &g_py);
    return 0;
}

/* The embedded interpreter: started here, once per process, and never finalized.
 *
 * pythonfmu starts Python itself when the host has not, and finalizes it from a C++ static
 * destructor at process exit. Exit handlers run in the reverse order of registration, and
 * that destructor is registered when pythonfmu's library loads, before the Python extension
 * modules the slave imports register theirs: by the time pythonfmu finalizes, scipy's
 * `_uarray` (imported through scipy.optimize/scipy.linalg) has destroyed its static C++
 * objects, and the interpreter's final garbage collection frees them a second time (heap
 * corruption, SIGSEGV in `Function::clear`). Starting the interpreter here, before
 * pythonfmu looks, makes pythonfmu treat it as the host's: it never finalizes it. The
 * interpreter then ends with the process, as Python's own extension modules expect (their
 * static destructors run after a live or finalized interpreter alike, never before a
 * finalization). Finalizing it earlier (at the last fmi2FreeInstance) is not an option:
 * numpy and scipy cannot be imported again into a second interpreter of the same process.
 * In a Python host the interpreter is the host's and nothing here touches it.
 *
 * The libpython is loaded RTLD_GLOBAL (pythonfmu's library and Python's extension modules
 * resolve the C API from the global scope). Its program name is the recorded executable,
 * so the interpreter finds a venv as that python would (pyvenv.cfg, then site-packages with
 * its .pth files), and its home is the installation's prefix (the standard library),
 * without PYTHONHOME or PYTHONPATH in the host's environment. */
static int ensure_python(const char *folder, char *err, size_t n) {
    int (*is_init)(void) = (int (*)(void))dlsym(RTLD_DEFAULT, "Py_IsInitialized");
    if (is_init && is_init()) return 0; /* a Python host: its interpreter, unchanged */
    if (choose_python(folder, err, n)) {
        if (!is_init) return -1;
        g_py.origin[0] = 0; /* a preloaded libpython, nothing recorded: take it as it is */
    }
    if (!is_init) {
        if (!g_py.libpython[0]) {
            snprintf(err, n, "%s (Python %s, %s) has no shared libpython (built without "
                     "--enable-shared), so it cannot run inside this host. %s", g_py.origin,
                     g_py.version, g_py.executable, FIX);
            return -1;
        }
        void *lib = dlopen(g_py.libpython, RTLD_NOW | RTLD_GLOBAL | RTLD_NODELETE);
        if (!lib) {
            snprintf(err, n, "cannot load the Python library %s of %s (%s): %s. %s",
                     g_py.libpython, g_py.origin, g_py.executable, dlerror(), FIX);
            return -1;
        }
        is_init = (int (*)(void))dlsym(lib, "Py_IsInitialized");
    } else if (g_py.origin[0]) { /* preloaded (LD_PRELOAD): the record applies if it is it */
        Dl_info info;
        char a[PATH_MAX], b[PATH_MAX];
        if (!dladdr((void *)is_init, &info) || !info.dli_fname ||
            !realpath(info.dli_fname, a) || !realpath(g_py.libpython, b) || strcmp(a, b)) {
            snprintf(g_py.origin, sizeof g_py.origin, "the libpython the host preloaded (%s)",
                     info.dli_fname ? info.dli_fname : "?");
            g_py.executable[0] = g_py.home[0] = g_py.sites[0] = 0;
        }
    }
    void (*init_ex)(int) = (void (*)(int))dlsym(RTLD_DEFAULT, "Py_InitializeEx");
    void *(*save_thread)(void) = (void *(*)(void))dlsym(RTLD_DEFAULT, "PyEval_SaveThread");
    wchar_t *(*decode)(const char *, size_t *) =
        (wchar_t * (*)(const char *, size_t *)) dlsym(RTLD_DEFAULT, "Py_DecodeLocale");
    void (*set_name)(const wchar_t *) =
        (void (*)(const wchar_t *))dlsym(RTLD_DEFAULT, "Py_SetProgramName");
    void (*set_home)(const wchar_t *) =
        (void (*)(const wchar_t *))dlsym(RTLD_DEFAULT, "Py_SetPythonHome");
    if (!is_init || !init_ex || !save_thread || !decode) {
        snprintf(err, n, "the Python library of %s lacks Py_InitializeEx/PyEval_SaveThread",
                 g_py.origin[0] ? g_py.origin : "the host");
        return -1;
    }
    if (is_init()) return 0;
    /* Both strings must outlive the interpreter (Py_SetProgramName keeps the pointer).
     * Without a record: a program name that is not on PATH, so the prefix (standard
     * library) comes from the preloaded libpython itself, not from whichever python3 PATH
     * finds first. */
    if (set_name) set_name(decode(g_py.executable[0] ? g_py.executable : "./GearPairFMU", NULL));
    if (set_home && g_py.home[0]) set_home(decode(g_py.home, NULL));
    init_ex(0); /* 0: leave the host's signal handlers alone */
    save_thread(); /* release the GIL: pythonfmu takes it per call, from any thread */
    g_py_started = 1;
    return 0;
}

/* A Python bytes literal of `s` (every byte outside a safe set escaped), for code run in the
 * interpreter: paths may hold quotes, backslashes or any UTF-8. */
static void py_bytes(const char *s, char *out, size_t n) {
    size_t o = 0;
    if (n < 4) return;
    out[o++] = 'b';
    out[o++] = '\'';
    for (; *s && o + 6 < n; s++) {
        unsigned char c = (unsigned char)*s;
        if ((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
            strchr("/._-+:= ,()", c))
            out[o++] = (char)c;
        else
            o += (size_t)snprintf(out + o, n - o, "\\x%02x", c);
    }
    out[o++] = '\'';
    out[o] = 0;
}

/* Before pythonfmu imports the slave: make the recorded package folders importable (only in
 * an interpreter started here) and check that numpy, scipy and pythonfmu import
 * (resources/gearpair_python.py). One message names what is missing, where it looked and
 * the fix; `note` says which Python runs (and whether numba is there). Returns -1 with `err`
 * set when the FMU cannot run. */
static int check_python(const char *folder, char *note, size_t nn, char *err, size_t n) {
    int (*ensure)(void) = (int (*)(void))dlsym(RTLD_DEFAULT, "PyGILState_Ensure");
    void (*release)(int) = (void (*)(int))dlsym(RTLD_DEFAULT, "PyGILState_Release");
    void *(*new_dict)(void) = (void *(*)(void))dlsym(RTLD_DEFAULT, "PyDict_New");
    void *(*run)(const char *, int, void *, void *, void *) =
        (void *(*)(const char *, int, void *, void *, void *))dlsym(RTLD_DEFAULT,
                                                                  "PyRun_StringFlags");
    void *(*item)(void *, const char *) =
        (void *(*)(void *, const char *))dlsym(RTLD_DEFAULT, "PyDict_GetItemString");
    const char *(*utf8)(void *) = (const char *(*)(void *))dlsym(RTLD_DEFAULT,
                                                                 "PyUnicode_AsUTF8");
    void (*decref)(void *) = (void (*)(void *))dlsym(RTLD_DEFAULT, "Py_DecRef");
    void (*clear)(void) = (void (*)(void))dlsym(RTLD_DEFAULT, "PyErr_Clear");
    if (!ensure || !release || !new_dict || !run || !item || !utf8 || !decref || !clear)
        return 0; /* not a CPython we know: let pythonfmu try */
    char script[4200];
    snprintf(script, sizeof script, "%s/gearpair_python.py", folder);
    if (access(script, R_OK)) return 0; /* an FMU built without it: nothing to check */
    static char code[64 * PY_FIELD];
    static char lit_script[4 * 4200 + 8], lit_sites[4 * sizeof g_py.sites + 8];
    static char lit_origin[4 * sizeof g_py.origin + 8];
    py_bytes(script, lit_script, sizeof lit_script);
    py_bytes(g_py_started ? g_py.sites : "", lit_sites, sizeof lit_sites);
    py_bytes(g_py_started ? (g_py.origin[0] ? g_py.origin : "the libpython the host preloaded")
             : getenv("GEARPAIR_PYTHON") ? "the host's own Python; GEARPAIR_PYTHON is not "
                                           "used in a Python host"
                                         : "the host's own Python",
             lit_origin, sizeof lit_origin);
    snprintf(code, sizeof code,
             "def _gp_check():\n"
             "    import sys, importlib.util\n"
             "    d = lambda b: b.decode('utf-8', 'surrogateescape')\n"
             "    m = sys.modules.get('_gearpair_python')\n"
             "    if m is None:\n"
             "        spec = importlib.util.spec_from_file_location('_gearpair_python', "
             "d(%s))\n"
             "        m = importlib.util.module_from_spec(spec)\n"
             "        spec.loader.exec_module(m)\n"
             "        sys.modules['_gearpair_python'] = m\n"
             "    return m.prepare(d(%s).split('\\n'), %d, d(%s))\n"
             "try:\n"
             "    error, note = _gp_check()\n"
             "except BaseException as e:\n"
             "    error, note = 'checking the Python failed: %%s: %%s' %% (type(e).__name__, "
             "e), ''\n",
             lit_script, lit_sites, g_py_started, lit_origin);
    int gil = ensure();
    int bad = 0;
    void *g = new_dict();
    void *r = g ? run(code, 257 /* Py_file_input */, g, g, NULL) : NULL;
    if (!r) {
        clear();
        snprintf(err, n, "the FMU could not check its Python (%s)", script);
        bad = -1;
    } else {
        decref(r);
        void *e = item(g, "error"), *t = item(g, "note");
        const char *es = e ? utf8(e) : NULL, *ts = t ? utf8(t) : NULL;
        if (!es || !ts) clear();
        if (es && es[0]) {
            snprintf(err, n, "%s", es);
            bad = -1;
        }
        snprintf(note, nn, "%s", ts ? ts : "");
    }
    if (g) decref(g);
    release(gil);
    return bad;
}

static int load_inner(const char *folder, char *note, size_t nn, char *err, size_t n) {
    if (!g_loaded && ensure_python(folder, err, n)) return -1;
    if (check_python(folder, note, nn, err, n)) return -1;
    if (g_loaded) return 0;
    Dl_info info;
    if (!dladdr((void *)&load_inner, &info) || !info.dli_fname) {
        snprintf(err, n, "cannot locate the FMU's binary folder (dladdr failed)");
        return -1;
    }
    char path[4096];
    const char *slash = strrchr(info.dli_fname, '/');
    int dirlen = slash ? (int)(slash - info.dli_fname) : 1;
    snprintf(path, sizeof path, "%.*s/%s", dirlen, slash ? info.dli_fname : ".", MODEL_INNER_LIB);
    /* NODELETE: Python holds pointers into it (the slave's logger) until the process ends */
    void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL | RTLD_NODELETE);
    if (!lib) {
        snprintf(err, n, "cannot load %s: %s", path, dlerror());
        return -1;
    }
    err[0] = 0;
    inner.instantiate = (fmi2InstantiateTYPE *)load_sym(lib, "fmi2Instantiate", err, n);
    inner.free_instance = (fmi2FreeInstanceTYPE *)load_sym(lib, "fmi2FreeInstance", err, n);
    inner.setup = (fmi2SetupExperimentTYPE *)load_sym(lib, "fmi2SetupExperiment", err, n);
    inner.enter = (fmi2ComponentCallTYPE *)load_sym(lib, "fmi2EnterInitializationMode", err, n);
    inner.exit_init = (fmi2ComponentCallTYPE *)load_sym(lib, "fmi2ExitInitializationMode", err, n);
    inner.get_real = (fmi2GetRealTYPE *)load_sym(lib, "fmi2GetReal", err, n);
    inner.get_int = (fmi2GetIntegerTYPE *)load_sym(lib, "fmi2GetInteger", err, n);
    inner.set_real = (fmi2SetRealTYPE *)load_sym(lib, "fmi2SetReal", err, n);
    inner.set_int = (fmi2SetIntegerTYPE *)load_sym(lib, "fmi2SetInteger", err, n);
    inner.set_bool = (fmi2SetBooleanTYPE *)load_sym(lib, "fmi2SetBoolean", err, n);
    inner.get_state = (fmi2GetFMUstateTYPE *)load_sym(lib, "fmi2GetFMUstate", err, n);
    inner.set_state = (fmi2SetFMUstateTYPE *)load_sym(lib, "fmi2SetFMUstate", err, n);
    inner.free_state = (fmi2FreeFMUstateTYPE *)load_sym(lib, "fmi2FreeFMUstate", err, n);
    inner.state_size =
        (fmi2SerializedFMUstateSizeTYPE *)load_sym(lib, "fmi2SerializedFMUstateSize", err, n);
    inner.serialize = (fmi2SerializeFMUstateTYPE *)load_sym(lib, "fmi2SerializeFMUstate", err, n);
    inner.deserialize =
        (fmi2DeSerializeFMUstateTYPE *)load_sym(lib, "fmi2DeSerializeFMUstate", err, n);
    inner.do_step = (fmi2DoStepTYPE *)load_sym(lib, "fmi2DoStep", err, n);
    if (err[0]) return -1;
    inner.release_guard = (void (*)(void))dlsym(lib, "finalizePythonInterpreter");
    g_py_is_init = (int (*)(void))dlsym(RTLD_DEFAULT, "Py_IsInitialized");
    g_py_finalizing = (int (*)(void))dlsym(RTLD_DEFAULT, "Py_IsFinalizing"); /* 3.13 */
    if (!g_py_finalizing)
        g_py_finalizing = (int (*)(void))dlsym(RTLD_DEFAULT, "_Py_IsFinalizing");
    g_loaded = 1;
    return 0;
}

/* -- after the host's interpreter ------------------------------------------------------------
 * A Python host may end with an instance alive: OMSimulator's Python API destroys its models
 * from a static destructor after Python has finalized, and pythonfmu would then take the GIL
 * of a finalized interpreter (SIGSEGV). Every call checks first and is answered here. */
static int py_gone(void) {
    return g_loaded && ((g_py_is_init && !g_py_is_init()) ||
                        (g_py_finalizing && g_py_finalizing()));
}

/* Whether the host's logger can be called after its interpreter finalized: not if it is
 * Python's (a ctypes callback: anonymous memory or libffi) or lies in a Python package
 * (fmpy's logging.so forwards to a Python function); a C/C++ host's logger (OMSimulator's)
 * lies in one of the host's own files. An interpreter started here never ends. */
static int logger_is_native(const Instance *s) {
    static const char *const python_places[] = {"site-packages", "dist-packages",
                                                "lib-dynload", "libffi", "_ctypes",
                                                "libpython"};
    Dl_info info;
    if (g_py_started) return 1;
    if (!s->host.logger || !dladdr((void *)s->host.logger, &info) || !info.dli_fname)
        return 0;
    for (size_t i = 0; i < sizeof python_places / sizeof *python_places; i++)
        if (strstr(info.dli_fname, python_places[i])) return 0;
    return 1;
}

int py_slave_gone(PySlave *p, const char *fn) {
    static const char msg[] = "the host's Python interpreter has finalized (the process is "
                              "ending): the FMU cannot run any more; only fmi2Terminate and "
                              "fmi2FreeInstance are answered (by its C layer)";
    if (!py_gone()) return 0;
    if (!p->late_said && strcmp(fn, "fmi2Terminate")) {
        p->late_said = 1;
        if (logger_is_native(p->inst))
            fmu_log(p->inst, fmi2Error, "%s: %s", fn, msg);
        else
            fprintf(stderr, "GearPair FMU instance %s: %s: %s\n", p->inst->name, fn, msg);
    }
    return 1;
}

/* -- the slave ----------------------------------------------------------------------------- */
static void begin(PySlave *p) { p->worst = fmi2OK; }

/* Status of a forwarded call: fmi2Error when the slave logged an error during it (the
 * slave's way to refuse without an exception). */
static fmi2Status settle(PySlave *p, fmi2Status st) {
    if (p->worst > st) st = p->worst;
    return st == fmi2Fatal ? fmi2Error : st;
}

/* Deliver what the slave queued outside a call (its constructor's messages): pythonfmu
 * passes queued messages on at the end of each call, and its destructor crashes (SIGSEGV in
 * clearLogBuffer) when it finds any left at fmi2FreeInstance. A fmi2GetReal of no variables
 * is a call that does nothing else. */
static void flush_log(PySlave *p) {
    fmi2ValueReference none = 0;
    fmi2Real unused = 0.0;
    begin(p);
    settle(p, inner.get_real(p->c, &none, 0, &unused));
}

PySlave *py_slave_new(Instance *inst, const char *why) {
    char err[8192] = "", note[2048] = "", uri[4096 + 8];
    PySlave *p = calloc(1, sizeof *p);
    if (!p) return NULL;
    p->inst = inst;
    /* pythonfmu gets the folder as file:// + an absolute path, the one form it reads */
    snprintf(uri, sizeof uri, "file://%s", inst->resources);
    pthread_mutex_lock(&g_lock);
    int bad = load_inner(inst->resources, note, sizeof note, err, sizeof err);
    if (!bad) {
        p->mine = inst->host;
        p->mine.logger = inner_logger;
        p->mine.componentEnvironment = p;
        if (!p->mine.allocateMemory || !p->mine.freeMemory) {
            p->mine.allocateMemory = calloc;
            p->mine.freeMemory = free;
        }
        p->c = inner.instantiate(inst->name, fmi2CoSimulation, MODEL_GUID, uri, &p->mine,
                                 fmi2False, fmi2True);
        /* pythonfmu keeps its interpreter guard in a static shared_ptr and releases it twice
         * at exit (a C++ static destructor, then an ELF destructor that reads the freed
         * block). Emptying the static now makes both no-ops; the instance holds its own
         * reference, and the guard owns nothing since the interpreter is not pythonfmu's. */
        if (p->c && inner.release_guard) inner.release_guard();
    }
    pthread_mutex_unlock(&g_lock);
    if (bad || !p->c) {
        if (bad) fmu_log(inst, fmi2Error, "%s: %s", why, err);
        free(p);
        return NULL;
    }
    if (note[0]) fmu_log(inst, fmi2OK, "GearPair FMU %s", note); /* which Python */
    flush_log(p);
    return p;
}

void py_slave_free(PySlave *p) {
    if (!p) return;
    int gone = py_gone(); /* the process is ending: the slave's memory goes with it */
    if (!gone) flush_log(p);
    pthread_mutex_lock(&g_lock);
    if (!gone) inner.free_instance(p->c);
    pthread_mutex_unlock(&g_lock);
    free(p);
}

/* The values of one causality ('p' parameters, 'i' inputs) to the slave, by type. */
static fmi2Status put_values(PySlave *p, const double *v, char causality) {
    fmi2Status st = fmi2OK, r;
    for (int i = 0; i < MODEL_NVARS && st <= fmi2Warning; i++) {
        const FmuVar *var = &MODEL_VARS[i];
        if (var->causality != causality) continue;
        if (var->type == 'R') {
            r = inner.set_real(p->c, &var->vr, 1, &v[i]);
        } else if (var->type == 'I') {
            fmi2Integer x = (fmi2Integer)v[i];
            r = inner.set_int(p->c, &var->vr, 1, &x);
        } else {
            fmi2Boolean x = v[i] != 0.0;
            r = inner.set_bool(p->c, &var->vr, 1, &x);
        }
        st = settle(p, r);
    }
    return st;
}

static fmi2Status take_outputs(PySlave *p, double *v) {
    fmi2Status st = fmi2OK;
    for (int i = 0; i < MODEL_NVARS && st <= fmi2Warning; i++) {
        const FmuVar *var = &MODEL_VARS[i];
        if (var->causality != 'o') continue;
        if (var->type == 'R') {
            st = settle(p, inner.get_real(p->c, &var->vr, 1, &v[i]));
        } else {
            fmi2Integer x = 0;
            st = settle(p, inner.get_int(p->c, &var->vr, 1, &x));
            v[i] = x;
        }
    }
    return st;
}

fmi2Status py_slave_init(PySlave *p, double *v, double t0) {
    begin(p);
    fmi2Status st = put_values(p, v, 'p');
    if (st <= fmi2Warning) st = put_values(p, v, 'i');
    if (st <= fmi2Warning) st = settle(p, inner.setup(p->c, fmi2False, 0.0, t0, fmi2False, 0.0));
    if (st <= fmi2Warning) st = settle(p, inner.enter(p->c));
    if (st <= fmi2Warning) st = settle(p, inner.exit_init(p->c));
    if (st <= fmi2Warning) st = take_outputs(p, v);
    return st;
}

fmi2Status py_slave_step(PySlave *p, double *v, double t, double h) {
    begin(p);
    fmi2Status st = put_values(p, v, 'i');
    if (st <= fmi2Warning) st = settle(p, inner.do_step(p->c, t, h, fmi2True));
    if (st <= fmi2Warning) {
        fmi2Status out = take_outputs(p, v);
        if (out > st) st = out;
    }
    return st;
}

/* The slave's state serialized: get, size, serialize, free. */
static fmi2Status serialized(PySlave *p, unsigned char *out, size_t *n) {
    fmi2FMUstate s = NULL;
    size_t size = 0;
    begin(p);
    fmi2Status st = settle(p, inner.get_state(p->c, &s));
    if (st <= fmi2Warning) st = settle(p, inner.state_size(p->c, s, &size));
    if (st <= fmi2Warning && out) {
        if (size != *n) st = fmi2Error;
        else st = settle(p, inner.serialize(p->c, s, (fmi2Byte *)out, size));
    }
    if (s) inner.free_state(p->c, &s);
    *n = size;
    return st;
}

fmi2Status py_slave_state_size(PySlave *p, size_t *n) { return serialized(p, NULL, n); }

fmi2Status py_slave_state_save(PySlave *p, unsigned char *out, size_t n) {
    return serialized(p, out, &n);
}

fmi2Status py_slave_state_load(PySlave *p, const unsigned char *in, size_t n) {
    fmi2FMUstate s = NULL;
    begin(p);
    fmi2Status st = settle(p, inner.deserialize(p->c, (const fmi2Byte *)in, n, &s));
    if (st <= fmi2Warning) st = settle(p, inner.set_state(p->c, s));
    if (s) inner.free_state(p->c, &s);
    return st;
}
