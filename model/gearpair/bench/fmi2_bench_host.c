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
 * "interleaved" runs every mode in each of BLOCKS rounds, back to back (`interleave`), so
 * that the ratios of modes compare times taken a fraction of a second apart: seven
 * instances, two serial (the first also "main"), one worker, two pair, a twin that this
 * process and a forked copy of it step at once (two instances that share nothing: the
 * machine's ceiling for two) and one "floor" at 10 H (N / 10 steps a block, N a multiple
 * of 10: the same model time at the engine's bulk cost). With -c SPIN each round also runs
 * a dependent chain of SPIN floating-point multiply-adds (no memory traffic) twice one
 * after the other, then twice at once in two threads. The RESULT line then also has
 * "rounds": per round the wall times main_s, worker_s, serial_s (both serial blocks),
 * pair_s and procs_s (first start to last end of the two blocks), floor_s, spin_serial_s
 * and spin_pair_s, and twin_digest, the forked copy's digest.
 *
 * "instances" instantiates and initializes BLOCKS instances one after the other in the main
 * thread (each also takes its first step) and steps none further: the RESULT line then has
 * "setup_s" (per instance, fmi2Instantiate to the end of fmi2ExitInitializationMode) and
 * "rss_kb" (the process's resident memory after each, from /proc/self/statm).
 *
 * "native" (with -x GO,BACK) runs BLOCKS rounds of one instance's block of N steps and of
 * the same block of the engine's native step in another process (gearpair/bench/
 * nativestep.py: the engine's compiled step called at its C address, as the FMU it replaced
 * called it), which steps block b when this host writes b (an int64) to the pipe GO and
 * answers on BACK with its wall and CPU time (two doubles) and its digest so far (uint64);
 * which of the two goes first alternates from round to round. The RESULT line then also has
 * "native": its wall_s and cpu_s per round and its digest after the last. This host writes
 * -1 to GO at the end.
 *
 * "peak_rss_kb" is the process's peak resident memory when it prints (VmHWM).
 *
 * Build (the FMI 2 headers ship with fmpy, in fmpy/c-code):
 *     gcc -O2 -std=c99 -I"$FMPY/c-code" -o fmi2_bench_host fmi2_bench_host.c -ldl -lpthread
 * Usage:
 *     fmi2_bench_host DIR MODEL_ID GUID H N BLOCKS IN_VRS IN_VALUES OUT_VRS
 *                     [-r|-i|-b VR=V]... [-t main|worker|pair|serial|interleaved|native]
 *                     [-c SPIN] [-x GO,BACK]
 *   DIR the extracted FMU; IN_VRS, OUT_VRS comma-separated Real value references; IN_VALUES
 *   the inputs' values (comma separated, held constant); -r / -i / -b set a Real / Integer /
 *   Boolean (0 or 1) start value before initialization (repeatable).
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <pthread.h>
#include <sched.h>
#include <stdint.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

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

/* The process's resident memory (kB), or 0 where /proc is not there. */
static long rss_kb(void) {
    long size = 0, resident = 0;
    FILE *f = fopen("/proc/self/statm", "r");
    if (f) {
        if (fscanf(f, "%ld %ld", &size, &resident) != 2) resident = 0;
        fclose(f);
    }
    return resident * (sysconf(_SC_PAGESIZE) / 1024);
}

/* The process's peak resident memory so far (kB, VmHWM of /proc/self/status), or 0. */
static long peak_kb(void) {
    char line[256];
    long kb = 0;
    FILE *f = fopen("/proc/self/status", "r");
    if (!f) return 0;
    while (fgets(line, sizeof line, f))
        if (!strncmp(line, "VmHWM:", 6)) kb = strtol(line + 6, NULL, 10);
    fclose(f);
    return kb;
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
    double out_val[MAXV], h, wall[MAXB], cpu[MAXB], began[MAXB], ended[MAXB];
    int n_in, n_out, status;
    long n, blocks, cur; /* cur: the block `one_block` runs */
    uint64_t digest; /* FNV-1a over the bits of every output of every timed step */
} Run;

/* Block b of r: N steps on the master's grid i*h, timed (wall, thread CPU, and the wall
 * clock's readings at its start and end). */
static void block(Run *r, long b) {
    fmi2Component c = r->c;
    int st = r->status;
    double w0 = now(CLOCK_MONOTONIC), c0 = now(CLOCK_THREAD_CPUTIME_ID);
    for (long k = 0; k < r->n && st <= fmi2Warning; k++) {
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
    double w1 = now(CLOCK_MONOTONIC);
    r->wall[b] = w1 - w0;
    r->cpu[b] = now(CLOCK_THREAD_CPUTIME_ID) - c0;
    r->began[b] = w0;
    r->ended[b] = w1;
    r->status = st;
}

static void *steps(void *arg) {
    Run *r = arg;
    for (long b = 0; b < r->blocks && r->status <= fmi2Warning; b++) block(r, b);
    return NULL;
}

static void *one_block(void *arg) {
    Run *r = arg;
    block(r, r->cur);
    return NULL;
}

static void print_times(const char *key, const double *v, long n) {
    printf("\"%s\": [", key);
    for (long b = 0; b < n; b++) printf("%s%.9g", b ? ", " : "", v[b]);
    printf("]");
}

/* The arithmetic of the machine's two-thread ceiling: a dependent chain, no memory
 * traffic. */
static void *spin(void *arg) {
    long n = *(const long *)arg;
    volatile double x = 1.0;
    double y = x;
    for (long k = 0; k < n; k++) y = y * 1.0000001 + 1e-9;
    x = y;
    return NULL;
}

/* fn(arg[i]) for i < k (at most 2) at once, one thread each, on the CPUs `cpus`; returns
 * once all have ended (0: a thread could not be made). */
static int in_threads(void *(*fn)(void *), void **arg, int k, const cpu_set_t *cpus) {
    pthread_t th[2];
    pthread_attr_t attr;
    int made = 0;
    if (pthread_attr_init(&attr)) return 0;
    pthread_attr_setaffinity_np(&attr, sizeof *cpus, cpus);
    for (; made < k; made++)
        if (pthread_create(&th[made], &attr, fn, arg[made])) break;
    for (int i = 0; i < made; i++) pthread_join(th[i], NULL);
    pthread_attr_destroy(&attr);
    return made == k;
}

/* The spin twice one after the other, then twice at once in two threads: the wall times
 * (1: a thread could not be made). */
static int spin_twice(long n, double *serial, double *pair, const cpu_set_t *cpus) {
    void *arg[2] = {&n, &n};
    double w0 = now(CLOCK_MONOTONIC);
    spin(&n);
    spin(&n);
    *serial = now(CLOCK_MONOTONIC) - w0;
    w0 = now(CLOCK_MONOTONIC);
    int ok = in_threads(spin, arg, 2, cpus);
    *pair = now(CLOCK_MONOTONIC) - w0;
    return !ok;
}

/* Interleaved mode: instances by role. The two serial ones step in the main thread one
 * after the other (the first is also "main"), WORKER in a thread of its own, the two PAIR
 * ones at once in two threads, FLOOR in the main thread at 10 H (N / 10 steps a block: the
 * same stretch of model time at the engine's bulk cost). TWIN steps in the main thread while
 * a forked copy of this process steps its own copy of TWIN at the same time (`twin_block`):
 * two instances that share nothing at all, the machine's ceiling for two of them. */
enum { SERIAL1, SERIAL2, WORKER, PAIR1, PAIR2, TWIN, FLOOR, N_MIXED };

/* The per-round wall times of the RESULT line's "rounds", by name. */
enum { MAIN_S, WORKER_S, SERIAL_S, PAIR_S, PROCS_S, FLOOR_S, SPIN_SERIAL_S, SPIN_PAIR_S,
       N_SERIES };
static const char *const SERIES[N_SERIES] = {"main_s",  "worker_s",      "serial_s",
                                             "pair_s",  "procs_s",       "floor_s",
                                             "spin_serial_s", "spin_pair_s"};
typedef struct {
    double s[N_SERIES][MAXB];
    uint64_t twin_digest; /* the forked copy's TWIN */
} Rounds;

/* The wall time from the first start to the last end of block b of two runs. */
static double span(double began0, double ended0, double began1, double ended1) {
    return (ended0 > ended1 ? ended0 : ended1) - (began0 < began1 ? began0 : began1);
}

/* The forked copy of this process: steps its copy of TWIN block by block as told through
 * `go` (a block number; -1: exit) and answers through `back` (the block's start and end on
 * the shared monotonic clock, its digest so far). It runs no Python and leaves by _exit: the
 * interpreter it inherited is never touched. */
static void twin_child(Run *twin, int go, int back) {
    long b;
    while (read(go, &b, sizeof b) == (ssize_t)sizeof b && b >= 0) {
        block(twin, b);
        double times[2] = {twin->began[b], twin->ended[b]};
        if (write(back, times, sizeof times) != (ssize_t)sizeof times ||
            write(back, &twin->digest, sizeof twin->digest) != (ssize_t)sizeof twin->digest)
            break;
    }
    _exit(twin->status > fmi2Warning);
}

/* Block b of TWIN here and in the forked copy at once: the span of the two (-1.0: the copy
 * did not answer). */
static double twin_block(Run *twin, long b, int go, int back, uint64_t *digest) {
    double times[2];
    if (write(go, &b, sizeof b) != (ssize_t)sizeof b) return -1.0;
    block(twin, b);
    if (read(back, times, sizeof times) != (ssize_t)sizeof times ||
        read(back, digest, sizeof *digest) != (ssize_t)sizeof *digest)
        return -1.0;
    return span(twin->began[b], twin->ended[b], times[0], times[1]);
}

/* Block b of each given instance at once, one thread each, on the CPUs `cpus` (0:
 * a thread could not be made). */
static int together(Run **r, int k, long b, const cpu_set_t *cpus) {
    for (int i = 0; i < k; i++) r[i]->cur = b;
    return in_threads(one_block, (void **)r, k, cpus);
}

/* Round b of every mode back to back, so that each ratio compares times a few tens of
 * milliseconds apart in the same stretch of model time: on a machine whose speed drifts,
 * runs of one mode after another compare different speeds, not different modes. With
 * spin_n > 0 each round also runs the machine ceiling's arithmetic (`spin_twice`).
 * Returns 0, or 1 when a thread or the forked copy could not be made or did not answer. */
static int interleave(Run *run, long blocks, long spin_n, Rounds *out) {
    /* The main thread and the worker run on one CPU, the one the main thread is on: the
     * vCPUs of a virtual machine can run at different speeds at the same moment (a busy
     * sibling hyperthread on the host), and worker / main is to compare threads, not CPUs.
     * The pair, the forked copy and the spin get every CPU the process may use. */
    cpu_set_t all, one;
    if (sched_getaffinity(0, sizeof all, &all)) return 1;
    CPU_ZERO(&one);
    CPU_SET(sched_getcpu(), &one);
    if (pthread_setaffinity_np(pthread_self(), sizeof one, &one)) return 1;
    int go[2], back[2];
    if (pipe(go) || pipe(back)) return 1;
    fflush(stdout); /* the copy must not print this process's buffered output again */
    pid_t child = fork();
    if (child < 0) return 1;
    if (child == 0) {
        close(go[1]);
        close(back[0]);
        sched_setaffinity(0, sizeof all, &all);
        twin_child(&run[TWIN], go[0], back[1]);
    }
    close(go[0]);
    close(back[1]);
    int failed = 0;
    for (long b = 0; b < blocks && !failed; b++) {
        Run *pair[2] = {&run[PAIR1], &run[PAIR2]}, *worker = &run[WORKER];
        block(&run[SERIAL1], b);
        failed |= !together(&worker, 1, b, &one);
        block(&run[SERIAL2], b);
        block(&run[FLOOR], b);
        failed |= !together(pair, 2, b, &all);
        double *got[N_SERIES];
        for (int k = 0; k < N_SERIES; k++) got[k] = &out->s[k][b];
        *got[PROCS_S] = twin_block(&run[TWIN], b, go[1], back[0], &out->twin_digest);
        failed |= *got[PROCS_S] < 0.0;
        *got[MAIN_S] = run[SERIAL1].wall[b];
        *got[WORKER_S] = run[WORKER].wall[b];
        *got[SERIAL_S] = run[SERIAL1].wall[b] + run[SERIAL2].wall[b];
        *got[PAIR_S] = span(pair[0]->began[b], pair[0]->ended[b], pair[1]->began[b],
                            pair[1]->ended[b]);
        *got[FLOOR_S] = run[FLOOR].wall[b];
        *got[SPIN_SERIAL_S] = *got[SPIN_PAIR_S] = 0.0;
        if (spin_n > 0 && spin_twice(spin_n, got[SPIN_SERIAL_S], got[SPIN_PAIR_S], &all))
            failed = 1;
    }
    long quit = -1;
    if (write(go[1], &quit, sizeof quit) != (ssize_t)sizeof quit) failed = 1;
    close(go[1]);
    close(back[0]);
    int status = 0;
    if (waitpid(child, &status, 0) != child || !WIFEXITED(status) || WEXITSTATUS(status))
        failed = 1;
    pthread_setaffinity_np(pthread_self(), sizeof all, &all);
    return failed;
}

/* What the native step's process answered, per round (mode "native"). */
typedef struct {
    double wall[MAXB], cpu[MAXB];
    uint64_t digest;
} Native;

/* Block b of the native step in the process at the other end of the pipes `go` and
 * `back` (1: it did not answer). */
static int native_block(long b, int go, int back, Native *out) {
    double times[2];
    if (write(go, &b, sizeof b) != (ssize_t)sizeof b ||
        read(back, times, sizeof times) != (ssize_t)sizeof times ||
        read(back, &out->digest, sizeof out->digest) != (ssize_t)sizeof out->digest)
        return 1;
    out->wall[b] = times[0];
    out->cpu[b] = times[1];
    return 0;
}

/* The native step's rounds: block b of this host's instance and block b of the native
 * step, the first of the two alternating (on a machine whose speed drifts, neither always
 * runs first). Returns 0, or 1 when the other process did not answer. */
static int native_rounds(Run *run, long blocks, int go, int back, Native *out) {
    int failed = 0;
    for (long b = 0; b < blocks && !failed && run->status <= fmi2Warning; b++) {
        if (b % 2) failed |= native_block(b, go, back, out);
        block(run, b);
        if (!(b % 2)) failed |= native_block(b, go, back, out);
    }
    long quit = -1;
    if (write(go, &quit, sizeof quit) != (ssize_t)sizeof quit) failed = 1;
    return failed;
}

static void print_rounds(const Rounds *r, long blocks) {
    printf(", \"rounds\": {");
    for (int k = 0; k < N_SERIES; k++) {
        printf("%s", k ? ", " : "");
        print_times(SERIES[k], r->s[k], blocks);
    }
    printf(", \"twin_digest\": \"%016llx\"}", (unsigned long long)r->twin_digest);
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
    long spin_n = 0;
    int go = -1, back = -1;
    for (int a = 10; a + 1 < argc; a += 2) {
        if (!strcmp(argv[a], "-t")) {
            mode = argv[a + 1];
            continue;
        }
        if (!strcmp(argv[a], "-x")) {
            if (sscanf(argv[a + 1], "%d,%d", &go, &back) != 2) return 2;
            continue;
        }
        if (!strcmp(argv[a], "-c")) {
            spin_n = strtol(argv[a + 1], NULL, 10);
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
    int mixed = !strcmp(mode, "interleaved"), many = !strcmp(mode, "instances");
    int native = !strcmp(mode, "native");
    if (native && (go < 0 || back < 0)) return 2;
    int n_inst = mixed ? N_MIXED : many ? (int)blocks
                 : (!strcmp(mode, "pair") || !strcmp(mode, "serial")) ? 2 : 1;
    if (mixed && n % 10) return 2; /* the floor instance steps n / 10 times 10 h */
    static Run run[MAXB > N_MIXED ? MAXB : N_MIXED];
    double setup_s[MAXB];
    long rss[MAXB];
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
        r->h = (mixed && i == FLOOR) ? 10.0 * h : h;
        r->n = (mixed && i == FLOOR) ? n / 10 : n;
        r->blocks = blocks;
        r->digest = 1469598103934665603ull;
        double a0 = now(CLOCK_MONOTONIC);
        char name[16];
        snprintf(name, sizeof name, "bench%d", i + 1);
        r->c = instantiate(name, fmi2CoSimulation, guid, resources, &callbacks, fmi2False,
                           fmi2False);
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
        if (many) {
            setup_s[i] = now(CLOCK_MONOTONIC) - a0;
            rss[i] = rss_kb();
        }
        if ((st = set_real(c, in_vr, (size_t)n_in, in_val)) > fmi2Warning)
            return fail("fmi2SetReal (inputs)", st);
        if ((st = do_step(c, 0.0, r->h, fmi2True)) > fmi2Warning)
            return fail("fmi2DoStep", st);
        if (!i) t3 = now(CLOCK_MONOTONIC);
    }

    double w0 = now(CLOCK_MONOTONIC);
    Rounds rounds;
    static Native nat;
    if (many) {
        /* no loop: the instances' set-up was what this mode measures */
    } else if (mixed) {
        if (interleave(run, blocks, spin_n, &rounds))
            return fail("a thread or the forked copy (interleaved mode)", -1);
    } else if (native) {
        if (native_rounds(&run[0], blocks, go, back, &nat))
            return fail("the native step's process (native mode)", -1);
    } else if (!strcmp(mode, "main") || !strcmp(mode, "serial")) {
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
    printf("RESULT {\"ok\": 1, \"peak_rss_kb\": %ld, \"threads\": \"%s\", "
           "\"instantiate_s\": %.9g, "
           "\"initialize_s\": %.9g, \"first_step_s\": %.9g, \"steps_per_block\": %ld, "
           "\"last_output\": %.17g, \"total_wall_s\": %.9g, ", peak_kb(), mode, t1 - t0,
           t2 - t1,
           t3 - t2, n, n_out ? run[0].out_val[0] : 0.0, total);
    print_times("block_wall_s", run[0].wall, blocks);
    printf(", ");
    print_times("block_cpu_s", run[0].cpu, blocks);
    if (mixed) print_rounds(&rounds, blocks);
    if (native) {
        printf(", \"native\": {");
        print_times("wall_s", nat.wall, blocks);
        printf(", ");
        print_times("cpu_s", nat.cpu, blocks);
        printf(", \"digest\": \"%016llx\"}", (unsigned long long)nat.digest);
    }
    if (many) {
        printf(", ");
        print_times("setup_s", setup_s, n_inst);
        printf(", \"rss_kb\": [");
        for (int i = 0; i < n_inst; i++) printf("%s%ld", i ? ", " : "", rss[i]);
        printf("]");
    }
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
