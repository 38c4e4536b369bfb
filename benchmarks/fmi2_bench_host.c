/* Timing host for `gearpair bench`: what one co-simulation step of an FMI 2.0 FMU costs in a
 * C master, and what its first start costs.
 *
 * It loads an extracted FMU with dlopen, instantiates it once (timed), initializes it with
 * the given start values (timed), takes a first step (timed: the first step may load or
 * compile code), then times BLOCKS blocks of N steps of the loop a master runs:
 *
 *     fmi2SetReal(inputs) ; fmi2DoStep(t, H) ; fmi2GetReal(outputs)
 *
 * on the wall clock (CLOCK_MONOTONIC) and on the process CPU clock. It prints one line
 *
 *     RESULT {"instantiate_s": ..., "initialize_s": ..., "first_step_s": ...,
 *             "block_wall_s": [...], "block_cpu_s": [...], "steps_per_block": N, "ok": 1}
 *
 * and flushes it before anything else can go wrong: the caller reads that line whatever the
 * exit status (pythonfmu's binary may crash while the process exits).
 *
 * Build (the FMI 2 headers ship with fmpy, in fmpy/c-code):
 *     gcc -O2 -std=c99 -I"$FMPY/c-code" -o fmi2_bench_host fmi2_bench_host.c -ldl
 * Usage:
 *     fmi2_bench_host DIR MODEL_ID GUID H N BLOCKS IN_VRS IN_VALUES OUT_VRS [-r|-i|-b VR=V]...
 *   DIR the extracted FMU; IN_VRS, OUT_VRS comma-separated Real value references; IN_VALUES
 *   the inputs' values (comma separated, held constant); -r / -i / -b set a Real / Integer /
 *   Boolean (0 or 1) start value before initialization (repeatable).
 * A pythonfmu FMU needs LD_PRELOAD=<libpython.so> and PYTHONPATH=<site-packages>
 * (docs/hosts.md).
 */
#define _POSIX_C_SOURCE 200809L
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "fmi2Functions.h"

#define MAXV 64
#define MAXB 64

static void log_message(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                        fmi2String category, fmi2String message, ...) {
    va_list ap;
    (void)env;
    (void)instance;
    va_start(ap, message);
    fprintf(stderr, "fmu log (status %d, %s): ", (int)status, category ? category : "-");
    vfprintf(stderr, message, ap);
    fputc('\n', stderr);
    va_end(ap);
}

static double now(clockid_t id) {
    struct timespec ts;
    clock_gettime(id, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Comma-separated numbers into out (at most MAXV); returns how many. */
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

static void *need(void *lib, const char *name) {
    void *f = dlsym(lib, name);
    if (!f) {
        printf("RESULT {\"ok\": 0, \"error\": \"missing symbol %s\"}\n", name);
        fflush(stdout);
        exit(1);
    }
    return f;
}

static int fail(const char *what, int status) {
    printf("RESULT {\"ok\": 0, \"error\": \"%s returned status %d\"}\n", what, status);
    fflush(stdout);
    return 1;
}

int main(int argc, char **argv) {
    if (argc < 10) {
        fprintf(stderr, "usage: %s DIR MODEL_ID GUID H N BLOCKS IN_VRS IN_VALUES OUT_VRS "
                        "[-r|-i|-b VR=V]...\n", argv[0]);
        return 2;
    }
    const char *dir = argv[1], *model = argv[2], *guid = argv[3];
    double h = strtod(argv[4], NULL), buf[MAXV];
    long n = strtol(argv[5], NULL, 10), blocks = strtol(argv[6], NULL, 10);
    unsigned in_vr[MAXV], out_vr[MAXV], start_vr[MAXV], int_vr[MAXV], bool_vr[MAXV];
    double in_val[MAXV], out_val[MAXV], start_val[MAXV];
    int int_val[MAXV], n_start = 0, n_int = 0, n_bool = 0;
    fmi2Boolean bool_val[MAXV];
    int n_in = numbers(argv[7], buf);
    for (int k = 0; k < n_in; k++) in_vr[k] = (unsigned)buf[k];
    if (numbers(argv[8], in_val) != n_in || n_in < 0) return 2;
    int n_out = numbers(argv[9], buf);
    if (n_out < 0) return 2;
    for (int k = 0; k < n_out; k++) out_vr[k] = (unsigned)buf[k];
    if (blocks < 1 || blocks > MAXB || n < 1 || !(h > 0.0)) return 2;
    for (int a = 10; a + 1 < argc; a += 2) {
        const char *eq = strchr(argv[a + 1], '=');
        if (!eq) return 2;
        if (!strcmp(argv[a], "-r") && n_start < MAXV) {
            start_vr[n_start] = (unsigned)strtoul(argv[a + 1], NULL, 10);
            start_val[n_start++] = strtod(eq + 1, NULL);
        } else if (!strcmp(argv[a], "-i") && n_int < MAXV) {
            int_vr[n_int] = (unsigned)strtoul(argv[a + 1], NULL, 10);
            int_val[n_int++] = (int)strtol(eq + 1, NULL, 10);
        } else if (!strcmp(argv[a], "-b") && n_bool < MAXV) {
            bool_vr[n_bool] = (unsigned)strtoul(argv[a + 1], NULL, 10);
            bool_val[n_bool++] = strtol(eq + 1, NULL, 10) ? fmi2True : fmi2False;
        } else {
            return 2;
        }
    }

    char so[4096], resources[4200];
    snprintf(so, sizeof so, "%s/binaries/linux64/%s.so", dir, model);
    snprintf(resources, sizeof resources, "file://%s/resources", dir);
    void *lib = dlopen(so, RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        printf("RESULT {\"ok\": 0, \"error\": \"dlopen failed\"}\n");
        fprintf(stderr, "dlopen %s: %s\n", so, dlerror());
        fflush(stdout);
        return 1;
    }
    fmi2InstantiateTYPE *instantiate = (fmi2InstantiateTYPE *)need(lib, "fmi2Instantiate");
    fmi2SetupExperimentTYPE *setup = (fmi2SetupExperimentTYPE *)need(lib, "fmi2SetupExperiment");
    fmi2EnterInitializationModeTYPE *enter_init =
        (fmi2EnterInitializationModeTYPE *)need(lib, "fmi2EnterInitializationMode");
    fmi2ExitInitializationModeTYPE *exit_init =
        (fmi2ExitInitializationModeTYPE *)need(lib, "fmi2ExitInitializationMode");
    fmi2SetRealTYPE *set_real = (fmi2SetRealTYPE *)need(lib, "fmi2SetReal");
    fmi2SetIntegerTYPE *set_integer = (fmi2SetIntegerTYPE *)need(lib, "fmi2SetInteger");
    fmi2SetBooleanTYPE *set_boolean = (fmi2SetBooleanTYPE *)need(lib, "fmi2SetBoolean");
    fmi2GetRealTYPE *get_real = (fmi2GetRealTYPE *)need(lib, "fmi2GetReal");
    fmi2DoStepTYPE *do_step = (fmi2DoStepTYPE *)need(lib, "fmi2DoStep");
    fmi2TerminateTYPE *terminate = (fmi2TerminateTYPE *)need(lib, "fmi2Terminate");
    fmi2FreeInstanceTYPE *free_instance = (fmi2FreeInstanceTYPE *)need(lib, "fmi2FreeInstance");

    fmi2CallbackFunctions callbacks = {log_message, calloc, free, NULL, NULL};
    double t0 = now(CLOCK_MONOTONIC);
    fmi2Component c = instantiate("bench", fmi2CoSimulation, guid, resources, &callbacks,
                                  fmi2False, fmi2False);
    double t1 = now(CLOCK_MONOTONIC);
    if (!c) return fail("fmi2Instantiate", -1);
    int st;
    if ((st = setup(c, fmi2False, 0.0, 0.0, fmi2False, 0.0)) > fmi2Warning)
        return fail("fmi2SetupExperiment", st);
    if (n_start && (st = set_real(c, start_vr, (size_t)n_start, start_val)) > fmi2Warning)
        return fail("fmi2SetReal (start values)", st);
    if (n_int && (st = set_integer(c, int_vr, (size_t)n_int, int_val)) > fmi2Warning)
        return fail("fmi2SetInteger (start values)", st);
    if (n_bool && (st = set_boolean(c, bool_vr, (size_t)n_bool, bool_val)) > fmi2Warning)
        return fail("fmi2SetBoolean (start values)", st);
    if ((st = enter_init(c)) > fmi2Warning) return fail("fmi2EnterInitializationMode", st);
    if ((st = exit_init(c)) > fmi2Warning) return fail("fmi2ExitInitializationMode", st);
    double t2 = now(CLOCK_MONOTONIC);
    double t = 0.0;
    if ((st = set_real(c, in_vr, (size_t)n_in, in_val)) > fmi2Warning)
        return fail("fmi2SetReal (inputs)", st);
    if ((st = do_step(c, t, h, fmi2True)) > fmi2Warning) return fail("fmi2DoStep", st);
    double t3 = now(CLOCK_MONOTONIC);
    t += h;

    double wall[MAXB], cpu[MAXB];
    for (long b = 0; b < blocks; b++) {
        double w0 = now(CLOCK_MONOTONIC), c0 = now(CLOCK_PROCESS_CPUTIME_ID);
        for (long k = 0; k < n; k++) {
            st = set_real(c, in_vr, (size_t)n_in, in_val);
            if (st <= fmi2Warning) st = do_step(c, t, h, fmi2True);
            if (st <= fmi2Warning) st = get_real(c, out_vr, (size_t)n_out, out_val);
            if (st > fmi2Warning) return fail("the step loop", st);
            t = (double)(b * n + k + 2) * h;  /* the master's grid, n*h, not a running sum */
        }
        wall[b] = now(CLOCK_MONOTONIC) - w0;
        cpu[b] = now(CLOCK_PROCESS_CPUTIME_ID) - c0;
    }
    printf("RESULT {\"ok\": 1, \"instantiate_s\": %.9g, \"initialize_s\": %.9g, "
           "\"first_step_s\": %.9g, \"steps_per_block\": %ld, \"last_output\": %.17g, "
           "\"block_wall_s\": [", t1 - t0, t2 - t1, t3 - t2, n, n_out ? out_val[0] : 0.0);
    for (long b = 0; b < blocks; b++) printf("%s%.9g", b ? ", " : "", wall[b]);
    printf("], \"block_cpu_s\": [");
    for (long b = 0; b < blocks; b++) printf("%s%.9g", b ? ", " : "", cpu[b]);
    printf("]}\n");
    fflush(stdout);
    fflush(stderr);
    terminate(c);
    free_instance(c);
    return 0;
}
