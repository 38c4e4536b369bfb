/* A C host that runs many scenes of an FMI 2.0 co-simulation FMU in one process, for
 * comparing the FMU's binaries of two platforms (tests/test_win64.py: linux64 natively,
 * win64 under Wine, whose start-up is slow): the same script gives the same text when the
 * binaries compute the same bits.
 *
 *   fmi2_scenes UNZIPDIR MODEL_ID GUID < SCRIPT
 *
 * The binary is UNZIPDIR/binaries/<platform>/MODEL_ID<suffix> (examples/hosts/fmu_dl.h).
 * SCRIPT has one command a line ('#' starts a comment); VALUES are start values Rvr=x,
 * Ivr=n, Bvr=0|1 set before initialization:
 *   outputs R,R,... I,I,...         the value references of the outputs printed (Real, Integer)
 *   location TEXT                   the resource location of the instances that follow
 *                                   (default: file:///UNZIPDIR/resources)
 *   run NAME N H VALUES             initialize, N steps of H; prints each row "NAME k t bits"
 *                                   (t and the outputs as the hex of their 64 bits)
 *   states NAME N H VALUES          N steps with the FMU state got and serialized after N/2;
 *                                   the second half replayed after fmi2SetFMUstate and in a
 *                                   fresh instance after fmi2DeSerializeFMUstate must give the
 *                                   same bits; prints the serialized size and a hash of it
 *   pair NAME N H VALUES / VALUES   two instances, each alone, then both stepped in turn in
 *                                   one thread, then each in a thread of its own at once:
 *                                   the same bits each time, and the two runs differ
 *   refuse NAME VALUES / BAD        VALUES set, then BAD set in initialization mode and
 *                                   fmi2ExitInitializationMode; when that passes, two steps,
 *                                   BAD set again in step mode (the outputs must not change)
 *                                   and one more step; prints every status
 * The FMU's log messages are printed as "log INSTANCE STATUS CATEGORY: TEXT". Exit status 0
 * when every check held (a refused call is no failure: its status is printed), else 1.
 */
#define _POSIX_C_SOURCE 200809L
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "fmu_dl.h"

#ifdef _WIN32
typedef HANDLE thread_t;
#define THREAD_FN DWORD WINAPI
#define THREAD_RET 0
static int thread_start(thread_t *t, LPTHREAD_START_ROUTINE f, void *arg) {
    *t = CreateThread(NULL, 0, f, arg, 0, NULL);
    return *t ? 0 : -1;
}
static void thread_join(thread_t t) {
    WaitForSingleObject(t, INFINITE);
    CloseHandle(t);
}
#else
#include <pthread.h>
typedef pthread_t thread_t;
#define THREAD_FN void *
#define THREAD_RET NULL
static int thread_start(thread_t *t, void *(*f)(void *), void *arg) {
    return pthread_create(t, NULL, f, arg);
}
static void thread_join(thread_t t) { pthread_join(t, NULL); }
#endif

#define MAXV 64
#define MAXTOK 128

static struct {
    fmi2InstantiateTYPE *instantiate;
    fmi2FreeInstanceTYPE *free_instance;
    fmi2SetupExperimentTYPE *setup;
    fmi2EnterInitializationModeTYPE *enter;
    fmi2ExitInitializationModeTYPE *exit_init;
    fmi2TerminateTYPE *terminate;
    fmi2SetRealTYPE *set_real;
    fmi2SetIntegerTYPE *set_int;
    fmi2SetBooleanTYPE *set_bool;
    fmi2GetRealTYPE *get_real;
    fmi2GetIntegerTYPE *get_int;
    fmi2DoStepTYPE *do_step;
    fmi2GetFMUstateTYPE *get_state;
    fmi2SetFMUstateTYPE *set_state;
    fmi2FreeFMUstateTYPE *free_state;
    fmi2SerializedFMUstateSizeTYPE *state_size;
    fmi2SerializeFMUstateTYPE *serialize;
    fmi2DeSerializeFMUstateTYPE *deserialize;
} F;

static const char *g_guid;
static char g_uri[4200];
static unsigned g_rvr[MAXV], g_ivr[MAXV];
static int g_nr, g_ni, g_failed;

typedef struct {
    char type[MAXV];
    unsigned vr[MAXV];
    double x[MAXV];
    int n;
} Values;

static void logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                   fmi2String category, fmi2String message, ...) {
    (void)env;
    char text[8192];
    va_list ap;
    va_start(ap, message);
    vsnprintf(text, sizeof text, message, ap);
    va_end(ap);
    printf("log %s %d %s: %s\n", instance ? instance : "?", (int)status,
           category ? category : "", text);
}

static void failed(const char *scene, const char *what) {
    printf("%s FAILED %s\n", scene, what);
    g_failed = 1;
}

static uint64_t bits(double x) {
    uint64_t u;
    memcpy(&u, &x, sizeof u);
    return u;
}

static uint64_t fnv1a(const unsigned char *p, size_t n) {
    uint64_t h = 1469598103934665603ull;
    for (size_t i = 0; i < n; i++) h = (h ^ p[i]) * 1099511628211ull;
    return h;
}

static int parse_values(char **tok, int ntok, Values *v) {
    v->n = 0;
    for (int i = 0; i < ntok && v->n < MAXV; i++) {
        char *eq = strchr(tok[i], '=');
        if (!eq || !strchr("RIB", tok[i][0])) {
            fprintf(stderr, "bad value %s\n", tok[i]);
            return -1;
        }
        v->type[v->n] = tok[i][0];
        v->vr[v->n] = (unsigned)strtoul(tok[i] + 1, NULL, 10);
        v->x[v->n++] = strtod(eq + 1, NULL);
    }
    return 0;
}

/* Set the values one by one; the worst status. */
static fmi2Status set_values(fmi2Component c, const Values *v) {
    fmi2Status worst = fmi2OK, st;
    for (int i = 0; i < v->n; i++) {
        if (v->type[i] == 'R') {
            st = F.set_real(c, &v->vr[i], 1, &v->x[i]);
        } else {
            fmi2Integer k = (fmi2Integer)v->x[i];
            st = v->type[i] == 'I' ? F.set_int(c, &v->vr[i], 1, &k)
                                   : F.set_bool(c, &v->vr[i], 1, &k);
        }
        if (st > worst) worst = st;
    }
    return worst;
}

static fmi2Component instantiate(const char *name) {
    static const fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    return F.instantiate(name, fmi2CoSimulation, g_guid, g_uri, &cb, fmi2False, fmi2False);
}

/* An instance initialized with v at t = 0, or NULL. */
static fmi2Component start(const char *name, const Values *v) {
    fmi2Component c = instantiate(name);
    if (!c) return NULL;
    if (F.setup(c, fmi2False, 0.0, 0.0, fmi2False, 0.0) > fmi2Warning ||
        set_values(c, v) > fmi2Warning || F.enter(c) > fmi2Warning ||
        F.exit_init(c) > fmi2Warning) {
        F.free_instance(c);
        return NULL;
    }
    return c;
}

#define ROW (1 + MAXV) /* t and the outputs */

/* The outputs at t into row (t, reals, integers). */
static int outputs(fmi2Component c, double t, double *row) {
    fmi2Integer k[MAXV];
    row[0] = t;
    if (g_nr && F.get_real(c, g_rvr, (size_t)g_nr, row + 1) > fmi2Warning) return -1;
    if (g_ni && F.get_int(c, g_ivr, (size_t)g_ni, k) > fmi2Warning) return -1;
    for (int j = 0; j < g_ni; j++) row[1 + g_nr + j] = k[j];
    return 0;
}

/* Steps k0 + 1 .. n of h from t = k0 h (accumulated as a master does: t += h), the rows
 * into rows[k]. */
static int steps(fmi2Component c, int k0, int n, double h, double t, double *rows) {
    for (int k = k0 + 1; k <= n; k++) {
        if (F.do_step(c, t, h, fmi2True) > fmi2Warning) return -1;
        t += h;
        if (outputs(c, t, rows + (size_t)k * ROW)) return -1;
    }
    return 0;
}

static double time_after(int k, double h) {
    double t = 0.0;
    for (int i = 0; i < k; i++) t += h;
    return t;
}

/* One whole run: initialize, n steps, terminate, free. */
static int run_alone(const char *name, const Values *v, int n, double h, double *rows) {
    fmi2Component c = start(name, v);
    if (!c) return -1;
    int bad = outputs(c, 0.0, rows) || steps(c, 0, n, h, 0.0, rows);
    if (!bad) bad = F.terminate(c) > fmi2Warning;
    F.free_instance(c);
    return bad ? -1 : 0;
}

static int same_rows(const double *a, const double *b, int n) {
    return !memcmp(a, b, (size_t)(n + 1) * ROW * sizeof(double));
}

static void print_rows(const char *name, const double *rows, int n) {
    for (int k = 0; k <= n; k++) {
        const double *r = rows + (size_t)k * ROW;
        printf("%s %d", name, k);
        for (int j = 0; j < 1 + g_nr + g_ni; j++) printf(" %016llx", (unsigned long long)bits(r[j]));
        putchar('\n');
    }
}

static double *new_rows(int n) { return calloc((size_t)(n + 1) * ROW, sizeof(double)); }

static void cmd_run(const char *name, int n, double h, const Values *v) {
    double *rows = new_rows(n);
    if (run_alone(name, v, n, h, rows))
        failed(name, "run");
    else
        print_rows(name, rows, n);
    free(rows);
}

static void cmd_states(const char *name, int n, double h, const Values *v) {
    double *rows = new_rows(n), *again = new_rows(n);
    int half = n / 2;
    double th = time_after(half, h);
    fmi2FMUstate s = NULL, s2 = NULL;
    size_t size = 0;
    char *bytes = NULL;
    fmi2Component c = start(name, v), d = NULL;
    if (!c || outputs(c, 0.0, rows) || steps(c, 0, half, h, 0.0, rows) ||
        F.get_state(c, &s) > fmi2Warning || F.state_size(c, s, &size) > fmi2Warning ||
        !(bytes = malloc(size)) || F.serialize(c, s, bytes, size) > fmi2Warning ||
        steps(c, half, n, h, th, rows)) {
        failed(name, "run with a state");
        goto done;
    }
    printf("%s state %zu bytes, hash %016llx\n", name, size,
           (unsigned long long)fnv1a((unsigned char *)bytes, size));
    memcpy(again, rows, (size_t)(half + 1) * ROW * sizeof(double));
    if (F.set_state(c, s) > fmi2Warning || steps(c, half, n, h, th, again))
        failed(name, "replay after fmi2SetFMUstate");
    else
        printf("%s replay after fmi2SetFMUstate %s\n", name,
               same_rows(rows, again, n) ? "identical" : "DIFFERS");
    if (!same_rows(rows, again, n)) g_failed = 1;
    memset(again + (size_t)(half + 1) * ROW, 0, (size_t)(n - half) * ROW * sizeof(double));
    char fresh[256];
    snprintf(fresh, sizeof fresh, "%s-fresh", name);
    if (!(d = instantiate(fresh)) || F.deserialize(d, bytes, size, &s2) > fmi2Warning ||
        F.set_state(d, s2) > fmi2Warning || steps(d, half, n, h, th, again))
        failed(name, "replay in a fresh instance after fmi2DeSerializeFMUstate");
    else
        printf("%s replay in a fresh instance after fmi2DeSerializeFMUstate %s\n", name,
               same_rows(rows, again, n) ? "identical" : "DIFFERS");
    if (!same_rows(rows, again, n)) g_failed = 1;
    bytes[size / 2] ^= 1; /* an altered state is refused */
    fmi2FMUstate s3 = NULL;
    fmi2Status st = F.deserialize(d, bytes, size, &s3);
    printf("%s altered state: status %d\n", name, (int)st);
    if (st != fmi2Error) g_failed = 1;
done:
    if (c && s) F.free_state(c, &s);
    if (d && s2) F.free_state(d, &s2);
    if (c) F.free_instance(c);
    if (d) F.free_instance(d);
    free(bytes);
    free(rows);
    free(again);
}

typedef struct {
    const char *name;
    const Values *v;
    int n, bad;
    double h, *rows;
} Job;

static THREAD_FN job_run(void *arg) {
    Job *j = arg;
    j->bad = run_alone(j->name, j->v, j->n, j->h, j->rows);
    return THREAD_RET;
}

static void cmd_pair(const char *name, int n, double h, const Values *a, const Values *b) {
    double *ra = new_rows(n), *rb = new_rows(n), *xa = new_rows(n), *xb = new_rows(n);
    char na[256], nb[256];
    snprintf(na, sizeof na, "%s-a", name);
    snprintf(nb, sizeof nb, "%s-b", name);
    if (run_alone(na, a, n, h, ra) || run_alone(nb, b, n, h, rb)) {
        failed(name, "runs alone");
        goto done;
    }
    printf("%s runs differ: %s\n", name, same_rows(ra, rb, n) ? "NO" : "yes");
    if (same_rows(ra, rb, n)) g_failed = 1;
    /* both in one thread, stepped in turn */
    fmi2Component ca = start(na, a), cb = start(nb, b);
    int bad = !ca || !cb || outputs(ca, 0.0, xa) || outputs(cb, 0.0, xb);
    double t = 0.0;
    for (int k = 1; k <= n && !bad; k++) {
        bad = steps(ca, k - 1, k, h, t, xa) || steps(cb, k - 1, k, h, t, xb);
        t += h;
    }
    if (ca) F.free_instance(ca);
    if (cb) F.free_instance(cb);
    if (bad) failed(name, "two instances in turn");
    else printf("%s two instances in turn: %s\n", name,
                same_rows(ra, xa, n) && same_rows(rb, xb, n) ? "identical" : "DIFFER");
    if (bad || !same_rows(ra, xa, n) || !same_rows(rb, xb, n)) g_failed = 1;
    /* each in a thread of its own, at once */
    memset(xa, 0, (size_t)(n + 1) * ROW * sizeof(double));
    memset(xb, 0, (size_t)(n + 1) * ROW * sizeof(double));
    Job ja = {na, a, n, 0, h, xa}, jb = {nb, b, n, 0, h, xb};
    thread_t ta, tb;
    if (thread_start(&ta, job_run, &ja) || thread_start(&tb, job_run, &jb)) {
        failed(name, "starting threads");
        goto done;
    }
    thread_join(ta);
    thread_join(tb);
    if (ja.bad || jb.bad) failed(name, "two threads");
    else printf("%s two threads at once: %s\n", name,
                same_rows(ra, xa, n) && same_rows(rb, xb, n) ? "identical" : "DIFFER");
    if (ja.bad || jb.bad || !same_rows(ra, xa, n) || !same_rows(rb, xb, n)) g_failed = 1;
done:
    free(ra), free(rb), free(xa), free(xb);
}

static void cmd_refuse(const char *name, const Values *v, const Values *badv) {
    double h = 1e-4, before[ROW], after[ROW];
    fmi2Component c = instantiate(name);
    if (!c || F.setup(c, fmi2False, 0.0, 0.0, fmi2False, 0.0) > fmi2Warning ||
        set_values(c, v) > fmi2Warning || F.enter(c) > fmi2Warning) {
        failed(name, "instantiate");
        if (c) F.free_instance(c);
        return;
    }
    printf("%s set in initialization mode: status %d\n", name, (int)set_values(c, badv));
    fmi2Status st = F.exit_init(c);
    printf("%s fmi2ExitInitializationMode: status %d\n", name, (int)st);
    if (st <= fmi2Warning) {
        double t = 0.0;
        for (int k = 0; k < 2; k++, t += h)
            printf("%s step: status %d\n", name, (int)F.do_step(c, t, h, fmi2True));
        outputs(c, t, before);
        printf("%s set in step mode: status %d\n", name, (int)set_values(c, badv));
        outputs(c, t, after);
        int same = !memcmp(before, after, sizeof before);
        printf("%s outputs after the refusal: %s\n", name, same ? "unchanged" : "CHANGED");
        if (!same) g_failed = 1;
        printf("%s step: status %d\n", name, (int)F.do_step(c, t, h, fmi2True));
        printf("%s fmi2Terminate: status %d\n", name, (int)F.terminate(c));
    }
    F.free_instance(c);
}

static int split(char *line, char **tok) {
    int n = 0;
    for (char *p = strtok(line, " \t\r\n"); p && n < MAXTOK; p = strtok(NULL, " \t\r\n"))
        tok[n++] = p;
    return n;
}

static int slash(char **tok, int n) {
    for (int i = 0; i < n; i++)
        if (!strcmp(tok[i], "/")) return i;
    return -1;
}

static int parse_list(const char *s, unsigned *out) {
    int n = 0;
    for (const char *p = s; *p && n < MAXV;) {
        out[n++] = (unsigned)strtoul(p, NULL, 10);
        p = strchr(p, ',');
        if (!p) break;
        p++;
    }
    return n;
}

#define LOAD(field, name)                                                            \
    do {                                                                             \
        void *f_ = fmu_dlsym(lib, name);                                             \
        if (!f_) {                                                                   \
            fprintf(stderr, "missing %s: %s\n", name, fmu_dlerror());                \
            return 1;                                                                \
        }                                                                            \
        memcpy(&F.field, &f_, sizeof f_);                                            \
    } while (0)

int main(int argc, char **argv) {
    if (argc != 4) {
        fprintf(stderr, "usage: %s UNZIPDIR MODEL_ID GUID < SCRIPT\n", argv[0]);
        return 2;
    }
    char path[4096], line[8192], *tok[MAXTOK];
    /* one write a block, not a line: under Wine each write costs about 1 ms */
    static char out_buf[1 << 16];
    setvbuf(stdout, out_buf, _IOFBF, sizeof out_buf);
    fmu_binary_path(argv[1], argv[2], path, sizeof path);
    fmu_resource_uri(argv[1], g_uri, sizeof g_uri);
    g_guid = argv[3];
    fmu_lib lib = fmu_dlopen(path);
    if (!lib) {
        fprintf(stderr, "loading %s: %s\n", path, fmu_dlerror());
        return 1;
    }
    LOAD(instantiate, "fmi2Instantiate");
    LOAD(free_instance, "fmi2FreeInstance");
    LOAD(setup, "fmi2SetupExperiment");
    LOAD(enter, "fmi2EnterInitializationMode");
    LOAD(exit_init, "fmi2ExitInitializationMode");
    LOAD(terminate, "fmi2Terminate");
    LOAD(set_real, "fmi2SetReal");
    LOAD(set_int, "fmi2SetInteger");
    LOAD(set_bool, "fmi2SetBoolean");
    LOAD(get_real, "fmi2GetReal");
    LOAD(get_int, "fmi2GetInteger");
    LOAD(do_step, "fmi2DoStep");
    LOAD(get_state, "fmi2GetFMUstate");
    LOAD(set_state, "fmi2SetFMUstate");
    LOAD(free_state, "fmi2FreeFMUstate");
    LOAD(state_size, "fmi2SerializedFMUstateSize");
    LOAD(serialize, "fmi2SerializeFMUstate");
    LOAD(deserialize, "fmi2DeSerializeFMUstate");
    while (fgets(line, sizeof line, stdin)) {
        char *hash = strchr(line, '#');
        if (hash) *hash = 0;
        int n = split(line, tok);
        if (!n) continue;
        int s = slash(tok, n);
        Values a, b;
        if (!strcmp(tok[0], "outputs") && n >= 2) {
            g_nr = parse_list(tok[1], g_rvr);
            g_ni = n > 2 ? parse_list(tok[2], g_ivr) : 0;
        } else if (!strcmp(tok[0], "location") && n == 2) {
            snprintf(g_uri, sizeof g_uri, "%s", tok[1]);
        } else if ((!strcmp(tok[0], "run") || !strcmp(tok[0], "states")) && n >= 4) {
            if (parse_values(tok + 4, n - 4, &a)) return 2;
            int steps_n = atoi(tok[2]);
            double h = strtod(tok[3], NULL);
            if (tok[0][0] == 'r') cmd_run(tok[1], steps_n, h, &a);
            else cmd_states(tok[1], steps_n, h, &a);
        } else if (!strcmp(tok[0], "pair") && n >= 4 && s > 0) {
            if (parse_values(tok + 4, s - 4, &a) || parse_values(tok + s + 1, n - s - 1, &b))
                return 2;
            cmd_pair(tok[1], atoi(tok[2]), strtod(tok[3], NULL), &a, &b);
        } else if (!strcmp(tok[0], "refuse") && n >= 2 && s > 0) {
            if (parse_values(tok + 2, s - 2, &a) || parse_values(tok + s + 1, n - s - 1, &b))
                return 2;
            cmd_refuse(tok[1], &a, &b);
        } else {
            fprintf(stderr, "bad command: %s\n", tok[0]);
            return 2;
        }
        fflush(stdout);
    }
    if (fmu_dlclose(lib) != 0) {
        fprintf(stderr, "unloading: %s\n", fmu_dlerror());
        return 1;
    }
    return g_failed;
}
