/* Per-step cost of an FMI 2.0 co-simulation FMU driven from C, as a co-simulation master
 * drives it: each communication step sets the Real inputs, calls fmi2DoStep and gets the
 * outputs. Used by c_host_steps.py (which builds it, and runs it with the environment a
 * pythonfmu FMU needs); the FMU's results are not printed.
 *
 * Usage:
 *   step_timer UNZIPDIR MODEL_ID GUID H N REPEATS [-r VR=V]... [-u VRS] [-o VRS] [-n VRS]
 *     H, N, REPEATS  communication step (s); steps per timed block; timed blocks (after one
 *                    untimed warm-up block)
 *     -r VR=V        set a Real (parameter or input) before initialization; repeatable
 *     -u VR,VR,...   Real inputs set to their start value (-r) before every step
 *     -o VR,VR,...   Real outputs got after every step
 *     -n VR,VR,...   Integer outputs got after every step
 * Prints one JSON line: the best block's wall-clock and process CPU time per step (us).
 */
#define _POSIX_C_SOURCE 200809L
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "fmi2Functions.h"

#define MAXV 64

static void logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                   fmi2String category, fmi2String message, ...) {
    (void)env;
    (void)category;
    va_list ap;
    va_start(ap, message);
    fprintf(stderr, "[%s|%d] ", instance ? instance : "?", (int)status);
    vfprintf(stderr, message, ap);
    fputc('\n', stderr);
    va_end(ap);
}

static void *sym(void *lib, const char *name) {
    void *f = dlsym(lib, name);
    if (!f) {
        fprintf(stderr, "missing symbol %s: %s\n", name, dlerror());
        exit(1);
    }
    return f;
}

static int parse_list(const char *s, unsigned *out) {
    int n = 0;
    char *copy = strdup(s), *save = NULL;
    for (char *tok = strtok_r(copy, ",", &save); tok && n < MAXV;
         tok = strtok_r(NULL, ",", &save))
        out[n++] = (unsigned)strtoul(tok, NULL, 10);
    free(copy);
    return n;
}

static double seconds(clockid_t clock) {
    struct timespec ts;
    clock_gettime(clock, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

#define CHECK(call)                                                                  \
    do {                                                                             \
        fmi2Status st_ = (call);                                                     \
        if (st_ > fmi2Warning) {                                                     \
            fprintf(stderr, "%s returned status %d\n", #call, (int)st_);             \
            fflush(stderr);                                                          \
            _exit(1);                                                                \
        }                                                                            \
    } while (0)

int main(int argc, char **argv) {
    if (argc < 7) {
        fprintf(stderr, "usage: %s UNZIPDIR MODEL_ID GUID H N REPEATS [-r VR=V] [-u VRS] "
                        "[-o VRS] [-n VRS]\n", argv[0]);
        return 2;
    }
    const char *dir = argv[1], *model = argv[2], *guid = argv[3];
    double h = strtod(argv[4], NULL);
    long n = strtol(argv[5], NULL, 10), repeats = strtol(argv[6], NULL, 10);
    unsigned rvr[MAXV], uvr[MAXV], orvr[MAXV], oivr[MAXV];
    double rval[MAXV], uval[MAXV];
    int n_r = 0, n_u = 0, n_or = 0, n_oi = 0;
    for (int a = 7; a + 1 < argc; a += 2) {
        const char *opt = argv[a], *arg = argv[a + 1];
        if (!strcmp(opt, "-r") && n_r < MAXV) {
            rvr[n_r] = (unsigned)strtoul(arg, NULL, 10);
            rval[n_r++] = strtod(strchr(arg, '=') + 1, NULL);
        } else if (!strcmp(opt, "-u")) {
            n_u = parse_list(arg, uvr);
        } else if (!strcmp(opt, "-o")) {
            n_or = parse_list(arg, orvr);
        } else if (!strcmp(opt, "-n")) {
            n_oi = parse_list(arg, oivr);
        } else {
            fprintf(stderr, "unknown option %s\n", opt);
            return 2;
        }
    }
    for (int j = 0; j < n_u; j++) { /* each input is held at the value set with -r */
        uval[j] = 0.0;
        for (int i = 0; i < n_r; i++)
            if (rvr[i] == uvr[j]) uval[j] = rval[i];
    }

    char path[4096], uri[4200];
    snprintf(path, sizeof path, "%s/binaries/linux64/%s.so", dir, model);
    snprintf(uri, sizeof uri, "file://%s/resources", dir);
    void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fprintf(stderr, "dlopen %s: %s\n", path, dlerror());
        return 1;
    }
    fmi2InstantiateTYPE *instantiate = (fmi2InstantiateTYPE *)sym(lib, "fmi2Instantiate");
    fmi2SetupExperimentTYPE *setup = (fmi2SetupExperimentTYPE *)sym(lib, "fmi2SetupExperiment");
    fmi2EnterInitializationModeTYPE *enter =
        (fmi2EnterInitializationModeTYPE *)sym(lib, "fmi2EnterInitializationMode");
    fmi2ExitInitializationModeTYPE *exit_init =
        (fmi2ExitInitializationModeTYPE *)sym(lib, "fmi2ExitInitializationMode");
    fmi2SetRealTYPE *set_real = (fmi2SetRealTYPE *)sym(lib, "fmi2SetReal");
    fmi2GetRealTYPE *get_real = (fmi2GetRealTYPE *)sym(lib, "fmi2GetReal");
    fmi2GetIntegerTYPE *get_int = (fmi2GetIntegerTYPE *)sym(lib, "fmi2GetInteger");
    fmi2DoStepTYPE *do_step = (fmi2DoStepTYPE *)sym(lib, "fmi2DoStep");

    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    double t_load = seconds(CLOCK_MONOTONIC);
    fmi2Component c = instantiate("timer", fmi2CoSimulation, guid, uri, &cb, fmi2False,
                                  fmi2False);
    if (!c) {
        fprintf(stderr, "fmi2Instantiate failed\n");
        return 1;
    }
    CHECK(setup(c, fmi2False, 0.0, 0.0, fmi2False, 0.0));
    if (n_r) CHECK(set_real(c, rvr, (size_t)n_r, rval));
    CHECK(enter(c));
    CHECK(exit_init(c));
    double t = 0.0, rout[MAXV];
    int iout[MAXV];
    double first_step = 0.0, best_wall = 1e300, best_cpu = 1e300;
    for (long r = 0; r <= repeats; r++) {
        double w0 = seconds(CLOCK_MONOTONIC), c0 = seconds(CLOCK_PROCESS_CPUTIME_ID);
        for (long k = 0; k < n; k++) {
            if (n_u) CHECK(set_real(c, uvr, (size_t)n_u, uval));
            CHECK(do_step(c, t, h, fmi2True));
            t += h;
            if (n_or) CHECK(get_real(c, orvr, (size_t)n_or, rout));
            if (n_oi) CHECK(get_int(c, oivr, (size_t)n_oi, iout));
            if (r == 0 && k == 0) first_step = seconds(CLOCK_MONOTONIC) - t_load;
        }
        double wall = (seconds(CLOCK_MONOTONIC) - w0) / (double)n;
        double cpu = (seconds(CLOCK_PROCESS_CPUTIME_ID) - c0) / (double)n;
        if (r == 0) continue; /* warm-up block */
        if (wall < best_wall) best_wall = wall;
        if (cpu < best_cpu) best_cpu = cpu;
    }
    printf("{\"h\": %.17g, \"steps\": %ld, \"repeats\": %ld, \"wall_us\": %.4f, "
           "\"cpu_us\": %.4f, \"start_to_first_step_s\": %.4f}\n",
           h, n, repeats, 1e6 * best_wall, 1e6 * best_cpu, first_step);
    /* Leave without interpreter teardown: what is measured is done (docs/hosts.md). */
    fflush(stdout);
    fflush(stderr);
    _exit(0);
}
