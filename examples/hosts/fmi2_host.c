/* A minimal FMI 2.0 co-simulation host: loads an extracted FMU's binary (dlopen on Linux,
 * LoadLibrary on Windows: fmu_dl.h), sets start values, steps it and prints the outputs
 * after every step as CSV with full precision.
 *
 * Build (the FMI 2 headers ship with fmpy, in fmpy/c-code):
 *   gcc -O2 -std=c99 -I"$(python -c 'import fmpy, os; print(os.path.dirname(fmpy.__file__))')/c-code" \
 *       -o fmi2_host fmi2_host.c -ldl
 * and for Windows x86-64 (binaries/win64; C99 printf for the same digits as on Linux):
 *   x86_64-w64-mingw32-gcc -O2 -std=c99 -D__USE_MINGW_ANSI_STDIO=1 -I<that folder> \
 *       -o fmi2_host.exe fmi2_host.c
 *
 * Usage:
 *   fmi2_host UNZIPDIR MODEL_ID GUID STEPS N [options]
 *     UNZIPDIR  the extracted FMU (the folder holding modelDescription.xml)
 *     STEPS     communication step sizes, comma separated, used in turn (cycled) for N steps
 *   options:
 *     -r VR=VALUE    set a Real (parameter or input) before initialization; repeatable
 *     -i VR=VALUE    set an Integer before initialization; repeatable
 *     -o VR,VR,...   Real outputs to print (value references)
 *     -n VR,VR,...   Integer outputs to print
 *     -t T0          start time (default 0)
 *     -d 1           unload the FMU's library (dlclose, FreeLibrary) after fmi2FreeInstance
 *     -l 1           loggingOn: information messages too (e.g. which Python and engine run)
 * Prints "time,<reals...>,<integers...>" for the initial state and after each step. Exits 0
 * when every call returned fmi2OK/fmi2Warning, else 1 (with the failing call on stderr).
 * Returns from main normally: the FMU's embedded interpreter lives until the process ends
 * and the exit is clean (docs/hosts.md).
 *
 * GearPair.fmu needs no environment variables: its binary loads the Python recorded in the
 * FMU (or the one GEARPAIR_PYTHON names; see docs/hosts.md).
 */
#define _POSIX_C_SOURCE 200809L
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "fmu_dl.h"

#define MAXV 64

static void logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                   fmi2String category, fmi2String message, ...) {
    (void)env;
    va_list ap;
    va_start(ap, message);
    fprintf(stderr, "[%s|%d|%s] ", instance ? instance : "?", (int)status,
            category ? category : "");
    vfprintf(stderr, message, ap);
    fputc('\n', stderr);
    va_end(ap);
}

static void *sym(fmu_lib lib, const char *name) {
    void *f = fmu_dlsym(lib, name);
    if (!f) {
        fprintf(stderr, "missing symbol %s: %s\n", name, fmu_dlerror());
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

#define CHECK(call)                                                                  \
    do {                                                                             \
        fmi2Status st_ = (call);                                                     \
        if (st_ > fmi2Warning) {                                                     \
            fprintf(stderr, "%s returned status %d\n", #call, (int)st_);             \
            return 1;                                                                \
        }                                                                            \
    } while (0)

int main(int argc, char **argv) {
    if (argc < 6) {
        fprintf(stderr, "usage: %s UNZIPDIR MODEL_ID GUID STEPS N [-r VR=V] [-i VR=V] "
                        "[-o VRS] [-n VRS] [-t T0]\n", argv[0]);
        return 2;
    }
    const char *dir = argv[1], *model = argv[2], *guid = argv[3];
    double steps[MAXV];
    int n_h = 0;
    {
        char *copy = strdup(argv[4]), *save = NULL;
        for (char *tok = strtok_r(copy, ",", &save); tok && n_h < MAXV;
             tok = strtok_r(NULL, ",", &save))
            steps[n_h++] = strtod(tok, NULL);
        free(copy);
    }
    long n = strtol(argv[5], NULL, 10);
    unsigned rvr[MAXV], ivr[MAXV], orvr[MAXV], oivr[MAXV];
    double rval[MAXV];
    int ival[MAXV], n_r = 0, n_i = 0, n_or = 0, n_oi = 0;
    double t = 0.0;
    int unload = 0, logging_on = 0;
    for (int a = 6; a + 1 < argc; a += 2) {
        const char *opt = argv[a], *arg = argv[a + 1];
        if (!strcmp(opt, "-r") && n_r < MAXV) {
            rvr[n_r] = (unsigned)strtoul(arg, NULL, 10);
            rval[n_r++] = strtod(strchr(arg, '=') + 1, NULL);
        } else if (!strcmp(opt, "-i") && n_i < MAXV) {
            ivr[n_i] = (unsigned)strtoul(arg, NULL, 10);
            ival[n_i++] = (int)strtol(strchr(arg, '=') + 1, NULL, 10);
        } else if (!strcmp(opt, "-o")) {
            n_or = parse_list(arg, orvr);
        } else if (!strcmp(opt, "-n")) {
            n_oi = parse_list(arg, oivr);
        } else if (!strcmp(opt, "-t")) {
            t = strtod(arg, NULL);
        } else if (!strcmp(opt, "-d")) {
            unload = atoi(arg);
        } else if (!strcmp(opt, "-l")) {
            logging_on = atoi(arg);
        } else {
            fprintf(stderr, "unknown option %s\n", opt);
            return 2;
        }
    }

    char path[4096], uri[4200];
    fmu_binary_path(dir, model, path, sizeof path);
    fmu_resource_uri(dir, uri, sizeof uri);
    fmu_lib lib = fmu_dlopen(path);
    if (!lib) {
        fprintf(stderr, "loading %s: %s\n", path, fmu_dlerror());
        return 1;
    }
    fmi2InstantiateTYPE *instantiate = (fmi2InstantiateTYPE *)sym(lib, "fmi2Instantiate");
    fmi2SetupExperimentTYPE *setup = (fmi2SetupExperimentTYPE *)sym(lib, "fmi2SetupExperiment");
    fmi2EnterInitializationModeTYPE *enter =
        (fmi2EnterInitializationModeTYPE *)sym(lib, "fmi2EnterInitializationMode");
    fmi2ExitInitializationModeTYPE *exit_init =
        (fmi2ExitInitializationModeTYPE *)sym(lib, "fmi2ExitInitializationMode");
    fmi2SetRealTYPE *set_real = (fmi2SetRealTYPE *)sym(lib, "fmi2SetReal");
    fmi2SetIntegerTYPE *set_int = (fmi2SetIntegerTYPE *)sym(lib, "fmi2SetInteger");
    fmi2GetRealTYPE *get_real = (fmi2GetRealTYPE *)sym(lib, "fmi2GetReal");
    fmi2GetIntegerTYPE *get_int = (fmi2GetIntegerTYPE *)sym(lib, "fmi2GetInteger");
    fmi2DoStepTYPE *do_step = (fmi2DoStepTYPE *)sym(lib, "fmi2DoStep");
    fmi2TerminateTYPE *terminate = (fmi2TerminateTYPE *)sym(lib, "fmi2Terminate");
    fmi2FreeInstanceTYPE *free_instance = (fmi2FreeInstanceTYPE *)sym(lib, "fmi2FreeInstance");

    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    fmi2Component c = instantiate("host", fmi2CoSimulation, guid, uri, &cb, fmi2False,
                                 logging_on ? fmi2True : fmi2False);
    if (!c) {
        fprintf(stderr, "fmi2Instantiate failed\n");
        return 1;
    }
    CHECK(setup(c, fmi2False, 0.0, t, fmi2False, 0.0));
    if (n_r) CHECK(set_real(c, rvr, (size_t)n_r, rval));
    if (n_i) CHECK(set_int(c, ivr, (size_t)n_i, ival));
    CHECK(enter(c));
    CHECK(exit_init(c));

    double rout[MAXV];
    int iout[MAXV];
    for (long k = 0; k <= n; k++) {
        if (k > 0) {
            double h = steps[(k - 1) % n_h];
            CHECK(do_step(c, t, h, fmi2True));
            t += h;
        }
        if (n_or) CHECK(get_real(c, orvr, (size_t)n_or, rout));
        if (n_oi) CHECK(get_int(c, oivr, (size_t)n_oi, iout));
        printf("%.17g", t);
        for (int j = 0; j < n_or; j++) printf(",%.17g", rout[j]);
        for (int j = 0; j < n_oi; j++) printf(",%d", iout[j]);
        putchar('\n');
    }
    CHECK(terminate(c));
    free_instance(c);
    if (unload && fmu_dlclose(lib) != 0) {
        fprintf(stderr, "unloading: %s\n", fmu_dlerror());
        return 1;
    }
    return 0;
}
