/* A minimal FMI 3.0 co-simulation host: loads an extracted FMU, sets start values, steps it
 * over fixed communication points and prints the outputs with all their bits. With early
 * return allowed it records every early return (an event inside a step) and, with Event
 * Mode, the outputs after the event was handled there; the next step starts where the last
 * one ended. Several instances of the same case run in threads of their own.
 *
 * Build (the FMI 3 headers ship with fmpy, in fmpy/c-code; fmu_dl.h is beside this file):
 *   gcc -O2 -std=c99 -I"$(python -c 'import fmpy, os; print(os.path.dirname(fmpy.__file__))')/c-code" \
 *       -o fmi3_host fmi3_host.c -ldl -lpthread
 * (for Windows with mingw-w64: x86_64-w64-mingw32-gcc ... -D__USE_MINGW_ANSI_STDIO=1).
 *
 * Usage:
 *   fmi3_host UNZIPDIR MODEL_ID TOKEN H T_END [options]
 *     UNZIPDIR  the extracted FMU (the folder holding modelDescription.xml)
 *     TOKEN     the instantiationToken of its modelDescription
 *     H, T_END  communication step and stop time (s): communication points T0 + k H
 *   options:
 *     -r VR=V   set a Float64 (parameter or input) before initialization; repeatable
 *     -i VR=V   an Int32, -e VR=V an Enumeration (Int64), -b VR=0|1 a Boolean
 *     -o VRS    Float64 outputs to print (value references, comma separated)
 *     -n VRS    Int32 outputs to print
 *     -t T0     start time (default 0)
 *     -E MODE   0: no early return; 1: early return with Event Mode (default); 2: early
 *               return without Event Mode (the FMU handles its events itself)
 *     -j N      N instances of the case, each in a thread of its own (default 1)
 *     -l 1      loggingOn
 * Prints, per instance, "# instance K" and rows "KIND,time,<reals...>,<integers...>": KIND
 * init after initialization, step at a communication point, early where a step returned
 * early (lastSuccessfulTime), event after fmi3UpdateDiscreteStates at that time. Exits 0
 * when every call returned fmi3OK/fmi3Warning, else 1 (the failing call on stderr).
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3FunctionTypes.h"
#include "fmu_dl.h"

#ifdef _WIN32
#define FMI3_PLATFORM "x86_64-windows"
#else
#include <pthread.h>
#define FMI3_PLATFORM "x86_64-linux"
#endif

#define MAXV 64

/* -- text into a growing buffer (each instance writes its own) -------------------------- */
typedef struct {
    char *p;
    size_t n, cap;
} Out;

static void out(Out *o, const char *fmt, ...) {
    va_list ap, aq;
    va_start(ap, fmt);
    va_copy(aq, ap);
    int k = vsnprintf(NULL, 0, fmt, ap);
    va_end(ap);
    if (k > 0 && o->n + (size_t)k + 1 > o->cap) {
        size_t cap = 2 * (o->n + (size_t)k + 1);
        char *p = realloc(o->p, cap);
        if (!p) abort();
        o->p = p;
        o->cap = cap;
    }
    if (k > 0) o->n += (size_t)vsnprintf(o->p + o->n, o->cap - o->n, fmt, aq);
    va_end(aq);
}

/* -- the FMU's functions -------------------------------------------------------------------- */
static struct {
    fmi3InstantiateCoSimulationTYPE *instantiate;
    fmi3FreeInstanceTYPE *free_instance;
    fmi3EnterInitializationModeTYPE *enter_init;
    fmi3ExitInitializationModeTYPE *exit_init;
    fmi3EnterEventModeTYPE *enter_event;
    fmi3UpdateDiscreteStatesTYPE *update;
    fmi3EnterStepModeTYPE *enter_step;
    fmi3DoStepTYPE *do_step;
    fmi3TerminateTYPE *terminate;
    fmi3SetFloat64TYPE *set_f64;
    fmi3SetInt32TYPE *set_i32;
    fmi3SetInt64TYPE *set_i64;
    fmi3SetBooleanTYPE *set_bool;
    fmi3GetFloat64TYPE *get_f64;
    fmi3GetInt32TYPE *get_i32;
} F;

static void *sym(fmu_lib lib, const char *name) {
    void *f = fmu_dlsym(lib, name);
    if (!f) {
        fprintf(stderr, "missing symbol %s: %s\n", name, fmu_dlerror());
        exit(1);
    }
    return f;
}

/* -- the case -------------------------------------------------------------------------------- */
typedef struct {
    const char *token, *resources;
    double h, t_end, t0;
    int mode, logging_on;
    unsigned fvr[MAXV], ivr[MAXV], evr[MAXV], bvr[MAXV], ovr[MAXV], nvr[MAXV];
    double fval[MAXV];
    fmi3Int32 ival[MAXV];
    fmi3Int64 eval[MAXV];
    fmi3Boolean bval[MAXV];
    int n_f, n_i, n_e, n_b, n_o, n_n;
} Case;

typedef struct {
    const Case *c;
    int index;
    Out text;
    int failed;
} Run;

static void logger(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category,
                   fmi3String message) {
    Run *r = env;
    fprintf(stderr, "[instance %d|%d|%s] %s\n", r ? r->index : -1, (int)status,
            category ? category : "", message);
}

#define CHECK(call)                                                                  \
    do {                                                                             \
        fmi3Status st_ = (call);                                                     \
        if (st_ > fmi3Warning) {                                                     \
            fprintf(stderr, "instance %d: %s returned status %d\n", r->index, #call, \
                    (int)st_);                                                       \
            r->failed = 1;                                                           \
            goto end;                                                                \
        }                                                                            \
    } while (0)

static int row(Run *r, fmi3Instance c, const char *kind, double t) {
    const Case *k = r->c;
    double f[MAXV];
    fmi3Int32 i[MAXV];
    if (k->n_o && F.get_f64(c, k->ovr, (size_t)k->n_o, f, (size_t)k->n_o) > fmi3Warning) return 1;
    if (k->n_n && F.get_i32(c, k->nvr, (size_t)k->n_n, i, (size_t)k->n_n) > fmi3Warning) return 1;
    out(&r->text, "%s,%.17g", kind, t);
    for (int j = 0; j < k->n_o; j++) out(&r->text, ",%.17g", f[j]);
    for (int j = 0; j < k->n_n; j++) out(&r->text, ",%d", (int)i[j]);
    out(&r->text, "\n");
    return 0;
}

/* Event Mode until the FMU needs no further update, then Step Mode again. */
static fmi3Status event_iteration(fmi3Instance c) {
    fmi3Boolean more = fmi3True, term, nom, val, next_defined;
    fmi3Float64 next;
    fmi3Status st = fmi3OK;
    while (more && st <= fmi3Warning)
        st = F.update(c, &more, &term, &nom, &val, &next_defined, &next);
    return st > fmi3Warning ? st : F.enter_step(c);
}

static void run_case(Run *r) {
    const Case *k = r->c;
    char name[32];
    snprintf(name, sizeof name, "instance%d", r->index);
    out(&r->text, "# instance %d\n", r->index);
    fmi3Instance c = F.instantiate(name, k->token, k->resources, fmi3False,
                                   k->logging_on ? fmi3True : fmi3False, k->mode == 1,
                                   k->mode != 0, NULL, 0, r, logger, NULL);
    if (!c) {
        fprintf(stderr, "instance %d: fmi3InstantiateCoSimulation failed\n", r->index);
        r->failed = 1;
        return;
    }
    double t = k->t0;
    CHECK(F.enter_init(c, fmi3False, 0.0, t, fmi3True, k->t_end));
    if (k->n_f) CHECK(F.set_f64(c, k->fvr, (size_t)k->n_f, k->fval, (size_t)k->n_f));
    if (k->n_i) CHECK(F.set_i32(c, k->ivr, (size_t)k->n_i, k->ival, (size_t)k->n_i));
    if (k->n_e) CHECK(F.set_i64(c, k->evr, (size_t)k->n_e, k->eval, (size_t)k->n_e));
    if (k->n_b) CHECK(F.set_bool(c, k->bvr, (size_t)k->n_b, k->bval, (size_t)k->n_b));
    CHECK(F.exit_init(c));
    if (k->mode == 1) CHECK(event_iteration(c)); /* Event Mode follows initialization */
    CHECK(row(r, c, "init", t) ? fmi3Error : fmi3OK);
    long n = 0; /* communication points reached */
    while (t < k->t_end && k->t_end - t > 1e-9 * k->h) {
        double next = k->t0 + (double)(n + 1) * k->h;
        if (next > k->t_end) next = k->t_end;
        fmi3Boolean event, term, early;
        fmi3Float64 last;
        CHECK(F.do_step(c, t, next - t, fmi3True, &event, &term, &early, &last));
        if (early && last < next) {
            t = last;
            CHECK(row(r, c, "early", t) ? fmi3Error : fmi3OK);
        } else {
            t = next;
            n++;
            CHECK(row(r, c, "step", t) ? fmi3Error : fmi3OK);
        }
        if (event && k->mode == 1) {
            CHECK(F.enter_event(c));
            CHECK(event_iteration(c));
            CHECK(row(r, c, "event", t) ? fmi3Error : fmi3OK);
        }
        if (term) break;
    }
    CHECK(F.terminate(c));
end:
    F.free_instance(c);
}

#ifdef _WIN32
static DWORD WINAPI thread_main(LPVOID arg) {
    run_case(arg);
    return 0;
}
#else
static void *thread_main(void *arg) {
    run_case(arg);
    return NULL;
}
#endif

static int parse_list(const char *s, unsigned *o) {
    int n = 0;
    for (const char *p = s; *p && n < MAXV; p = strchr(p, ',') ? strchr(p, ',') + 1 : "")
        o[n++] = (unsigned)strtoul(p, NULL, 10);
    return n;
}

int main(int argc, char **argv) {
    if (argc < 6) {
        fprintf(stderr, "usage: %s UNZIPDIR MODEL_ID TOKEN H T_END [-r VR=V] [-i VR=V] "
                        "[-e VR=V] [-b VR=V] [-o VRS] [-n VRS] [-t T0] [-E MODE] [-j N] "
                        "[-l 1]\n", argv[0]);
        return 2;
    }
    static Case k;
    const char *dir = argv[1], *model = argv[2];
    k.token = argv[3];
    k.h = strtod(argv[4], NULL);
    k.t_end = strtod(argv[5], NULL);
    k.mode = 1;
    int n_threads = 1;
    for (int a = 6; a + 1 < argc; a += 2) {
        const char *opt = argv[a], *arg = argv[a + 1], *eq = strchr(arg, '=');
        unsigned vr = (unsigned)strtoul(arg, NULL, 10);
        if (strchr("rieb", opt[1]) && opt[1] && !eq) {
            fprintf(stderr, "%s needs VR=VALUE\n", opt);
            return 2;
        }
        if (!strcmp(opt, "-r") && k.n_f < MAXV) {
            k.fvr[k.n_f] = vr;
            k.fval[k.n_f++] = strtod(eq + 1, NULL);
        } else if (!strcmp(opt, "-i") && k.n_i < MAXV) {
            k.ivr[k.n_i] = vr;
            k.ival[k.n_i++] = (fmi3Int32)strtol(eq + 1, NULL, 10);
        } else if (!strcmp(opt, "-e") && k.n_e < MAXV) {
            k.evr[k.n_e] = vr;
            k.eval[k.n_e++] = (fmi3Int64)strtoll(eq + 1, NULL, 10);
        } else if (!strcmp(opt, "-b") && k.n_b < MAXV) {
            k.bvr[k.n_b] = vr;
            k.bval[k.n_b++] = strtol(eq + 1, NULL, 10) != 0;
        } else if (!strcmp(opt, "-o")) {
            k.n_o = parse_list(arg, k.ovr);
        } else if (!strcmp(opt, "-n")) {
            k.n_n = parse_list(arg, k.nvr);
        } else if (!strcmp(opt, "-t")) {
            k.t0 = strtod(arg, NULL);
        } else if (!strcmp(opt, "-E")) {
            k.mode = atoi(arg);
        } else if (!strcmp(opt, "-j")) {
            n_threads = atoi(arg);
        } else if (!strcmp(opt, "-l")) {
            k.logging_on = atoi(arg);
        } else {
            fprintf(stderr, "unknown option %s\n", opt);
            return 2;
        }
    }
    if (n_threads < 1 || n_threads > MAXV || !(k.h > 0.0) || !(k.t_end > k.t0)) {
        fprintf(stderr, "bad -j, H or T_END\n");
        return 2;
    }

    char path[4096], resources[4200];
    snprintf(path, sizeof path, "%s/binaries/%s/%s%s", dir, FMI3_PLATFORM, model, FMU_SUFFIX);
    snprintf(resources, sizeof resources, "%s/resources/", dir); /* FMI 3: a path */
    k.resources = resources;
    fmu_lib lib = fmu_dlopen(path);
    if (!lib) {
        fprintf(stderr, "loading %s: %s\n", path, fmu_dlerror());
        return 1;
    }
    F.instantiate = sym(lib, "fmi3InstantiateCoSimulation");
    F.free_instance = sym(lib, "fmi3FreeInstance");
    F.enter_init = sym(lib, "fmi3EnterInitializationMode");
    F.exit_init = sym(lib, "fmi3ExitInitializationMode");
    F.enter_event = sym(lib, "fmi3EnterEventMode");
    F.update = sym(lib, "fmi3UpdateDiscreteStates");
    F.enter_step = sym(lib, "fmi3EnterStepMode");
    F.do_step = sym(lib, "fmi3DoStep");
    F.terminate = sym(lib, "fmi3Terminate");
    F.set_f64 = sym(lib, "fmi3SetFloat64");
    F.set_i32 = sym(lib, "fmi3SetInt32");
    F.set_i64 = sym(lib, "fmi3SetInt64");
    F.set_bool = sym(lib, "fmi3SetBoolean");
    F.get_f64 = sym(lib, "fmi3GetFloat64");
    F.get_i32 = sym(lib, "fmi3GetInt32");

    Run runs[MAXV];
    memset(runs, 0, sizeof runs);
    for (int j = 0; j < n_threads; j++) {
        runs[j].c = &k;
        runs[j].index = j;
    }
    if (n_threads == 1) {
        run_case(&runs[0]);
    } else {
#ifdef _WIN32
        HANDLE th[MAXV];
        for (int j = 0; j < n_threads; j++)
            th[j] = CreateThread(NULL, 0, thread_main, &runs[j], 0, NULL);
        WaitForMultipleObjects((DWORD)n_threads, th, TRUE, INFINITE);
        for (int j = 0; j < n_threads; j++) CloseHandle(th[j]);
#else
        pthread_t th[MAXV];
        for (int j = 0; j < n_threads; j++) pthread_create(&th[j], NULL, thread_main, &runs[j]);
        for (int j = 0; j < n_threads; j++) pthread_join(th[j], NULL);
#endif
    }
    int failed = 0;
    for (int j = 0; j < n_threads; j++) {
        if (runs[j].text.p) fputs(runs[j].text.p, stdout);
        failed |= runs[j].failed;
        free(runs[j].text.p);
    }
    return failed ? 1 : 0;
}
