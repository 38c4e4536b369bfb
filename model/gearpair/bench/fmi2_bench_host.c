/* Timing host for `gearpair bench`: what one co-simulation step of an FMI 2.0 FMU costs in a
 * C master, from which thread, and what its first start costs.
 *
 * It loads an extracted FMU with dlopen, instantiates it once (timed), initializes it with
 * the given start values (timed), takes a first step (timed: the first step may load or
 * compile code), then times BLOCKS blocks of N steps of the loop a master runs:
 *
 *     fmi2SetReal(inputs) ; fmi2DoStep(t, H) ; fmi2GetReal(outputs)
 *
 * on the wall clock (CLOCK_MONOTONIC) and on the stepping thread's CPU clock. It prints one
 * line
 *
 *     RESULT {"instantiate_s": ..., "initialize_s": ..., "first_step_s": ...,
 *             "block_wall_s": [...], "block_cpu_s": [...], "steps_per_block": N, "ok": 1,
 *             "threads": MODE, "instances": [{"block_wall_s": [...], "digest": ...}, ...],
 *             "total_wall_s": ...}
 *
 * and flushes it before anything else can go wrong: the caller reads that line whatever the
 * exit status. ``digest`` is a hash of the bits of every output of every timed step (equal
 * digests: equal results).
 *
 * Threads (-t MODE): "main" (default) steps in the thread that instantiated; "worker" in
 * another thread (instantiated and initialized in the main thread, as a master with a
 * thread pool does); "pair" instantiates two instances and steps them at once in two
 * threads; "serial" the same two instances one after the other in the main thread.
 * ``block_wall_s`` is the first instance's; ``total_wall_s`` spans all timed steps.
 *
 * Machine ceiling (``fmi2_bench_host --ceiling N``): no FMU; a chain of N floating-point
 * multiply-adds run twice one after the other in the main thread, then twice at once in two
 * threads, printing RESULT {"ok": 1, "serial_s": ..., "pair_s": ...}. Their ratio is what
 * two threads of this machine deliver at best (2 on two free cores; less where the cores are
 * hyperthreads of one or shared with other guests): the yardstick of "pair".
 *
 * Build (the FMI 2 headers ship with fmpy, in fmpy/c-code):
 *     gcc -O2 -std=c99 -I"$FMPY/c-code" -o fmi2_bench_host fmi2_bench_host.c -ldl -lpthread
 * Usage:
 *     fmi2_bench_host DIR MODEL_ID GUID H N BLOCKS IN_VRS IN_VALUES OUT_VRS
 *                     [-r|-i|-b VR=V]... [-t main|worker|pair|serial]
 *     fmi2_bench_host --ceiling N
 *   DIR the extracted FMU; IN_VRS, OUT_VRS comma-separated Real value references; IN_VALUES
 *   the inputs' values (comma separated, held constant); -r / -i / -b set a Real / Integer /
 *   Boolean (0 or 1) start value before initialization (repeatable).
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <pthread.h>
#include <stdint.h>
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

/* One instance and its timed loop (`steps`, run in whichever thread the mode says). */
typedef struct {
    fmi2Component c;
    fmi2SetRealTYPE *set_real;
    fmi2DoStepTYPE *do_step;
    fmi2GetRealTYPE *get_real;
    const unsigned *in_vr, *out_vr;
    const double *in_val;
    double out_val[MAXV], h, wall[MAXB], cpu[MAXB];
    int n_in, n_out, status;
    long n, blocks;
    uint64_t digest; /* FNV-1a over the bits of every output of every timed step */
} Run;

static void *steps(void *arg) {
    Run *r = arg;
    fmi2Component c = r->c;
    int st = fmi2OK;
    for (long b = 0; b < r->blocks && st <= fmi2Warning; b++) {
        double w0 = now(CLOCK_MONOTONIC), c0 = now(CLOCK_THREAD_CPUTIME_ID);
        for (long k = 0; k < r->n; k++) {
            double t = (double)(b * r->n + k + 1) * r->h; /* the master's grid, i*h */
            st = r->set_real(c, r->in_vr, (size_t)r->n_in, r->in_val);
            if (st <= fmi2Warning) st = r->do_step(c, t, r->h, fmi2True);
            if (st <= fmi2Warning) st = r->get_real(c, r->out_vr, (size_t)r->n_out, r->out_val);
            if (st > fmi2Warning) break;
            for (int j = 0; j < r->n_out; j++) {
                uint64_t bits;
                memcpy(&bits, &r->out_val[j], sizeof bits);
                r->digest = (r->digest ^ bits) * 1099511628211ull;
            }
        }
        r->wall[b] = now(CLOCK_MONOTONIC) - w0;
        r->cpu[b] = now(CLOCK_THREAD_CPUTIME_ID) - c0;
    }
    r->status = st;
    return NULL;
}

static void print_times(const char *key, const double *v, long n) {
    printf("\"%s\": [", key);
    for (long b = 0; b < n; b++) printf("%s%.9g", b ? ", " : "", v[b]);
    printf("]");
}

/* The arithmetic of the machine ceiling: a dependent chain, no memory traffic. */
static void *spin(void *arg) {
    long n = *(const long *)arg;
    volatile double x = 1.0;
    double y = x;
    for (long k = 0; k < n; k++) y = y * 1.0000001 + 1e-9;
    x = y;
    return NULL;
}

static int ceiling(long n) {
    pthread_t th[2];
    double w0 = now(CLOCK_MONOTONIC);
    spin(&n);
    spin(&n);
    double serial = now(CLOCK_MONOTONIC) - w0;
    w0 = now(CLOCK_MONOTONIC);
    for (int i = 0; i < 2; i++)
        if (pthread_create(&th[i], NULL, spin, &n)) return fail("pthread_create", -1);
    for (int i = 0; i < 2; i++) pthread_join(th[i], NULL);
    printf("RESULT {\"ok\": 1, \"serial_s\": %.9g, \"pair_s\": %.9g}\n", serial,
           now(CLOCK_MONOTONIC) - w0);
    fflush(stdout);
    return 0;
}

int main(int argc, char **argv) {
    if (argc == 3 && !strcmp(argv[1], "--ceiling")) return ceiling(strtol(argv[2], NULL, 10));
    if (argc < 10) {
        fprintf(stderr, "usage: %s DIR MODEL_ID GUID H N BLOCKS IN_VRS IN_VALUES OUT_VRS "
                        "[-r|-i|-b VR=V]...\n", argv[0]);
        return 2;
    }
    const char *dir = argv[1], *model = argv[2], *guid = argv[3];
    double h = strtod(argv[4], NULL), buf[MAXV];
    long n = strtol(argv[5], NULL, 10), blocks = strtol(argv[6], NULL, 10);
    unsigned in_vr[MAXV], out_vr[MAXV], start_vr[MAXV], int_vr[MAXV], bool_vr[MAXV];
    double in_val[MAXV], start_val[MAXV];
    int int_val[MAXV], n_start = 0, n_int = 0, n_bool = 0;
    fmi2Boolean bool_val[MAXV];
    int n_in = numbers(argv[7], buf);
    for (int k = 0; k < n_in; k++) in_vr[k] = (unsigned)buf[k];
    if (numbers(argv[8], in_val) != n_in || n_in < 0) return 2;
    int n_out = numbers(argv[9], buf);
    if (n_out < 0) return 2;
    for (int k = 0; k < n_out; k++) out_vr[k] = (unsigned)buf[k];
    if (blocks < 1 || blocks > MAXB || n < 1 || !(h > 0.0)) return 2;
    const char *mode = "main";
    for (int a = 10; a + 1 < argc; a += 2) {
        if (!strcmp(argv[a], "-t")) {
            mode = argv[a + 1];
            continue;
        }
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
    int n_inst = (!strcmp(mode, "pair") || !strcmp(mode, "serial")) ? 2 : 1;
    Run run[2];
    double t0 = now(CLOCK_MONOTONIC), t1 = t0, t2 = t0, t3 = t0;
    for (int i = 0; i < n_inst; i++) {
        Run *r = &run[i];
        memset(r, 0, sizeof *r);
        r->set_real = set_real;
        r->do_step = do_step;
        r->get_real = get_real;
        r->in_vr = in_vr;
        r->in_val = in_val;
        r->out_vr = out_vr;
        r->n_in = n_in;
        r->n_out = n_out;
        r->h = h;
        r->n = n;
        r->blocks = blocks;
        r->digest = 1469598103934665603ull;
        double a0 = now(CLOCK_MONOTONIC);
        r->c = instantiate(i ? "bench2" : "bench", fmi2CoSimulation, guid, resources,
                           &callbacks, fmi2False, fmi2False);
        if (!i) t1 = now(CLOCK_MONOTONIC), t0 = a0;
        fmi2Component c = r->c;
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
        if (!i) t2 = now(CLOCK_MONOTONIC);
        if ((st = set_real(c, in_vr, (size_t)n_in, in_val)) > fmi2Warning)
            return fail("fmi2SetReal (inputs)", st);
        if ((st = do_step(c, 0.0, h, fmi2True)) > fmi2Warning) return fail("fmi2DoStep", st);
        if (!i) t3 = now(CLOCK_MONOTONIC);
    }

    double w0 = now(CLOCK_MONOTONIC);
    if (!strcmp(mode, "main") || !strcmp(mode, "serial")) {
        for (int i = 0; i < n_inst; i++) steps(&run[i]);
    } else if (!strcmp(mode, "worker") || !strcmp(mode, "pair")) {
        pthread_t th[2];
        for (int i = 0; i < n_inst; i++)
            if (pthread_create(&th[i], NULL, steps, &run[i])) return fail("pthread_create", -1);
        for (int i = 0; i < n_inst; i++) pthread_join(th[i], NULL);
    } else {
        return 2;
    }
    double total = now(CLOCK_MONOTONIC) - w0;
    for (int i = 0; i < n_inst; i++)
        if (run[i].status > fmi2Warning) return fail("the step loop", run[i].status);
    printf("RESULT {\"ok\": 1, \"threads\": \"%s\", \"instantiate_s\": %.9g, "
           "\"initialize_s\": %.9g, \"first_step_s\": %.9g, \"steps_per_block\": %ld, "
           "\"last_output\": %.17g, \"total_wall_s\": %.9g, ", mode, t1 - t0, t2 - t1,
           t3 - t2, n, n_out ? run[0].out_val[0] : 0.0, total);
    print_times("block_wall_s", run[0].wall, blocks);
    printf(", ");
    print_times("block_cpu_s", run[0].cpu, blocks);
    printf(", \"instances\": [");
    for (int i = 0; i < n_inst; i++) {
        printf("%s{\"digest\": \"%016llx\", ", i ? ", " : "",
               (unsigned long long)run[i].digest);
        print_times("block_wall_s", run[i].wall, blocks);
        printf(", ");
        print_times("block_cpu_s", run[i].cpu, blocks);
        printf("}");
    }
    printf("]}\n");
    fflush(stdout);
    fflush(stderr);
    for (int i = 0; i < n_inst; i++) {
        terminate(run[i].c);
        free_instance(run[i].c);
    }
    return 0;
}
