/* Timing host for `gearpair bench`: GearPair3.fmu's step against GearPair.fmu's, with and
 * without early return, and GearPair.fmu's step in a win64 process (under Wine).
 *
 * It loads the extracted FMUs' binaries side by side (dlopen on Linux, LoadLibrary under
 * _WIN32: the same source builds with gcc and with mingw-w64), makes one instance per
 * variant named on the command line, initializes each at the given start values and times
 * ROUNDS rounds. In round b every variant steps its own instance over the same stretch of
 * model time, the communication points (b N + 1) H ... (b + 1) H N, through the loop a
 * master runs at each point:
 *
 *     set the inputs ; doStep to the point ; get the outputs
 *
 * on the wall clock and on the thread's CPU clock. The variants run back to back within a
 * round, the first one rotating from round to round, so every ratio of two variants
 * compares times taken a fraction of a second apart (a shared machine's speed drifts over
 * seconds). The variants:
 *
 *   fmi2         GearPair.fmu: fmi2SetReal, fmi2DoStep, fmi2GetReal
 *   fmi3         GearPair3.fmu without early return: fmi3SetFloat64, fmi3DoStep,
 *                fmi3GetFloat64
 *   fmi3_events  GearPair3.fmu with early return and Event Mode: a master that handles
 *                each early return. When fmi3DoStep returns early (earlyReturn, and
 *                lastSuccessfulTime before the point) it gets the outputs there, and when
 *                eventHandlingNeeded it calls fmi3EnterEventMode, fmi3UpdateDiscreteStates
 *                and fmi3EnterStepMode, then sets the inputs and steps on from
 *                lastSuccessfulTime to the same communication point
 *   fmi3_early   the same with early return allowed but no Event Mode (the next step
 *                starts at lastSuccessfulTime)
 *
 * and prints one line, flushed before the instances are freed:
 *
 *     RESULT {"ok": 1, "n": N, "h": H, "rounds": ROUNDS, "variants": {"fmi2": {
 *             "wall_s": [...], "cpu_s": [...], "calls": ..., "early": ..., "events": ...,
 *             "digest": "..."}, ...}}
 *
 * per variant the per-round times (s), the doStep calls, early returns and Event Mode
 * entries over all rounds, and a hash of the bits of every output got at a communication
 * point (equal digests: equal outputs at every point).
 *
 * Build (the FMI 2 and FMI 3 headers ship with fmpy, in fmpy/c-code):
 *     gcc -O2 -std=c99 -I"$FMPY/c-code" -o fmi3_bench_host fmi3_bench_host.c -ldl
 *     x86_64-w64-mingw32-gcc -O2 -std=c99 -D__USE_MINGW_ANSI_STDIO=1 -I"$FMPY/c-code" \
 *         -o fmi3_bench_host.exe fmi3_bench_host.c
 * Usage:
 *     fmi3_bench_host VARIANTS H N ROUNDS IN_VRS IN_VALUES OUT_VRS [-2 DIR GUID]
 *                     [-3 DIR TOKEN] [-r|-i|-e|-b VR=V]...
 *   VARIANTS comma-separated names of the list above; -2 / -3: the extracted GearPair.fmu /
 *   GearPair3.fmu (the folder as this process names it: Z:/... under Wine) and its GUID /
 *   instantiation token; IN_VRS, OUT_VRS comma-separated Float64 value references; IN_VALUES
 *   the inputs' values (held constant); -r / -i / -e / -b: a Float64 / Int32 / enumeration
 *   (fmi3: Int64) / Boolean (0 or 1) start value (repeatable; fmi2 sets -i and -e as
 *   Integer).
 */
#define _POSIX_C_SOURCE 200809L
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "fmi3Functions.h"

#ifdef _WIN32
#include <windows.h>
#define PLATFORM2 "win64"
#define PLATFORM3 "x86_64-windows"
#define SUFFIX ".dll"
typedef HMODULE lib_t;
static lib_t lib_open(const char *path) {
    return LoadLibraryExA(path, NULL, LOAD_WITH_ALTERED_SEARCH_PATH);
}
static void *lib_sym(lib_t lib, const char *name) {
    FARPROC f = GetProcAddress(lib, name);
    void *p;
    memcpy(&p, &f, sizeof p); /* a function's address as the data pointer dlsym returns */
    return p;
}
static double wall_now(void) {
    static LARGE_INTEGER freq;
    LARGE_INTEGER t;
    if (!freq.QuadPart) QueryPerformanceFrequency(&freq);
    QueryPerformanceCounter(&t);
    return (double)t.QuadPart / (double)freq.QuadPart;
}
/* The thread's CPU time (kernel + user, 100 ns units). */
static double cpu_now(void) {
    FILETIME created, ended, kernel, user;
    if (!GetThreadTimes(GetCurrentThread(), &created, &ended, &kernel, &user)) return 0.0;
    uint64_t k = ((uint64_t)kernel.dwHighDateTime << 32) | kernel.dwLowDateTime;
    uint64_t u = ((uint64_t)user.dwHighDateTime << 32) | user.dwLowDateTime;
    return 1e-7 * (double)(k + u);
}
#else
#include <dlfcn.h>
#include <time.h>
#define PLATFORM2 "linux64"
#define PLATFORM3 "x86_64-linux"
#define SUFFIX ".so"
typedef void *lib_t;
static lib_t lib_open(const char *path) { return dlopen(path, RTLD_NOW | RTLD_LOCAL); }
static void *lib_sym(lib_t lib, const char *name) { return dlsym(lib, name); }
static double clock_now(clockid_t id) {
    struct timespec ts;
    clock_gettime(id, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}
static double wall_now(void) { return clock_now(CLOCK_MONOTONIC); }
static double cpu_now(void) { return clock_now(CLOCK_THREAD_CPUTIME_ID); }
#endif

#define MAXV 64
#define MAXR 256

enum { FMI2, FMI3, FMI3_EVENTS, FMI3_EARLY, N_VARIANTS };
static const char *const NAMES[N_VARIANTS] = {"fmi2", "fmi3", "fmi3_events", "fmi3_early"};

static void quit(const char *what, int status) {
    printf("RESULT {\"ok\": 0, \"error\": \"%s (status %d)\"}\n", what, status);
    fflush(stdout);
    exit(1);
}

static void *need(lib_t lib, const char *name) {
    void *f = lib_sym(lib, name);
    if (!f) quit(name, -1);
    return f;
}

static void log2_(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                  fmi2String category, fmi2String message, ...) {
    va_list ap;
    (void)env, (void)instance, (void)category;
    if (status <= fmi2Warning) return;
    va_start(ap, message);
    fprintf(stderr, "fmi2 log (status %d): ", (int)status);
    vfprintf(stderr, message, ap);
    fputc('\n', stderr);
    va_end(ap);
}

static void log3_(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category,
                  fmi3String message) {
    (void)env, (void)category;
    if (status > fmi3Warning) fprintf(stderr, "fmi3 log (status %d): %s\n", (int)status, message);
}

/* Comma-separated numbers into out (at most MAXV); how many, or -1. */
static int numbers(const char *text, double *out) {
    int n = 0;
    const char *p = text;
    while (*p && n < MAXV) {
        char *end;
        out[n++] = strtod(p, &end);
        if (end == p) return -1;
        p = (*end == ',') ? end + 1 : end;
    }
    return n;
}

/* Start values by kind: r Float64, i Int32, e enumeration, b Boolean. */
typedef struct {
    unsigned vr[MAXV];
    double val[MAXV];
    int n;
} Starts;
static Starts starts[4];
static const char KINDS[] = "rieb"; /* as in -r -i -e -b */

/* The inputs and outputs of the master's loop, the same for every variant. */
static unsigned in_vr[MAXV], out_vr[MAXV];
static double in_val[MAXV];
static int n_in, n_out;

/* The FMI functions each variant calls. */
typedef struct {
    fmi2SetRealTYPE *set_real;
    fmi2GetRealTYPE *get_real;
    fmi2DoStepTYPE *do_step;
    fmi2FreeInstanceTYPE *free_instance;
} Api2;
typedef struct {
    fmi3SetFloat64TYPE *set_float64;
    fmi3GetFloat64TYPE *get_float64;
    fmi3DoStepTYPE *do_step;
    fmi3EnterEventModeTYPE *enter_event_mode;
    fmi3UpdateDiscreteStatesTYPE *update;
    fmi3EnterStepModeTYPE *enter_step_mode;
    fmi3FreeInstanceTYPE *free_instance;
} Api3;
static Api2 api2;
static Api3 api3;

/* One variant's instance, where it stands and what it measured. */
typedef struct {
    int kind, on;
    void *c;
    double t, out[MAXV], wall[MAXR], cpu[MAXR];
    long next; /* the next communication point's index: the point is next * h */
    long calls, early, events;
    uint64_t digest; /* FNV-1a over the bits of every output got at a communication point */
} Variant;

static void hash(Variant *v) {
    for (int j = 0; j < n_out; j++) {
        uint64_t bits;
        memcpy(&bits, &v->out[j], sizeof bits);
        v->digest = (v->digest ^ bits) * 1099511628211ull;
    }
}

/* Steps of one round: n communication points of GearPair.fmu. */
static void block2(Variant *v, double h, long n) {
    fmi2Component c = v->c;
    for (long k = 0; k < n; k++) {
        double point = (double)(v->next + 1) * h; /* the master's grid, i * h */
        int st = api2.set_real(c, in_vr, (size_t)n_in, in_val);
        if (st <= fmi2Warning) st = api2.do_step(c, v->t, point - v->t, fmi2True);
        if (st <= fmi2Warning) st = api2.get_real(c, out_vr, (size_t)n_out, v->out);
        if (st > fmi2Warning) quit("the fmi2 step loop", st);
        v->calls++;
        v->t = point;
        v->next++;
        hash(v);
    }
}

/* Steps of one round: n communication points of GearPair3.fmu, and as many early returns
 * on the way as the variant allows. */
static void block3(Variant *v, double h, long n) {
    fmi3Instance c = v->c;
    long end = v->next + n;
    while (v->next < end) {
        double point = (double)(v->next + 1) * h;
        fmi3Boolean event = fmi3False, terminate = fmi3False, early = fmi3False;
        fmi3Float64 last = point;
        int st = api3.set_float64(c, in_vr, (size_t)n_in, in_val, (size_t)n_in);
        if (st <= fmi3Warning)
            st = api3.do_step(c, v->t, point - v->t, fmi3True, &event, &terminate, &early,
                              &last);
        if (st <= fmi3Warning)
            st = api3.get_float64(c, out_vr, (size_t)n_out, v->out, (size_t)n_out);
        if (st > fmi3Warning) quit("the fmi3 step loop", st);
        v->calls++;
        if (early && last < point) {
            v->early++;
            v->t = last;
        } else {
            v->t = point;
            v->next++;
            hash(v);
        }
        if (event && v->kind == FMI3_EVENTS) {
            fmi3Boolean more, term, changed_nominals, changed_values, next_defined;
            fmi3Float64 next_time;
            st = api3.enter_event_mode(c);
            if (st <= fmi3Warning)
                st = api3.update(c, &more, &term, &changed_nominals, &changed_values,
                                 &next_defined, &next_time);
            if (st <= fmi3Warning) st = api3.enter_step_mode(c);
            if (st > fmi3Warning) quit("the fmi3 Event Mode", st);
            v->events++;
        }
    }
}

static void *instantiate2(lib_t lib, const char *dir, const char *guid) {
    static fmi2CallbackFunctions cb = {log2_, calloc, free, NULL, NULL};
    char uri[4200];
    /* file:///abs/resources; under Windows file:///Z:/abs/resources */
    snprintf(uri, sizeof uri, "file://%s%s/resources", dir[0] == '/' ? "" : "/", dir);
    for (char *p = uri; *p; p++)
        if (*p == '\\') *p = '/';
    fmi2Component c = ((fmi2InstantiateTYPE *)need(lib, "fmi2Instantiate"))(
        "bench2", fmi2CoSimulation, guid, uri, &cb, fmi2False, fmi2False);
    if (!c) quit("fmi2Instantiate", -1);
    int st = ((fmi2SetupExperimentTYPE *)need(lib, "fmi2SetupExperiment"))(c, fmi2False, 0.0,
                                                                           0.0, fmi2False, 0.0);
    for (int k = 0; k < 4 && st <= fmi2Warning; k++) {
        Starts *s = &starts[k];
        if (!s->n) continue;
        if (KINDS[k] == 'r') {
            st = ((fmi2SetRealTYPE *)need(lib, "fmi2SetReal"))(c, s->vr, (size_t)s->n, s->val);
        } else if (KINDS[k] == 'b') {
            fmi2Boolean b[MAXV];
            for (int j = 0; j < s->n; j++) b[j] = s->val[j] != 0.0;
            st = ((fmi2SetBooleanTYPE *)need(lib, "fmi2SetBoolean"))(c, s->vr, (size_t)s->n, b);
        } else {
            fmi2Integer x[MAXV];
            for (int j = 0; j < s->n; j++) x[j] = (fmi2Integer)s->val[j];
            st = ((fmi2SetIntegerTYPE *)need(lib, "fmi2SetInteger"))(c, s->vr, (size_t)s->n, x);
        }
    }
    if (st > fmi2Warning) quit("fmi2 start values", st);
    st = ((fmi2EnterInitializationModeTYPE *)need(lib, "fmi2EnterInitializationMode"))(c);
    if (st <= fmi2Warning)
        st = ((fmi2ExitInitializationModeTYPE *)need(lib, "fmi2ExitInitializationMode"))(c);
    if (st > fmi2Warning) quit("fmi2 initialization", st);
    return c;
}

static void *instantiate3(lib_t lib, const char *dir, const char *token, int kind) {
    char res[4200];
    snprintf(res, sizeof res, "%s/resources/", dir);
    fmi3Instance c = ((fmi3InstantiateCoSimulationTYPE *)need(lib, "fmi3InstantiateCoSimulation"))(
        "bench3", token, res, fmi3False, fmi3False, kind == FMI3_EVENTS, kind != FMI3, NULL, 0,
        NULL, log3_, NULL);
    if (!c) quit("fmi3InstantiateCoSimulation", -1);
    int st = ((fmi3EnterInitializationModeTYPE *)need(lib, "fmi3EnterInitializationMode"))(
        c, fmi3False, 0.0, 0.0, fmi3False, 0.0);
    for (int k = 0; k < 4 && st <= fmi3Warning; k++) {
        Starts *s = &starts[k];
        size_t n = (size_t)s->n;
        if (!n) continue;
        if (KINDS[k] == 'r') {
            st = ((fmi3SetFloat64TYPE *)need(lib, "fmi3SetFloat64"))(c, s->vr, n, s->val, n);
        } else if (KINDS[k] == 'b') {
            fmi3Boolean b[MAXV];
            for (size_t j = 0; j < n; j++) b[j] = s->val[j] != 0.0;
            st = ((fmi3SetBooleanTYPE *)need(lib, "fmi3SetBoolean"))(c, s->vr, n, b, n);
        } else if (KINDS[k] == 'i') {
            fmi3Int32 x[MAXV];
            for (size_t j = 0; j < n; j++) x[j] = (fmi3Int32)s->val[j];
            st = ((fmi3SetInt32TYPE *)need(lib, "fmi3SetInt32"))(c, s->vr, n, x, n);
        } else {
            fmi3Int64 x[MAXV];
            for (size_t j = 0; j < n; j++) x[j] = (fmi3Int64)s->val[j];
            st = ((fmi3SetInt64TYPE *)need(lib, "fmi3SetInt64"))(c, s->vr, n, x, n);
        }
    }
    if (st > fmi3Warning) quit("fmi3 start values", st);
    st = ((fmi3ExitInitializationModeTYPE *)need(lib, "fmi3ExitInitializationMode"))(c);
    if (st > fmi3Warning) quit("fmi3ExitInitializationMode", st);
    if (kind == FMI3_EVENTS) { /* with Event Mode, initialization ends in Event Mode */
        fmi3Boolean a, b, d, e, f;
        fmi3Float64 g;
        st = ((fmi3UpdateDiscreteStatesTYPE *)need(lib, "fmi3UpdateDiscreteStates"))(
            c, &a, &b, &d, &e, &f, &g);
        if (st <= fmi3Warning)
            st = ((fmi3EnterStepModeTYPE *)need(lib, "fmi3EnterStepMode"))(c);
        if (st > fmi3Warning) quit("fmi3 leaving initialization's Event Mode", st);
    }
    return c;
}

static void print_times(const char *key, const double *v, long n) {
    printf("\"%s\": [", key);
    for (long b = 0; b < n; b++) printf("%s%.9g", b ? ", " : "", v[b]);
    printf("]");
}

int main(int argc, char **argv) {
    if (argc < 8) {
        fprintf(stderr, "usage: %s VARIANTS H N ROUNDS IN_VRS IN_VALUES OUT_VRS [-2 DIR GUID] "
                        "[-3 DIR TOKEN] [-r|-i|-e|-b VR=V]...\n", argv[0]);
        return 2;
    }
    static Variant var[N_VARIANTS];
    for (const char *p = argv[1]; *p;) {
        size_t len = strcspn(p, ",");
        int found = 0;
        for (int k = 0; k < N_VARIANTS; k++)
            if (strlen(NAMES[k]) == len && !strncmp(p, NAMES[k], len)) var[k].on = found = 1;
        if (!found) return 2;
        p += len + (p[len] == ',');
    }
    double h = strtod(argv[2], NULL), buf[MAXV];
    long n = strtol(argv[3], NULL, 10), rounds = strtol(argv[4], NULL, 10);
    if (!(h > 0.0) || n < 1 || rounds < 1 || rounds > MAXR) return 2;
    n_in = numbers(argv[5], buf);
    for (int k = 0; k < n_in; k++) in_vr[k] = (unsigned)buf[k];
    if (n_in < 0 || numbers(argv[6], in_val) != n_in) return 2;
    n_out = numbers(argv[7], buf);
    if (n_out < 0) return 2;
    for (int k = 0; k < n_out; k++) out_vr[k] = (unsigned)buf[k];
    const char *dir2 = NULL, *guid2 = NULL, *dir3 = NULL, *token3 = NULL;
    for (int a = 8; a < argc; a++) {
        if ((!strcmp(argv[a], "-2") || !strcmp(argv[a], "-3")) && a + 2 < argc) {
            *(argv[a][1] == '2' ? &dir2 : &dir3) = argv[a + 1];
            *(argv[a][1] == '2' ? &guid2 : &token3) = argv[a + 2];
            a += 2;
            continue;
        }
        const char *eq = a + 1 < argc ? strchr(argv[a + 1], '=') : NULL;
        const char *kind = argv[a][0] == '-' ? strchr(KINDS, argv[a][1]) : NULL;
        if (!eq || !kind || argv[a][1] == '\0' || argv[a][2] != '\0') return 2;
        Starts *s = &starts[kind - KINDS];
        if (s->n == MAXV) return 2;
        s->vr[s->n] = (unsigned)strtoul(argv[a + 1], NULL, 10);
        s->val[s->n++] = strtod(eq + 1, NULL);
        a++;
    }

    char path[4300];
    if (var[FMI2].on) {
        if (!dir2) return 2;
        snprintf(path, sizeof path, "%s/binaries/%s/GearPair%s", dir2, PLATFORM2, SUFFIX);
        lib_t lib = lib_open(path);
        if (!lib) quit("loading GearPair.fmu's binary", -1);
        api2.set_real = (fmi2SetRealTYPE *)need(lib, "fmi2SetReal");
        api2.get_real = (fmi2GetRealTYPE *)need(lib, "fmi2GetReal");
        api2.do_step = (fmi2DoStepTYPE *)need(lib, "fmi2DoStep");
        api2.free_instance = (fmi2FreeInstanceTYPE *)need(lib, "fmi2FreeInstance");
        var[FMI2].c = instantiate2(lib, dir2, guid2);
    }
    if (var[FMI3].on || var[FMI3_EVENTS].on || var[FMI3_EARLY].on) {
        if (!dir3) return 2;
        snprintf(path, sizeof path, "%s/binaries/%s/GearPair3%s", dir3, PLATFORM3, SUFFIX);
        lib_t lib = lib_open(path);
        if (!lib) quit("loading GearPair3.fmu's binary", -1);
        api3.set_float64 = (fmi3SetFloat64TYPE *)need(lib, "fmi3SetFloat64");
        api3.get_float64 = (fmi3GetFloat64TYPE *)need(lib, "fmi3GetFloat64");
        api3.do_step = (fmi3DoStepTYPE *)need(lib, "fmi3DoStep");
        api3.enter_event_mode = (fmi3EnterEventModeTYPE *)need(lib, "fmi3EnterEventMode");
        api3.update = (fmi3UpdateDiscreteStatesTYPE *)need(lib, "fmi3UpdateDiscreteStates");
        api3.enter_step_mode = (fmi3EnterStepModeTYPE *)need(lib, "fmi3EnterStepMode");
        api3.free_instance = (fmi3FreeInstanceTYPE *)need(lib, "fmi3FreeInstance");
        for (int k = FMI3; k < N_VARIANTS; k++)
            if (var[k].on) var[k].c = instantiate3(lib, dir3, token3, k);
    }
    for (int k = 0; k < N_VARIANTS; k++) {
        var[k].kind = k;
        var[k].digest = 1469598103934665603ull;
    }

    for (long b = 0; b < rounds; b++)
        for (int i = 0; i < N_VARIANTS; i++) {
            Variant *v = &var[(i + b) % N_VARIANTS]; /* the first one rotates */
            if (!v->on) continue;
            double w0 = wall_now(), c0 = cpu_now();
            if (v->kind == FMI2)
                block2(v, h, n);
            else
                block3(v, h, n);
            v->cpu[b] = cpu_now() - c0;
            v->wall[b] = wall_now() - w0;
        }

    printf("RESULT {\"ok\": 1, \"n\": %ld, \"h\": %.17g, \"rounds\": %ld, \"variants\": {", n,
           h, rounds);
    for (int k = 0, first = 1; k < N_VARIANTS; k++) {
        Variant *v = &var[k];
        if (!v->on) continue;
        printf("%s\"%s\": {", first ? "" : ", ", NAMES[k]);
        first = 0;
        print_times("wall_s", v->wall, rounds);
        printf(", ");
        print_times("cpu_s", v->cpu, rounds);
        printf(", \"calls\": %ld, \"early\": %ld, \"events\": %ld, \"t_end\": %.17g, "
               "\"digest\": \"%016llx\"}", v->calls, v->early, v->events, v->t,
               (unsigned long long)v->digest);
    }
    printf("}}\n");
    fflush(stdout);
    for (int k = 0; k < N_VARIANTS; k++) {
        if (!var[k].on) continue;
        if (k == FMI2)
            api2.free_instance(var[k].c);
        else
            api3.free_instance(var[k].c);
    }
    return 0;
}
