/* The cost of GearPair3.fmu's steps against GearPair.fmu's, in one process
 * (benchmarks/fmi3_cost.py builds and runs it).
 *
 *   fmi3_cost UNZIP2 GUID2 UNZIP3 TOKEN3 H SPAN ROUNDS [VR=VALUE ...]
 *
 * Both FMUs' Linux binaries are loaded side by side. Each round makes a fresh instance of
 * each variant, initializes it at the default point (plus the Float64 start values given)
 * and times its stepping from 0 to SPAN on communication points k H, in CPU time of the
 * process: GearPair.fmu (fmi2), GearPair3.fmu without early return (fmi3), with early
 * return and Event Mode (fmi3_events: each early return followed by fmi3EnterEventMode,
 * fmi3UpdateDiscreteStates, fmi3EnterStepMode), and with early return without Event Mode
 * (fmi3_early). The variants alternate within each round; the best round of each is
 * printed: "VARIANT us_per_point calls_per_s early_per_s".
 */
#define _POSIX_C_SOURCE 200809L
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "fmi2Functions.h"
#include "fmi3Functions.h"

#define MAXV 32
static unsigned vr_set[MAXV];
static double val_set[MAXV];
static int n_set;

static void *sym(void *lib, const char *name) {
    void *f = dlsym(lib, name);
    if (!f) {
        fprintf(stderr, "missing %s\n", name);
        exit(2);
    }
    return f;
}

static double cpu_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static void log2_(fmi2ComponentEnvironment e, fmi2String i, fmi2Status s, fmi2String c,
                  fmi2String m, ...) {
    (void)e, (void)i, (void)c;
    if (s > fmi2Warning) fprintf(stderr, "fmi2: %s\n", m);
}
static void log3_(fmi3InstanceEnvironment e, fmi3Status s, fmi3String c, fmi3String m) {
    (void)e, (void)c;
    if (s > fmi3Warning) fprintf(stderr, "fmi3: %s\n", m);
}

#define OK(call)                                                                     \
    do {                                                                             \
        if ((int)(call) > 1) {                                                       \
            fprintf(stderr, "%s failed\n", #call);                                   \
            exit(1);                                                                 \
        }                                                                            \
    } while (0)

/* One run of GearPair.fmu: CPU seconds of the steps. */
static double run2(void *lib, const char *uri, const char *guid, double h, double span) {
    fmi2CallbackFunctions cb = {log2_, calloc, free, NULL, NULL};
    fmi2Component c = ((fmi2InstantiateTYPE *)sym(lib, "fmi2Instantiate"))(
        "b2", fmi2CoSimulation, guid, uri, &cb, fmi2False, fmi2False);
    if (!c) exit(1);
    OK(((fmi2SetupExperimentTYPE *)sym(lib, "fmi2SetupExperiment"))(c, 0, 0.0, 0.0, 0, 0.0));
    if (n_set) OK(((fmi2SetRealTYPE *)sym(lib, "fmi2SetReal"))(c, vr_set, (size_t)n_set, val_set));
    OK(((fmi2EnterInitializationModeTYPE *)sym(lib, "fmi2EnterInitializationMode"))(c));
    OK(((fmi2ExitInitializationModeTYPE *)sym(lib, "fmi2ExitInitializationMode"))(c));
    fmi2DoStepTYPE *step = (fmi2DoStepTYPE *)sym(lib, "fmi2DoStep");
    long n = (long)(span / h + 0.5);
    double c0 = cpu_now(), t = 0.0;
    for (long k = 0; k < n; k++) {
        double next = (double)(k + 1) * h;
        OK(step(c, t, next - t, fmi2True));
        t = next;
    }
    double used = cpu_now() - c0;
    ((fmi2FreeInstanceTYPE *)sym(lib, "fmi2FreeInstance"))(c);
    return used;
}

/* One run of GearPair3.fmu (mode 0: no early return, 1: with Event Mode, 2: without):
 * CPU seconds of the steps; *calls gets the fmi3DoStep calls, *early the early returns. */
static double run3(void *lib, const char *res, const char *token, double h, double span,
                   int mode, long *calls, long *early) {
    fmi3Instance c = ((fmi3InstantiateCoSimulationTYPE *)sym(lib, "fmi3InstantiateCoSimulation"))(
        "b3", token, res, fmi3False, fmi3False, mode == 1, mode != 0, NULL, 0, NULL, log3_,
        NULL);
    if (!c) exit(1);
    fmi3UpdateDiscreteStatesTYPE *update =
        (fmi3UpdateDiscreteStatesTYPE *)sym(lib, "fmi3UpdateDiscreteStates");
    fmi3EnterStepModeTYPE *enter_step = (fmi3EnterStepModeTYPE *)sym(lib, "fmi3EnterStepMode");
    fmi3EnterEventModeTYPE *enter_event = (fmi3EnterEventModeTYPE *)sym(lib, "fmi3EnterEventMode");
    fmi3Boolean more, term, a, b, defined, event, er;
    fmi3Float64 next_ev, last;
    OK(((fmi3EnterInitializationModeTYPE *)sym(lib, "fmi3EnterInitializationMode"))(
        c, fmi3False, 0.0, 0.0, fmi3False, 0.0));
    if (n_set)
        OK(((fmi3SetFloat64TYPE *)sym(lib, "fmi3SetFloat64"))(c, vr_set, (size_t)n_set, val_set,
                                                               (size_t)n_set));
    OK(((fmi3ExitInitializationModeTYPE *)sym(lib, "fmi3ExitInitializationMode"))(c));
    if (mode == 1) {
        OK(update(c, &more, &term, &a, &b, &defined, &next_ev));
        OK(enter_step(c));
    }
    fmi3DoStepTYPE *step = (fmi3DoStepTYPE *)sym(lib, "fmi3DoStep");
    long n = (long)(span / h + 0.5), k = 0;
    *calls = *early = 0;
    double c0 = cpu_now(), t = 0.0;
    while (k < n) {
        double next = (double)(k + 1) * h;
        OK(step(c, t, next - t, fmi3True, &event, &term, &er, &last));
        ++*calls;
        if (er && last < next) {
            t = last;
            ++*early;
        } else {
            t = next;
            k++;
        }
        if (event) {
            OK(enter_event(c));
            OK(update(c, &more, &term, &a, &b, &defined, &next_ev));
            OK(enter_step(c));
        }
    }
    double used = cpu_now() - c0;
    ((fmi3FreeInstanceTYPE *)sym(lib, "fmi3FreeInstance"))(c);
    return used;
}

int main(int argc, char **argv) {
    if (argc < 8) {
        fprintf(stderr, "usage: %s UNZIP2 GUID2 UNZIP3 TOKEN3 H SPAN ROUNDS [VR=VALUE ...]\n",
                argv[0]);
        return 2;
    }
    double h = strtod(argv[5], NULL), span = strtod(argv[6], NULL);
    int rounds = atoi(argv[7]);
    for (int a = 8; a < argc && n_set < MAXV; a++) {
        vr_set[n_set] = (unsigned)strtoul(argv[a], NULL, 10);
        val_set[n_set++] = strtod(strchr(argv[a], '=') + 1, NULL);
    }
    char path[4096], uri[4200], res[4200];
    snprintf(path, sizeof path, "%s/binaries/linux64/GearPair.so", argv[1]);
    void *lib2 = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    snprintf(path, sizeof path, "%s/binaries/x86_64-linux/GearPair3.so", argv[3]);
    void *lib3 = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!lib2 || !lib3) {
        fprintf(stderr, "dlopen: %s\n", dlerror());
        return 2;
    }
    snprintf(uri, sizeof uri, "file://%s/resources", argv[1]);
    snprintf(res, sizeof res, "%s/resources/", argv[3]);
    const char *names[4] = {"fmi2", "fmi3", "fmi3_events", "fmi3_early"};
    double best[4] = {1e300, 1e300, 1e300, 1e300};
    long calls[4] = {0}, early[4] = {0};
    for (int r = 0; r < rounds; r++)
        for (int v = 0; v < 4; v++) {
            double s = v == 0 ? run2(lib2, uri, argv[2], h, span)
                              : run3(lib3, res, argv[4], h, span, v - 1, &calls[v], &early[v]);
            if (s < best[v]) best[v] = s;
        }
    calls[0] = (long)(span / h + 0.5);
    for (int v = 0; v < 4; v++)
        printf("%s %.4f %.1f %.1f\n", names[v], best[v] / (span / h) * 1e6, calls[v] / span,
               early[v] / span);
    return 0;
}
