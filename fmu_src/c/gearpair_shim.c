/* GearPair FMU binary: a thin FMI 2.0 co-simulation layer over pythonfmu's library.
 *
 * The FMU's `binaries/linux64/GearPair.so` is this file, compiled by build_fmu.py with the
 * variable table it generates from the final modelDescription.xml (gearpair_vars.h).
 * pythonfmu's own library ships beside it under another name (GP_INNER_LIB) and runs the
 * Python slave; every fmi2 call is forwarded to it, with what pythonfmu 0.7 leaves out:
 *
 * - the FMI 2.0 co-simulation state machine per instance: a call not allowed in the
 *   instance's current mode returns fmi2Error with a log message and changes nothing;
 * - fmi2Set* checks against the variable table: unknown value references, outputs, fixed
 *   parameters after initialization, non-finite or out-of-range values and integer codes
 *   outside their choices are refused with fmi2Error, the old value kept (nothing is
 *   forwarded);
 * - the slave cannot return fmi2Error itself (pythonfmu turns a Python exception into
 *   fmi2Fatal), so it logs a refusal with status error and returns normally; a call during
 *   which the slave logged an error returns fmi2Error here;
 * - log messages of status warning and worse always reach the host's logger; only messages
 *   of status OK (information, debug) follow loggingOn and fmi2SetDebugLogging. pythonfmu is
 *   instantiated with loggingOn true and this layer's logger;
 * - serialized FMU states carry a trailer (format tag, mode, length, CRC-32), so a truncated
 *   or altered state is refused with fmi2Error before the slave sees it; FMU state pointers
 *   are checked against the instance's live states;
 * - the embedded interpreter's lifetime (see `ensure_python`): exit and dlclose are safe;
 * - the native step (see `Native`): after initialization and a first step the per-step
 *   calls (fmi2SetReal of inputs, fmi2DoStep, fmi2Get* of inputs and outputs) run the
 *   slave's compiled engine here, without Python, from any thread;
 * - which Python: in a host without one, the interpreter recorded in resources/python.txt
 *   or named by GEARPAIR_PYTHON is loaded (`ensure_python`), and the packages the slave
 *   needs are checked before pythonfmu imports it (`check_python`): one message, no
 *   traceback; the resource location is read in every local file: form (`resource_folder`);
 * - a value refused before initialization ended is remembered until a valid one is set:
 *   fmi2ExitInitializationMode refuses naming it (`refuse`, `taken`);
 * - calls after the host's interpreter finalized are answered here (`py_gone`).
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <math.h>
#include <pthread.h>
#include <spawn.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/wait.h>
#include <unistd.h>
#include <wchar.h>

#include "fmi2_abi.h"

#define EXPORT __attribute__((visibility("default")))

/* One FMU variable, from modelDescription.xml (generated: gearpair_vars.h). */
typedef struct {
    unsigned vr;
    char type;      /* 'R' Real, 'I' Integer, 'B' Boolean */
    char causality; /* 'p' parameter, 'i' input, 'o' output */
    char tunable;   /* settable after initialization (inputs, tunable parameters) */
    char has_lo, has_hi, lo_open;
    double lo, hi;
    const char *name;
    const char *unit; /* "" when none */
    const char *codes; /* integer codes with their names, or NULL */
} GpVar;

#include "gearpair_vars.h" /* GP_GUID, GP_INNER_LIB, GP_VARS[], GP_NVARS, GP_NATIVE */

/* Modes of an instance (FMI 2.0, section 4.2.4; the slave is synchronous, so there is no
 * stepInProgress, and a failed step leaves the state of its start: see fmi2DoStep). */
typedef enum { M_INSTANTIATED, M_INIT, M_STEP, M_TERMINATED, M_FATAL } Mode;
static const char *const MODE_NAME[] = {"instantiated", "initialization mode",
                                        "step mode (initialized)", "terminated",
                                        "fatal error"};
#define IN(m, set) (((set) >> (m)) & 1u)
#define B(m) (1u << (m))
#define ANY_LIVE (B(M_INSTANTIATED) | B(M_INIT) | B(M_STEP) | B(M_TERMINATED))

/* -- pythonfmu's library ---------------------------------------------------------------- */
static struct {
    fmi2InstantiateTYPE *instantiate;
    fmi2FreeInstanceTYPE *free_instance;
    fmi2SetupExperimentTYPE *setup;
    fmi2ComponentCallTYPE *enter, *exit_init, *terminate, *reset;
    fmi2GetRealTYPE *get_real;
    fmi2GetIntegerTYPE *get_int;
    fmi2GetBooleanTYPE *get_bool;
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

/* A state handed to the host: the slave's state and this layer's mode, in a list per
 * instance so that a pointer the instance did not hand out is refused, not dereferenced. */
typedef struct State {
    uint32_t magic;
    Mode mode;
    fmi2FMUstate inner;
    struct State *next;
} State;
#define STATE_MAGIC 0x47505354u

/* The native step (issue 25): the slave's step block (its inputs and the step record, the
 * outputs) and the fast engine's compiled step, handed over by the slave after
 * initialization and after every call that went through Python (`native_fetch`). While
 * `step` is set, fmi2SetReal of inputs, fmi2DoStep and fmi2Get* of inputs and outputs run
 * here without Python (no GIL, nothing shared between instances); anything else, and a step
 * the compiled one refuses or fails (after rolling it back), goes through the slave, which
 * takes the same step with the same compiled code and says why. The block and the engine
 * belong to the slave and live until fmi2Reset or fmi2FreeInstance. */
typedef struct {
    double *x;                          /* the step block (NULL: everything through Python) */
    int64_t (*step)(int64_t table);     /* the compiled step (NULL: doStep through Python) */
    int64_t table;                      /* its hand-off table */
    signed char slot[GP_NVARS];         /* block slot of each GP_VARS entry, -1: none */
    int have_slots;
} Native;

/* Slots of the step block (model/gearpair/stepblock.py) that this layer writes. */
enum { X_TEND, X_TCHK, X_H, X_TORQUE, X_SPEED, X_LOAD, X_LOADON, X_FMU, X_BAD };
/* The slave's answers to fmi2GetInteger of these value references (none of them is in the
 * modelDescription): NATIVE_VR + 0..5 the block, step and table addresses (low and high 32
 * bits); NATIVE_SLOT_VR + vr the block slot of variable vr (GearPair.py, `native_handoff`). */
#define NATIVE_VR 0x47500000u
#define NATIVE_SLOT_VR 0x47510000u
#define NATIVE_MAX 64 /* values per fmi2Get/Set call served from the block */

typedef struct {
    fmi2Component inner;
    fmi2CallbackFunctions host;
    fmi2CallbackFunctions mine; /* given to pythonfmu: our logger, the host's memory */
    char *name;
    Mode mode;
    int logging_on;
    char **categories; /* debug categories enabled (NULL: all) */
    size_t n_categories;
    fmi2Status worst; /* worst status the slave logged during the current call */
    double last_successful_time;
    State *states;
    /* values refused (or not taken with a refused one) before initialization ended, by
     * GP_VARS index: fmi2ExitInitializationMode refuses while any is left (masters that
     * ignore fmi2SetReal's status would otherwise run with a value the user did not get) */
    struct {
        char what; /* 0 none, 'r' refused, 'n' not taken: the same call had a refused value */
        char text[40];
        const char *fn;
    } refused[GP_NVARS];
    int n_refused;
    int late_said; /* the message about a finalized interpreter was given */
    Native nat;
} Shim;

/* -- logging ---------------------------------------------------------------------------- */
static int debug_enabled(const Shim *s, const char *category) {
    if (!s->logging_on) return 0;
    if (!s->categories) return 1;
    for (size_t i = 0; i < s->n_categories; i++)
        if (category && !strcmp(s->categories[i], category)) return 1;
    return 0;
}

static const char *status_category(fmi2Status st);

/* The message goes out as the format argument itself with every '%' doubled: a C host
 * that formats it prints the text, and hosts that take it verbatim (fmpy's ctypes logger)
 * show it as it is (a literal "%" appears doubled there). */
static void emit(Shim *s, fmi2Status status, const char *category, const char *msg) {
    if (!s->host.logger) return;
    if (status == fmi2OK && !debug_enabled(s, category)) return;
    size_t n = strlen(msg), extra = 0;
    for (size_t i = 0; i < n; i++) extra += msg[i] == '%';
    char small[2048], *buf = n + extra < sizeof small ? small : malloc(n + extra + 1);
    if (!buf) return;
    char *o = buf;
    for (size_t i = 0; i < n; i++) {
        *o++ = msg[i];
        if (msg[i] == '%') *o++ = '%';
    }
    *o = 0;
    s->host.logger(s->host.componentEnvironment, s->name, status,
                   category ? category : status_category(status), buf);
    if (buf != small) free(buf);
}

static const char *status_category(fmi2Status st) {
    switch (st) {
    case fmi2Warning: return "logStatusWarning";
    case fmi2Discard: return "logStatusDiscard";
    case fmi2Error: return "logStatusError";
    case fmi2Fatal: return "logStatusFatal";
    default: return "logAll";
    }
}

static void say(Shim *s, fmi2Status status, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
static void say(Shim *s, fmi2Status status, const char *fmt, ...) {
    char buf[8192];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    emit(s, status, status_category(status), buf);
}

/* pythonfmu's logger callback: remember the worst status, pass the message on (pythonfmu
 * hands over a printf format, as FMI 2.0 allows). */
static void inner_logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                         fmi2String category, fmi2String message, ...) {
    (void)instance;
    Shim *s = (Shim *)env;
    if (!s || !message) return;
    if (status > s->worst) s->worst = status;
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
    emit(s, status, category, buf);
    if (buf != small) free(buf);
}

/* -- loading pythonfmu and the interpreter ------------------------------------------------ */
static void *load_sym(void *lib, const char *name, char *err, size_t n) {
    void *f = dlsym(lib, name);
    if (!f && !err[0]) snprintf(err, n, "%s has no function %s", GP_INNER_LIB, name);
    return f;
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
 * In a Python host the interpreter is the host's and nothing here touches it. */
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
    "Fix: set GEARPAIR_PYTHON to the python executable of an environment with numpy, scipy, "
    "numba and pythonfmu whose Python has a shared libpython (a venv of such a Python "
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
    snprintf(path, sizeof path, "%.*s/%s", dirlen, slash ? info.dli_fname : ".", GP_INNER_LIB);
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
    inner.terminate = (fmi2ComponentCallTYPE *)load_sym(lib, "fmi2Terminate", err, n);
    inner.reset = (fmi2ComponentCallTYPE *)load_sym(lib, "fmi2Reset", err, n);
    inner.get_real = (fmi2GetRealTYPE *)load_sym(lib, "fmi2GetReal", err, n);
    inner.get_int = (fmi2GetIntegerTYPE *)load_sym(lib, "fmi2GetInteger", err, n);
    inner.get_bool = (fmi2GetBooleanTYPE *)load_sym(lib, "fmi2GetBoolean", err, n);
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
static int logger_is_native(const Shim *s) {
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

/* Once per instance: through the host's logger when that is safe, else on stderr. */
static void late_call(Shim *s, const char *fn) {
    static const char msg[] = "the host's Python interpreter has finalized (the process is "
                              "ending): the FMU cannot run any more; only fmi2Terminate and "
                              "fmi2FreeInstance are answered (by its C layer)";
    if (s->late_said) return;
    s->late_said = 1;
    if (logger_is_native(s))
        say(s, fmi2Error, "%s: %s", fn, msg);
    else
        fprintf(stderr, "GearPair FMU instance %s: %s: %s\n", s->name, fn, msg);
}

/* -- helpers ----------------------------------------------------------------------------- */
static Shim *live(fmi2Component c) { return (Shim *)c; }

/* Refuse a call not allowed in the instance's mode. */
static int allowed(Shim *s, unsigned modes, const char *fn) {
    if (py_gone()) {
        late_call(s, fn);
        return 0;
    }
    if (IN(s->mode, modes)) return 1;
    say(s, fmi2Error, "%s is not allowed in %s%s", fn, MODE_NAME[s->mode],
        s->mode == M_INIT && !strcmp(fn, "fmi2DoStep")
            ? ": call fmi2ExitInitializationMode first"
            : s->mode == M_INSTANTIATED && !strcmp(fn, "fmi2DoStep")
                  ? ": call fmi2EnterInitializationMode and fmi2ExitInitializationMode first"
                  : "");
    return 0;
}

/* Status of a forwarded call: fmi2Error when the slave logged an error during it (the
 * slave's way to refuse without an exception), fmi2Fatal makes the instance unusable. */
static fmi2Status settle(Shim *s, fmi2Status st) {
    if (st == fmi2Fatal || s->worst == fmi2Fatal) {
        s->mode = M_FATAL;
        return fmi2Fatal;
    }
    if (s->worst >= fmi2Error && st < fmi2Error) st = fmi2Error;
    return st;
}

static void begin(Shim *s) { s->worst = fmi2OK; }

static const GpVar *find_var(unsigned vr, char type) {
    /* value references are the variables' indices (pythonfmu numbers them in order) */
    if (vr < GP_NVARS && GP_VARS[vr].vr == vr) return GP_VARS[vr].type == type ? &GP_VARS[vr]
                                                                                : NULL;
    for (int i = 0; i < GP_NVARS; i++)
        if (GP_VARS[i].vr == vr && GP_VARS[i].type == type) return &GP_VARS[i];
    return NULL;
}

static const char *type_name(char t) {
    return t == 'R' ? "Real" : t == 'I' ? "Integer" : "Boolean";
}

static int check_refs(Shim *s, const char *fn, const fmi2ValueReference vr[], size_t nvr,
                      const void *values, char type) {
    if (nvr == 0) return 1;
    if (!vr || !values) {
        say(s, fmi2Error, "%s: null value reference or value array for %zu values", fn, nvr);
        return 0;
    }
    for (size_t i = 0; i < nvr; i++)
        if (!find_var(vr[i], type)) {
            say(s, fmi2Error, "%s: value reference %u is not a %s variable of this FMU", fn,
                vr[i], type_name(type));
            return 0;
        }
    return 1;
}

static void range_text(const GpVar *v, char *buf, size_t n) {
    const char *u = v->unit[0] ? " " : "";
    if (v->codes)
        snprintf(buf, n, "allowed %s", v->codes);
    else if (v->has_lo && v->has_hi)
        snprintf(buf, n, "allowed %c%.10g, %.10g]%s%s", v->lo_open ? '(' : '[', v->lo, v->hi,
                 u, v->unit);
    else if (v->has_lo)
        snprintf(buf, n, "allowed %s %.10g%s%s", v->lo_open ? ">" : ">=", v->lo, u, v->unit);
    else if (v->has_hi)
        snprintf(buf, n, "allowed <= %.10g%s%s", v->hi, u, v->unit);
    else
        snprintf(buf, n, "allowed any finite value");
}

/* Whether this instance may set variable v now; logs why not. */
static int settable(Shim *s, const char *fn, const GpVar *v) {
    if (v->causality == 'o') {
        say(s, fmi2Error, "%s: %s is an output and cannot be set", fn, v->name);
        return 0;
    }
    if (s->mode == M_STEP && !v->tunable) {
        say(s, fmi2Error, "%s: parameter %s is fixed (variability fixed): it can be set only "
            "before fmi2ExitInitializationMode; it keeps its value (reset the FMU to change "
            "it)", fn, v->name);
        return 0;
    }
    return 1;
}

static int real_ok(Shim *s, const char *fn, const GpVar *v, double x) {
    int ok = isfinite(x) && !(v->has_lo && (v->lo_open ? x <= v->lo : x < v->lo)) &&
             !(v->has_hi && x > v->hi);
    if (!ok) {
        char r[256];
        range_text(v, r, sizeof r);
        say(s, fmi2Error, "%s: %s = %.10g%s%s is %s; %s. The value is not taken: %s keeps its "
            "value", fn, v->name, x, v->unit[0] ? " " : "", v->unit,
            isfinite(x) ? "out of range" : "not finite", r, v->name);
    }
    return ok;
}

static int int_ok(Shim *s, const char *fn, const GpVar *v, int x) {
    int ok = !(v->has_lo && (v->lo_open ? x <= v->lo : x < v->lo)) &&
             !(v->has_hi && x > v->hi);
    if (!ok) {
        char r[256];
        range_text(v, r, sizeof r);
        say(s, fmi2Error, "%s: %s = %d is out of range; %s. The value is not taken: %s keeps "
            "its value", fn, v->name, x, r, v->name);
    }
    return ok;
}

/* -- values refused before initialization ended ---------------------------------------------- */
/* Remember a refused fmi2Set* call (before or in initialization mode): the value at `bad`
 * was refused, the others of the call were not taken either. Returns fmi2Error. */
static fmi2Status refuse(Shim *s, const char *fn, const fmi2ValueReference vr[], size_t nvr,
                         size_t bad, char type, const void *values) {
    if (s->mode != M_INSTANTIATED && s->mode != M_INIT) return fmi2Error;
    for (size_t i = 0; i < nvr; i++) {
        const GpVar *v = find_var(vr[i], type);
        if (!v || v->causality == 'o') continue;
        int k = (int)(v - GP_VARS);
        if (!s->refused[k].what) s->n_refused++;
        s->refused[k].what = i == bad ? 'r' : 'n';
        s->refused[k].fn = fn;
        if (type == 'R')
            snprintf(s->refused[k].text, sizeof s->refused[k].text, "%.10g",
                     ((const fmi2Real *)values)[i]);
        else if (type == 'I')
            snprintf(s->refused[k].text, sizeof s->refused[k].text, "%d",
                     ((const fmi2Integer *)values)[i]);
        else
            snprintf(s->refused[k].text, sizeof s->refused[k].text, "%s",
                     ((const fmi2Boolean *)values)[i] ? "true" : "false");
    }
    return fmi2Error;
}

/* A set that went through: its variables hold values the user asked for again. */
static fmi2Status taken(Shim *s, const fmi2ValueReference vr[], size_t nvr, char type,
                        fmi2Status st) {
    if (!s->n_refused || st > fmi2Warning) return st;
    for (size_t i = 0; i < nvr; i++) {
        const GpVar *v = find_var(vr[i], type);
        if (v && s->refused[v - GP_VARS].what) {
            s->refused[v - GP_VARS].what = 0;
            s->n_refused--;
        }
    }
    return st;
}

static fmi2Status refused_report(Shim *s) {
    char list[4096];
    size_t o = 0;
    list[0] = 0;
    for (int k = 0; k < GP_NVARS && o < sizeof list; k++) {
        if (!s->refused[k].what) continue;
        o += (size_t)snprintf(list + o, sizeof list - o, "%s%s = %s was %s at %s",
                              o ? ", " : "", GP_VARS[k].name, s->refused[k].text,
                              s->refused[k].what == 'r' ? "refused"
                                                        : "not taken (refused with the call)",
                              s->refused[k].fn);
    }
    say(s, fmi2Error, "fmi2ExitInitializationMode refused: %s; set %s or leave %s unset "
        "(the FMU stays in initialization mode)", list,
        s->n_refused > 1 ? "valid values" : "a valid value", s->n_refused > 1 ? "them" : "it");
    return fmi2Error;
}

/* -- CRC-32 (IEEE 802.3 polynomial, reflected) for serialized states -------------------- */
static uint32_t crc32_of(const unsigned char *p, size_t n, uint32_t crc) {
    crc = ~crc;
    for (size_t i = 0; i < n; i++) {
        crc ^= p[i];
        for (int k = 0; k < 8; k++) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
    }
    return ~crc;
}

/* Trailer appended to the slave's serialized state: tag, mode, payload length, CRC-32 of
 * payload and the preceding trailer fields (little-endian). */
#define TRAILER_TAG "GPFMUST1"
#define TRAILER_SIZE 20

static void put32(unsigned char *p, uint32_t x) {
    for (int i = 0; i < 4; i++) p[i] = (unsigned char)(x >> (8 * i));
}
static uint32_t get32(const unsigned char *p) {
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

/* Deliver what the slave queued outside a call (its constructor's messages, e.g. after
 * fmi2Instantiate or fmi2Reset): pythonfmu passes queued messages on at the end of each call,
 * and its destructor crashes (SIGSEGV in clearLogBuffer) when it finds any left at
 * fmi2FreeInstance. A fmi2GetReal of no variables is a call that does nothing else. */
static void flush_log(Shim *s) {
    fmi2ValueReference none = 0;
    fmi2Real unused = 0.0;
    begin(s);
    settle(s, inner.get_real(s->inner, &none, 0, &unused));
}

static int hexval(char c) {
    return c >= '0' && c <= '9' ? c - '0' : c >= 'a' && c <= 'f' ? c - 'a' + 10
           : c >= 'A' && c <= 'F' ? c - 'A' + 10 : -1;
}

static State *find_state(Shim *s, fmi2FMUstate p, State ***link) {
    State **l = &s->states;
    for (State *st = s->states; st; l = &st->next, st = st->next)
        if ((void *)st == p) {
            if (link) *link = l;
            return st;
        }
    return NULL;
}

static State *new_state(Shim *s, fmi2FMUstate in, Mode mode) {
    State *st = calloc(1, sizeof *st);
    if (!st) return NULL;
    st->magic = STATE_MAGIC;
    st->mode = mode;
    st->inner = in;
    st->next = s->states;
    s->states = st;
    return st;
}

/* The folder a resource location names, as an absolute path (percent-decoded), or -1.
 * Masters write the same folder in several forms: file:///abs (the usual), file:////abs
 * (OMSimulator: "file:///" + an absolute path), file:/abs and file://localhost/abs; a
 * plain absolute path is taken as it is. pythonfmu only strips a leading "file://", so
 * every form but the first reached the slave as a wrong path (//abs, localhost/abs). */
static int resource_folder(const char *uri, char *out, size_t n) {
    if (!uri || !n) return -1;
    const char *p = uri;
    if (!strncasecmp(p, "file:", 5)) {
        p += 5;
        if (p[0] == '/' && p[1] == '/') { /* an authority: empty or localhost */
            const char *auth = p + 2, *end = strchr(auth, '/');
            size_t len = end ? (size_t)(end - auth) : strlen(auth);
            if (len && !(len == 9 && !strncasecmp(auth, "localhost", 9))) return -1;
            p = end ? end : auth + len;
        }
    }
    if (p[0] != '/') return -1;
    while (p[1] == '/') p++; /* //abs names /abs here (POSIX leaves // to the system) */
    size_t o = 0;
    for (; *p; p++) {
        int c = (unsigned char)*p, hi, lo;
        if (c == '%' && (hi = hexval(p[1])) >= 0 && (lo = hexval(p[2])) >= 0) {
            c = hi * 16 + lo;
            p += 2;
        }
        if (o + 1 >= n) return -1;
        out[o++] = (char)c;
    }
    out[o] = 0;
    return 0;
}

/* -- the native step ------------------------------------------------------------------- */

/* Ask the slave for the step block and the compiled step (after a call through Python may
 * have changed either: initialization, a step, a restored state). A slave that answers
 * nothing usable leaves everything to Python. */
static void native_fetch(Shim *s) {
    fmi2ValueReference vr[6];
    fmi2Integer w[6] = {0};
    for (unsigned k = 0; k < 6; k++) vr[k] = NATIVE_VR + k;
    s->nat.x = NULL;
    s->nat.step = NULL;
    if (!GP_NATIVE) return; /* a slave that knows nothing of it (build_fmu.add_c_layer) */
    fmi2Status worst = s->worst;
    if (inner.get_int(s->inner, vr, 6, w) > fmi2Warning) {
        s->worst = worst;
        return;
    }
    uint64_t a[3];
    for (int k = 0; k < 3; k++)
        a[k] = (uint64_t)(uint32_t)w[2 * k] | (uint64_t)(uint32_t)w[2 * k + 1] << 32;
    if (!a[0]) return;
    if (!s->nat.have_slots) {
        fmi2ValueReference q[GP_NVARS];
        fmi2Integer slot[GP_NVARS];
        for (int i = 0; i < GP_NVARS; i++) q[i] = NATIVE_SLOT_VR + GP_VARS[i].vr;
        if (inner.get_int(s->inner, q, GP_NVARS, slot) > fmi2Warning) {
            s->worst = worst;
            return;
        }
        for (int i = 0; i < GP_NVARS; i++)
            s->nat.slot[i] = GP_VARS[i].type != 'B' && slot[i] >= 0 && slot[i] < 127
                                 ? (signed char)slot[i] : -1;
        s->nat.have_slots = 1;
    }
    s->nat.x = (double *)(uintptr_t)a[0];
    s->nat.step = (int64_t(*)(int64_t))(uintptr_t)a[1];
    s->nat.table = (int64_t)a[2];
}

static void native_drop(Shim *s) {
    s->nat.x = NULL;
    s->nat.step = NULL;
}

/* The block slots of value references vr[0..nvr) of this type, or 0 when one is not there
 * (then the call goes to the slave). */
static int native_slots(Shim *s, const fmi2ValueReference vr[], size_t nvr, char type,
                        int slot[]) {
    if (!s->nat.x || nvr > NATIVE_MAX) return 0;
    for (size_t i = 0; i < nvr; i++) {
        const GpVar *v = find_var(vr[i], type);
        if (!v || s->nat.slot[v - GP_VARS] < 0) return 0;
        slot[i] = s->nat.slot[v - GP_VARS];
    }
    return 1;
}

/* ======================================================================================== */
EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }
EXPORT const char *fmi2GetVersion(void) { return "2.0"; }

EXPORT fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid,
                                     fmi2String resources, const fmi2CallbackFunctions *cb,
                                     fmi2Boolean visible, fmi2Boolean logging_on) {
    if (!cb) return NULL;
    Shim *s = calloc(1, sizeof *s);
    if (!s) return NULL;
    s->host = *cb;
    s->name = strdup(name ? name : "");
    s->logging_on = logging_on == fmi2True;
    s->mode = M_INSTANTIATED;
    if (!s->name) goto fail;
    if (type != fmi2CoSimulation) {
        say(s, fmi2Error, "fmi2Instantiate: this FMU supports co-simulation only");
        goto fail;
    }
    if (!guid || strcmp(guid, GP_GUID)) {
        say(s, fmi2Error, "fmi2Instantiate: GUID %s does not match this FMU's %s", guid ? guid
            : "(null)", GP_GUID);
        goto fail;
    }
    /* pythonfmu gets the folder as file:// + an absolute path, the one form it reads */
    char folder[4096], uri[4096 + 8];
    if (resource_folder(resources, folder, sizeof folder)) {
        say(s, fmi2Error, "fmi2Instantiate: the resource location %s is not a local file URI "
            "(file:///path)", resources ? resources : "(null)");
        goto fail;
    }
    snprintf(uri, sizeof uri, "file://%s", folder);
    char err[8192] = "", note[2048] = "";
    pthread_mutex_lock(&g_lock);
    int bad = load_inner(folder, note, sizeof note, err, sizeof err);
    if (!bad) {
        s->mine = *cb;
        s->mine.logger = inner_logger;
        s->mine.componentEnvironment = s;
        if (!s->mine.allocateMemory || !s->mine.freeMemory) {
            s->mine.allocateMemory = calloc;
            s->mine.freeMemory = free;
        }
        s->inner = inner.instantiate(name, type, guid, uri, &s->mine, visible, fmi2True);
        /* pythonfmu keeps its interpreter guard in a static shared_ptr and releases it twice
         * at exit (a C++ static destructor, then an ELF destructor that reads the freed
         * block). Emptying the static now makes both no-ops; the instance holds its own
         * reference, and the guard owns nothing since the interpreter is not pythonfmu's. */
        if (s->inner && inner.release_guard) inner.release_guard();
    }
    pthread_mutex_unlock(&g_lock);
    if (bad) {
        say(s, fmi2Error, "fmi2Instantiate: %s", err);
        goto fail;
    }
    if (!s->inner) goto fail; /* pythonfmu logged why */
    if (note[0]) say(s, fmi2OK, "GearPair FMU %s", note); /* which Python and engine */
    flush_log(s);
    return s;
fail:
    free(s->name);
    free(s);
    return NULL;
}

EXPORT void fmi2FreeInstance(fmi2Component c) {
    Shim *s = live(c);
    if (!s) return;
    int gone = py_gone(); /* the process is ending: the slave's memory goes with it */
    for (State *st = s->states, *nx; st; st = nx) {
        nx = st->next;
        if (!gone) inner.free_state(s->inner, &st->inner);
        st->magic = 0;
        free(st);
    }
    native_drop(s);
    if (s->mode != M_FATAL && !gone) flush_log(s);
    pthread_mutex_lock(&g_lock);
    if (!gone) inner.free_instance(s->inner);
    pthread_mutex_unlock(&g_lock);
    for (size_t i = 0; i < s->n_categories; i++) free(s->categories[i]);
    free(s->categories);
    free(s->name);
    free(s);
}

EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n,
                                      const fmi2String categories[]) {
    Shim *s = live(c);
    if (!s) return fmi2Error;
    if (n && !categories) {
        say(s, fmi2Error, "fmi2SetDebugLogging: %zu categories but a null array", n);
        return fmi2Error;
    }
    char **copy = NULL;
    if (n) {
        copy = calloc(n, sizeof *copy);
        if (!copy) return fmi2Error;
        for (size_t i = 0; i < n; i++) copy[i] = strdup(categories[i] ? categories[i] : "");
    }
    for (size_t i = 0; i < s->n_categories; i++) free(s->categories[i]);
    free(s->categories);
    s->categories = copy;
    s->n_categories = n;
    s->logging_on = on == fmi2True;
    return fmi2OK;
}

EXPORT fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tol_defined, fmi2Real tol,
                                      fmi2Real start, fmi2Boolean stop_defined, fmi2Real stop) {
    Shim *s = live(c);
    if (!s || !allowed(s, B(M_INSTANTIATED), "fmi2SetupExperiment")) return fmi2Error;
    if (!isfinite(start) || (stop_defined && !(stop >= start))) {
        say(s, fmi2Error, "fmi2SetupExperiment: startTime = %.17g s must be finite and "
            "stopTime (%.17g s) not before it", start, stop_defined ? stop : start);
        return fmi2Error;
    }
    begin(s);
    return settle(s, inner.setup(s->inner, tol_defined, tol, start, stop_defined, stop));
}

EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    Shim *s = live(c);
    if (!s || !allowed(s, B(M_INSTANTIATED), "fmi2EnterInitializationMode")) return fmi2Error;
    begin(s);
    fmi2Status st = settle(s, inner.enter(s->inner));
    if (st <= fmi2Warning) s->mode = M_INIT;
    return st;
}

EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Shim *s = live(c);
    if (!s || !allowed(s, B(M_INIT), "fmi2ExitInitializationMode")) return fmi2Error;
    if (s->n_refused) return refused_report(s);
    begin(s);
    fmi2Status st = settle(s, inner.exit_init(s->inner));
    /* refused (e.g. a combination of parameters): the instance stays in initialization
     * mode, so the master may correct a parameter and call this again */
    if (st <= fmi2Warning) {
        s->mode = M_STEP;
        native_fetch(s);
    }
    s->last_successful_time = NAN;
    return st;
}

EXPORT fmi2Status fmi2Terminate(fmi2Component c) {
    Shim *s = live(c);
    if (s && py_gone()) { /* nothing to end: the interpreter and the process are ending */
        s->mode = M_TERMINATED;
        return fmi2OK;
    }
    if (!s || !allowed(s, B(M_STEP), "fmi2Terminate")) return fmi2Error;
    begin(s);
    fmi2Status st = settle(s, inner.terminate(s->inner));
    if (st <= fmi2Warning) s->mode = M_TERMINATED;
    return st;
}

EXPORT fmi2Status fmi2Reset(fmi2Component c) {
    Shim *s = live(c);
    if (!s || !allowed(s, ANY_LIVE, "fmi2Reset")) return fmi2Error;
    native_drop(s); /* the slave's block and engine go with it */
    begin(s);
    fmi2Status st = settle(s, inner.reset(s->inner));
    if (st <= fmi2Warning) {
        s->mode = M_INSTANTIATED;
        memset(s->refused, 0, sizeof s->refused);
        s->n_refused = 0;
        flush_log(s); /* the new slave's constructor messages */
    }
    return st;
}

/* -- get/set ----------------------------------------------------------------------------- */
#define GET_MODES (B(M_INIT) | B(M_STEP) | B(M_TERMINATED))

EXPORT fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                              fmi2Real value[]) {
    Shim *s = live(c);
    if (!s || !allowed(s, GET_MODES, "fmi2GetReal")) return fmi2Error;
    if (!check_refs(s, "fmi2GetReal", vr, nvr, value, 'R')) return fmi2Error;
    if (!nvr) return fmi2OK;
    int slot[NATIVE_MAX];
    if (native_slots(s, vr, nvr, 'R', slot)) {
        for (size_t i = 0; i < nvr; i++) value[i] = s->nat.x[slot[i]];
        return fmi2OK;
    }
    begin(s);
    return settle(s, inner.get_real(s->inner, vr, nvr, value));
}

EXPORT fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                 fmi2Integer value[]) {
    Shim *s = live(c);
    if (!s || !allowed(s, GET_MODES, "fmi2GetInteger")) return fmi2Error;
    if (!check_refs(s, "fmi2GetInteger", vr, nvr, value, 'I')) return fmi2Error;
    if (!nvr) return fmi2OK;
    int slot[NATIVE_MAX];
    if (native_slots(s, vr, nvr, 'I', slot)) {
        for (size_t i = 0; i < nvr; i++) value[i] = (fmi2Integer)s->nat.x[slot[i]];
        return fmi2OK;
    }
    begin(s);
    return settle(s, inner.get_int(s->inner, vr, nvr, value));
}

EXPORT fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                 fmi2Boolean value[]) {
    Shim *s = live(c);
    if (!s || !allowed(s, GET_MODES, "fmi2GetBoolean")) return fmi2Error;
    if (!check_refs(s, "fmi2GetBoolean", vr, nvr, value, 'B')) return fmi2Error;
    if (!nvr) return fmi2OK;
    begin(s);
    return settle(s, inner.get_bool(s->inner, vr, nvr, value));
}

EXPORT fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                fmi2String value[]) {
    Shim *s = live(c);
    (void)vr;
    (void)value;
    if (!s || !allowed(s, GET_MODES, "fmi2GetString")) return fmi2Error;
    if (!nvr) return fmi2OK;
    say(s, fmi2Error, "fmi2GetString: this FMU has no String variables");
    return fmi2Error;
}

#define SET_MODES (B(M_INSTANTIATED) | B(M_INIT) | B(M_STEP))

EXPORT fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                              const fmi2Real value[]) {
    static const char fn[] = "fmi2SetReal";
    Shim *s = live(c);
    if (!s || !allowed(s, SET_MODES, fn)) return fmi2Error;
    if (!check_refs(s, fn, vr, nvr, value, 'R')) return fmi2Error;
    for (size_t i = 0; i < nvr; i++) {
        const GpVar *v = find_var(vr[i], 'R');
        if (!settable(s, fn, v) || !real_ok(s, fn, v, value[i]))
            return refuse(s, fn, vr, nvr, i, 'R', value);
    }
    if (!nvr) return fmi2OK;
    int slot[NATIVE_MAX];
    if (native_slots(s, vr, nvr, 'R', slot)) { /* inputs: the slave reads them there */
        for (size_t i = 0; i < nvr; i++) s->nat.x[slot[i]] = value[i];
        return taken(s, vr, nvr, 'R', fmi2OK);
    }
    begin(s);
    return taken(s, vr, nvr, 'R', settle(s, inner.set_real(s->inner, vr, nvr, value)));
}

EXPORT fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                 const fmi2Integer value[]) {
    static const char fn[] = "fmi2SetInteger";
    Shim *s = live(c);
    if (!s || !allowed(s, SET_MODES, fn)) return fmi2Error;
    if (!check_refs(s, fn, vr, nvr, value, 'I')) return fmi2Error;
    for (size_t i = 0; i < nvr; i++) {
        const GpVar *v = find_var(vr[i], 'I');
        if (!settable(s, fn, v) || !int_ok(s, fn, v, value[i]))
            return refuse(s, fn, vr, nvr, i, 'I', value);
    }
    if (!nvr) return fmi2OK;
    begin(s);
    return taken(s, vr, nvr, 'I', settle(s, inner.set_int(s->inner, vr, nvr, value)));
}

EXPORT fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                 const fmi2Boolean value[]) {
    static const char fn[] = "fmi2SetBoolean";
    Shim *s = live(c);
    if (!s || !allowed(s, SET_MODES, fn)) return fmi2Error;
    if (!check_refs(s, fn, vr, nvr, value, 'B')) return fmi2Error;
    for (size_t i = 0; i < nvr; i++)
        if (!settable(s, fn, find_var(vr[i], 'B'))) return fmi2Error;
    if (!nvr) return fmi2OK;
    fmi2Boolean small[64], *norm = nvr <= 64 ? small : malloc(nvr * sizeof *norm);
    if (!norm) return fmi2Error;
    for (size_t i = 0; i < nvr; i++) norm[i] = value[i] ? fmi2True : fmi2False;
    begin(s);
    fmi2Status st = taken(s, vr, nvr, 'B', settle(s, inner.set_bool(s->inner, vr, nvr, norm)));
    if (norm != small) free(norm);
    return st;
}

EXPORT fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                const fmi2String value[]) {
    Shim *s = live(c);
    (void)vr;
    (void)value;
    if (!s || !allowed(s, SET_MODES, "fmi2SetString")) return fmi2Error;
    if (!nvr) return fmi2OK;
    say(s, fmi2Error, "fmi2SetString: this FMU has no String variables");
    return fmi2Error;
}

/* -- stepping ---------------------------------------------------------------------------- */
EXPORT fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean no_set) {
    Shim *s = live(c);
    if (!s || !allowed(s, B(M_STEP), "fmi2DoStep")) return fmi2Error;
    if (!isfinite(t) || !isfinite(h) || !(h > 0.0)) {
        say(s, fmi2Error, "fmi2DoStep refused: currentCommunicationPoint = %.17g s and "
            "communicationStepSize = %.17g s must be finite and the step size > 0; the FMU "
            "state is unchanged", t, h);
        return fmi2Error;
    }
    if (s->nat.step) {
        double *x = s->nat.x;
        x[X_TCHK] = t;
        x[X_H] = h;
        x[X_TEND] = t + h;
        x[X_FMU] = 1.0;
        if (s->nat.step(s->nat.table) == 0) {
            s->last_successful_time = t + h;
            return fmi2OK;
        }
        /* refused (nothing changed) or failed (rolled back to the step start): the slave
         * takes the step again and says why */
    }
    begin(s);
    fmi2Status st = settle(s, inner.do_step(s->inner, t, h, no_set));
    if (s->mode == M_STEP && (s->nat.x || s->nat.step)) native_fetch(s);
    /* The slave refuses a step (wrong communication point, invalid input: fmi2Error) or
     * fails inside it (fmi2Discard) only after restoring the state of the step start, so
     * the instance stays in step mode either way: the master may repeat the step with
     * other inputs or a smaller size. */
    if (st <= fmi2Warning)
        s->last_successful_time = t + h;
    else if (st == fmi2Discard)
        s->last_successful_time = t;
    return st;
}

EXPORT fmi2Status fmi2CancelStep(fmi2Component c) {
    Shim *s = live(c);
    if (s) say(s, fmi2Error, "fmi2CancelStep: steps are synchronous, there is none to cancel");
    return fmi2Error;
}

#define STATUS_MODES (B(M_STEP) | B(M_TERMINATED))

EXPORT fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind k, fmi2Status *v) {
    Shim *s = live(c);
    (void)k;
    (void)v;
    if (!s || !allowed(s, STATUS_MODES, "fmi2GetStatus")) return fmi2Error;
    return fmi2Discard; /* no asynchronous step: no status to report */
}

EXPORT fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind k, fmi2Real *v) {
    Shim *s = live(c);
    if (!s || !allowed(s, STATUS_MODES, "fmi2GetRealStatus")) return fmi2Error;
    if (k != fmi2LastSuccessfulTime || !v) return fmi2Discard;
    *v = s->last_successful_time;
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind k, fmi2Integer *v) {
    Shim *s = live(c);
    (void)k;
    (void)v;
    if (!s || !allowed(s, STATUS_MODES, "fmi2GetIntegerStatus")) return fmi2Error;
    return fmi2Discard;
}

EXPORT fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind k, fmi2Boolean *v) {
    Shim *s = live(c);
    if (!s || !allowed(s, STATUS_MODES, "fmi2GetBooleanStatus")) return fmi2Error;
    if (k != fmi2Terminated || !v) return fmi2Discard;
    *v = fmi2False; /* the slave never asks to end the simulation */
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind k, fmi2String *v) {
    Shim *s = live(c);
    (void)k;
    (void)v;
    if (!s || !allowed(s, STATUS_MODES, "fmi2GetStringStatus")) return fmi2Error;
    return fmi2Discard;
}

static fmi2Status unsupported(fmi2Component c, const char *fn) {
    Shim *s = live(c);
    if (s) say(s, fmi2Error, "%s is not supported by this FMU", fn);
    return fmi2Error;
}

EXPORT fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[],
                                               size_t nu, const fmi2ValueReference z[],
                                               size_t nz, const fmi2Real dv[], fmi2Real dz[]) {
    (void)u, (void)nu, (void)z, (void)nz, (void)dv, (void)dz;
    return unsupported(c, "fmi2GetDirectionalDerivative (providesDirectionalDerivative is "
                          "false)");
}

EXPORT fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                              size_t nvr, const fmi2Integer order[],
                                              const fmi2Real value[]) {
    (void)vr, (void)nvr, (void)order, (void)value;
    return unsupported(c, "fmi2SetRealInputDerivatives (canInterpolateInputs is false)");
}

EXPORT fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                               size_t nvr, const fmi2Integer order[],
                                               fmi2Real value[]) {
    (void)vr, (void)nvr, (void)order, (void)value;
    return unsupported(c, "fmi2GetRealOutputDerivatives (maxOutputDerivativeOrder is 0)");
}

/* -- FMU state --------------------------------------------------------------------------- */
EXPORT fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state) {
    Shim *s = live(c);
    if (!s || !allowed(s, ANY_LIVE, "fmi2GetFMUstate")) return fmi2Error;
    if (!state) {
        say(s, fmi2Error, "fmi2GetFMUstate: null state pointer");
        return fmi2Error;
    }
    State *own = *state ? find_state(s, *state, NULL) : NULL;
    if (*state && !own) {
        say(s, fmi2Error, "fmi2GetFMUstate: *FMUstate is neither null nor a state of this "
            "instance");
        return fmi2Error;
    }
    fmi2FMUstate in = NULL;
    begin(s);
    fmi2Status st = settle(s, inner.get_state(s->inner, &in));
    if (st > fmi2Warning) return st;
    if (own) { /* overwrite the given state, as the standard allows */
        inner.free_state(s->inner, &own->inner);
        own->inner = in;
        own->mode = s->mode;
        return st;
    }
    State *nw = new_state(s, in, s->mode);
    if (!nw) {
        inner.free_state(s->inner, &in);
        say(s, fmi2Error, "fmi2GetFMUstate: out of memory");
        return fmi2Error;
    }
    *state = nw;
    return st;
}

static State *known_state(Shim *s, fmi2FMUstate p, const char *fn) {
    State *st = p ? find_state(s, p, NULL) : NULL;
    if (!st) say(s, fmi2Error, "%s: not an FMU state of this instance (freed, or from "
                 "elsewhere)", fn);
    return st;
}

EXPORT fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
    Shim *s = live(c);
    if (!s || !allowed(s, ANY_LIVE, "fmi2SetFMUstate")) return fmi2Error;
    State *st = known_state(s, state, "fmi2SetFMUstate");
    if (!st) return fmi2Error;
    begin(s);
    fmi2Status r = settle(s, inner.set_state(s->inner, st->inner));
    if (r <= fmi2Warning) s->mode = st->mode; /* refused: the slave kept its state */
    if (s->mode == M_STEP) /* the engine may be another, or the instance new to stepping */
        native_fetch(s);
    else
        native_drop(s);
    return r;
}

EXPORT fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    Shim *s = live(c);
    if (!s || !allowed(s, ANY_LIVE, "fmi2FreeFMUstate")) return fmi2Error;
    if (!state || !*state) return fmi2OK; /* the standard: a null state is ignored */
    State **link;
    State *st = find_state(s, *state, &link);
    if (!st) {
        say(s, fmi2Error, "fmi2FreeFMUstate: not an FMU state of this instance (freed "
            "already, or from elsewhere)");
        return fmi2Error;
    }
    *link = st->next;
    begin(s);
    fmi2Status r = settle(s, inner.free_state(s->inner, &st->inner));
    st->magic = 0;
    free(st);
    *state = NULL;
    return r;
}

EXPORT fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size) {
    Shim *s = live(c);
    if (!s || !allowed(s, ANY_LIVE, "fmi2SerializedFMUstateSize")) return fmi2Error;
    State *st = known_state(s, state, "fmi2SerializedFMUstateSize");
    if (!st || !size) return fmi2Error;
    size_t n = 0;
    begin(s);
    fmi2Status r = settle(s, inner.state_size(s->inner, st->inner, &n));
    if (r <= fmi2Warning) *size = n + TRAILER_SIZE;
    return r;
}

EXPORT fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte bytes[],
                                        size_t size) {
    Shim *s = live(c);
    if (!s || !allowed(s, ANY_LIVE, "fmi2SerializeFMUstate")) return fmi2Error;
    State *st = known_state(s, state, "fmi2SerializeFMUstate");
    if (!st) return fmi2Error;
    size_t n = 0;
    begin(s);
    fmi2Status r = settle(s, inner.state_size(s->inner, st->inner, &n));
    if (r > fmi2Warning) return r;
    if (!bytes || size != n + TRAILER_SIZE || n > 0xFFFFFFFFu) {
        say(s, fmi2Error, "fmi2SerializeFMUstate: the buffer must have the size "
            "fmi2SerializedFMUstateSize gave (%zu bytes), got %zu", n + TRAILER_SIZE, size);
        return fmi2Error;
    }
    r = settle(s, inner.serialize(s->inner, st->inner, bytes, n));
    if (r > fmi2Warning) return r;
    unsigned char *t = (unsigned char *)bytes + n;
    memcpy(t, TRAILER_TAG, 8);
    put32(t + 8, (uint32_t)st->mode);
    put32(t + 12, (uint32_t)n);
    put32(t + 16, crc32_of((const unsigned char *)bytes, n + 16, 0));
    return r;
}

EXPORT fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size,
                                          fmi2FMUstate *state) {
    Shim *s = live(c);
    if (!s || !allowed(s, ANY_LIVE, "fmi2DeSerializeFMUstate")) return fmi2Error;
    if (!state || (size && !bytes)) {
        say(s, fmi2Error, "fmi2DeSerializeFMUstate: null argument");
        return fmi2Error;
    }
    const unsigned char *b = (const unsigned char *)bytes;
    const unsigned char *t = size >= TRAILER_SIZE ? b + size - TRAILER_SIZE : NULL;
    if (!t || memcmp(t, TRAILER_TAG, 8) || get32(t + 12) != size - TRAILER_SIZE ||
        get32(t + 8) > M_TERMINATED || crc32_of(b, size - 4, 0) != get32(t + 16)) {
        say(s, fmi2Error, "fmi2DeSerializeFMUstate: the %zu bytes are not a complete, "
            "unaltered serialized state of this FMU (format tag, length or checksum wrong); "
            "nothing was restored", size);
        return fmi2Error;
    }
    fmi2FMUstate in = NULL;
    begin(s);
    fmi2Status r = settle(s, inner.deserialize(s->inner, bytes, size - TRAILER_SIZE, &in));
    if (r > fmi2Warning) return r;
    State *nw = new_state(s, in, (Mode)get32(t + 8));
    if (!nw) {
        inner.free_state(s->inner, &in);
        return fmi2Error;
    }
    *state = nw;
    return r;
}
