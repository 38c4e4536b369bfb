/* Seeded FMI 3.0 call-sequence fuzzer for a co-simulation FMU (tests/test_fmu3_fuzz.py).
 *
 *   fmi3_fuzz UNZIPDIR MODEL_ID TOKEN SPEC SEED N_CALLS
 *
 * SPEC lists the variables, one a line: KIND VR LO HI SAFE_LO SAFE_HI NAME, KIND one of
 * Fi (Float64 input), Fp (Float64 parameter), Ip (Int32 parameter), Ep (Enumeration
 * parameter, Int64), Bp (Boolean parameter), Fo (Float64 output), Io (Int32 output), Ft
 * (the independent variable time). [LO, HI] is the declared range, [SAFE_LO, SAFE_HI] the
 * band the fuzzer draws normal values from.
 *
 * The driver keeps its own model of the FMI 3.0 co-simulation state machine (Instantiated,
 * Initialization Mode, Event Mode, Step Mode, Terminated; each instance made with random
 * eventModeUsed and earlyReturnAllowed) and knows for each call whether it is legal. It
 * draws random legal and illegal calls until N_CALLS fmi3 calls were made: values normal,
 * at the range ends, out of range, NaN, infinite, of the wrong type, with nValues wrong;
 * steps of every size, zero, negative, NaN, at a wrong communication point; Event Mode
 * entered and left, in order and out of it; early returns followed by Event Mode or not;
 * FMU states got, set, freed, serialized and deserialized, also truncated or with flipped
 * bits; reset; free and instantiate; the functions the FMU does not provide. It checks:
 *   - no call returns fmi3Fatal; a legal call returns fmi3OK (a step may also return
 *     fmi3Discard after extreme inputs), an illegal one fmi3Error;
 *   - fmi3DoStep's flags: earlyReturn only when allowed, with lastSuccessfulTime inside the
 *     step; eventHandlingNeeded only with Event Mode used; the next step starts there;
 *   - time (the independent variable) reads the driver's time, bit for bit;
 *   - after a refused call the outputs are unchanged and finite;
 *   - replaying steps from a saved state, from a deserialized one and in a fresh instance
 *     gives bit-identical outputs and the same early returns.
 * Exit status 0 when all held; otherwise it prints the failing call and exits 1.
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "fmu_dl.h" /* examples/hosts: dlopen, or LoadLibrary on Windows */

#ifdef _WIN32
#define FMI3_PLATFORM "x86_64-windows"
#else
#define FMI3_PLATFORM "x86_64-linux"
#endif

#define MAXV 128
typedef struct {
    char kind[3];
    unsigned vr;
    double lo, hi, safe_lo, safe_hi;
    char name[64];
} Var;

static Var vars[MAXV];
static int nvars, i_time = -1;
static uint64_t rng;
static long n_calls, op_no;
static const char *op_name = "";

static uint64_t next_u64(void) { /* xorshift64* */
    rng ^= rng >> 12;
    rng ^= rng << 25;
    rng ^= rng >> 27;
    return rng * 2685821657736338717ull;
}
static double uniform(void) { return (double)(next_u64() >> 11) * 0x1.0p-53; }
static int pick(int n) { return (int)(next_u64() % (uint64_t)n); }

static void fail(const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "FUZZ FAILURE at call %ld, op %ld (%s): ", n_calls, op_no, op_name);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
    exit(1);
}

static long n_logged[5], n_steps, n_early, n_events, n_discards, n_replays, n_corrupt;
static void logger(fmi3InstanceEnvironment env, fmi3Status st, fmi3String cat,
                   fmi3String msg) {
    (void)env, (void)cat;
    if (st <= fmi3Fatal) n_logged[st]++;
    if (st == fmi3Fatal) fprintf(stderr, "[fatal] %s\n", msg);
}

/* -- the FMU ------------------------------------------------------------------------------ */
#define FN(name) fmi3##name##TYPE *name
static struct {
    FN(InstantiateCoSimulation); FN(InstantiateModelExchange); FN(FreeInstance);
    FN(EnterInitializationMode); FN(ExitInitializationMode); FN(EnterEventMode);
    FN(UpdateDiscreteStates); FN(EnterStepMode); FN(DoStep); FN(Terminate); FN(Reset);
    FN(GetFloat64); FN(GetInt32); FN(GetInt64); FN(GetBoolean); FN(GetFloat32);
    FN(SetFloat64); FN(SetInt32); FN(SetInt64); FN(SetBoolean);
    FN(GetFMUState); FN(SetFMUState); FN(FreeFMUState); FN(SerializedFMUStateSize);
    FN(SerializeFMUState); FN(DeserializeFMUState); FN(EnterConfigurationMode);
    FN(GetDirectionalDerivative); FN(GetOutputDerivatives); FN(SetTime);
} F;

static void *sym(fmu_lib lib, const char *name) {
    void *f = fmu_dlsym(lib, name);
    if (!f) {
        fprintf(stderr, "missing %s\n", name);
        exit(2);
    }
    return f;
}

/* -- the driver's model of one instance --------------------------------------------------- */
enum { INST, INIT, EVENT, STEP, TERM };
#define GET_OK (1u << INIT | 1u << EVENT | 1u << STEP | 1u << TERM)
#define SET_OK (1u << INST | 1u << INIT | 1u << EVENT | 1u << STEP)
#define IS(m, set) (((set) >> (m)) & 1u)

typedef struct {
    int mode, event_mode, early, extreme, n_pending;
    double t;
    double value[MAXV];
    char ext[MAXV], pending[MAXV];
} Model;

typedef struct {
    fmi3Instance c;
    Model m;
} Inst;

static char resources[4200], token[256];

static void check(fmi3Status st, int legal, const char *what) {
    n_calls++;
    if (st == fmi3Fatal) fail("%s returned fmi3Fatal", what);
    if (legal && st != fmi3OK && st != fmi3Warning)
        fail("%s is legal here but returned %d", what, (int)st);
    if (!legal && st != fmi3Error) fail("%s is illegal here but returned %d", what, (int)st);
}

static void defaults(Model *m) {
    int em = m->event_mode, er = m->early;
    memset(m, 0, sizeof *m);
    m->mode = INST;
    m->event_mode = em;
    m->early = er;
    for (int i = 0; i < nvars; i++) m->value[i] = NAN;
}

static void instantiate(Inst *in, const char *name, int event_mode, int early) {
    in->c = F.InstantiateCoSimulation(name, token, resources, fmi3False, fmi3False,
                                      event_mode, early, NULL, 0, NULL, logger, NULL);
    n_calls++;
    if (!in->c) fail("fmi3InstantiateCoSimulation returned NULL");
    in->m.event_mode = event_mode;
    in->m.early = early;
    defaults(&in->m);
}

static int n_out_f, n_out_i;
static fmi3ValueReference out_f[MAXV], out_i[MAXV];

static fmi3Status outputs(Inst *in, double *f, fmi3Int32 *iv) {
    fmi3Status st = F.GetFloat64(in->c, out_f, (size_t)n_out_f, f, (size_t)n_out_f);
    n_calls++;
    if (st > fmi3Warning) return st;
    n_calls++;
    return F.GetInt32(in->c, out_i, (size_t)n_out_i, iv, (size_t)n_out_i);
}

static void expect_outputs(Inst *in, double *f, fmi3Int32 *iv) {
    check(outputs(in, f, iv), 1, "fmi3GetFloat64/fmi3GetInt32 of the outputs");
    n_calls -= 1; /* counted in outputs */
    for (int k = 0; k < n_out_f; k++)
        if (!isfinite(f[k])) fail("output vr %u is not finite: %g", out_f[k], f[k]);
    if (i_time >= 0 && in->m.mode != INIT) {
        double t;
        fmi3ValueReference vr = vars[i_time].vr;
        check(F.GetFloat64(in->c, &vr, 1, &t, 1), 1, "fmi3GetFloat64 of time");
        if (memcmp(&t, &in->m.t, sizeof t)) fail("time reads %.17g, not %.17g", t, in->m.t);
    }
}

static int index_of(const char *name) {
    for (int i = 0; i < nvars; i++)
        if (!strcmp(vars[i].name, name)) return i;
    return -1;
}

static int combination_refused(const Model *m) {
    int d = index_of("dof"), f = index_of("friction_law"), s = index_of("sliding");
    if (d < 0 || f < 0 || s < 0) return 0;
    double dv = isnan(m->value[d]) ? 0 : m->value[d], fv = isnan(m->value[f]) ? 3 : m->value[f],
           sv = isnan(m->value[s]) ? 0 : m->value[s];
    return dv == 1 && fv == 3 && sv == 0;
}

/* Set one variable (legal or not, as the driver's model says); returns whether refused. */
static int set_one(Inst *in, int i, int wrong_type) {
    Var *v = &vars[i];
    Model *m = &in->m;
    fmi3ValueReference vr = v->vr;
    op_name = v->name;
    int settable = IS(m->mode, SET_OK) && v->kind[1] != 'o' && v->kind[1] != 't' &&
                   (v->kind[1] == 'i' || m->mode == INST || m->mode == INIT);
    int valid = 1, extreme = 0;
    fmi3Status st;
    double x;
    char k = wrong_type ? "FIEB"[pick(4)] : v->kind[0];
    int type_ok = k == v->kind[0];
    if (k == 'F') {
        switch (pick(10)) {
        case 0: valid = 0; x = NAN; break;
        case 1: valid = 0; x = pick(2) ? INFINITY : -INFINITY; break;
        case 2: valid = 0; x = v->hi + fabs(v->hi) * 0.5 + 1.0; break;
        case 3: valid = 0; x = v->lo - fabs(v->lo) * 0.5 - 1.0; break;
        case 4:
            if (v->kind[1] == 'i') { /* range ends of an input: legal, perhaps hard */
                extreme = 1;
                x = pick(2) ? v->hi : v->lo;
                break;
            }
            /* fall through */
        default: x = v->safe_lo + (v->safe_hi - v->safe_lo) * uniform();
        }
        st = F.SetFloat64(in->c, &vr, 1, &x, 1);
    } else if (k == 'I' || k == 'E') {
        long long y = pick(4) ? (long long)v->safe_lo + pick((int)(v->safe_hi - v->safe_lo) + 1)
                              : (pick(2) ? (long long)v->hi + 1 + pick(5)
                                         : (long long)v->lo - 1 - pick(5));
        valid = y >= v->lo && y <= v->hi;
        x = (double)y;
        if (k == 'I') {
            fmi3Int32 z = (fmi3Int32)y;
            st = F.SetInt32(in->c, &vr, 1, &z, 1);
        } else {
            fmi3Int64 z = y;
            st = F.SetInt64(in->c, &vr, 1, &z, 1);
        }
    } else {
        fmi3Boolean z = pick(2);
        x = z;
        st = F.SetBoolean(in->c, &vr, 1, &z, 1);
    }
    int legal = settable && valid && type_ok;
    check(st, legal, "fmi3Set*");
    if (legal) {
        m->value[i] = x;
        m->ext[i] = (char)extreme;
        m->extreme = 0;
        for (int j = 0; j < nvars; j++) m->extreme |= m->ext[j];
        if (m->pending[i]) {
            m->pending[i] = 0;
            m->n_pending--;
        }
    } else if (type_ok && settable && !m->pending[i] && (m->mode == INST || m->mode == INIT)) {
        m->pending[i] = 1; /* refused before initialization ended: remembered */
        m->n_pending++;
    }
    return !legal;
}

/* Every variable with a refused value pending set again to the value it kept. */
static void set_pending_again(Inst *in) {
    for (int i = 0; i < nvars && in->m.n_pending; i++) {
        if (!in->m.pending[i]) continue;
        fmi3ValueReference vr = vars[i].vr;
        if (vars[i].kind[0] == 'F') {
            double x;
            check(F.GetFloat64(in->c, &vr, 1, &x, 1), 1, "fmi3GetFloat64 (refused variable)");
            check(F.SetFloat64(in->c, &vr, 1, &x, 1), 1, "fmi3SetFloat64 (kept value)");
        } else if (vars[i].kind[0] == 'I') {
            fmi3Int32 x;
            check(F.GetInt32(in->c, &vr, 1, &x, 1), 1, "fmi3GetInt32 (refused variable)");
            check(F.SetInt32(in->c, &vr, 1, &x, 1), 1, "fmi3SetInt32 (kept value)");
        } else {
            fmi3Int64 x;
            check(F.GetInt64(in->c, &vr, 1, &x, 1), 1, "fmi3GetInt64 (refused variable)");
            check(F.SetInt64(in->c, &vr, 1, &x, 1), 1, "fmi3SetInt64 (kept value)");
        }
        in->m.pending[i] = 0;
        in->m.n_pending--;
    }
}

static void settle_events(Inst *in) { /* Event Mode: update until nothing is left, leave */
    fmi3Boolean more, term, nom, val, defined;
    fmi3Float64 next;
    check(F.UpdateDiscreteStates(in->c, &more, &term, &nom, &val, &defined, &next), 1,
          "fmi3UpdateDiscreteStates");
    if (more || term || defined) fail("fmi3UpdateDiscreteStates asks for more");
    check(F.EnterStepMode(in->c), 1, "fmi3EnterStepMode");
    in->m.mode = STEP;
}

/* A legal step; returns 1 after an early return. */
static int legal_step(Inst *in, double h, int *discarded) {
    Model *m = &in->m;
    fmi3Boolean event = 9, term = 9, early = 9;
    fmi3Float64 last = NAN;
    fmi3Status st = F.DoStep(in->c, m->t, h, fmi3True, &event, &term, &early, &last);
    *discarded = st == fmi3Discard && m->extreme;
    if (*discarded) { /* allowed: the state is the step start */
        n_calls++;
        n_discards++;
        return 0;
    }
    check(st, 1, "fmi3DoStep");
    if (term) fail("terminateSimulation after a step");
    if (early && !m->early) fail("an early return that was not allowed");
    if (event && !(early && m->event_mode)) fail("eventHandlingNeeded without Event Mode");
    if (early ? !(last > m->t && last < m->t + h) : last != m->t + h)
        fail("lastSuccessfulTime %.17g for a step from %.17g over %.17g (early %d)", last,
             m->t, h, (int)early);
    m->t = last;
    n_steps++;
    if (early) n_early++;
    if (event) {
        n_events++;
        if (pick(4)) { /* mostly: handle it in Event Mode; else step on from there */
            check(F.EnterEventMode(in->c), 1, "fmi3EnterEventMode after an event");
            m->mode = EVENT;
            settle_events(in);
        }
    }
    return early;
}

/* Bring the instance to Step Mode (correcting refused values and combinations). */
static void to_step_mode(Inst *in) {
    Model *m = &in->m;
    if (m->mode == TERM || m->mode == INST) {
        check(F.Reset(in->c), 1, "fmi3Reset");
        defaults(m);
        check(F.EnterInitializationMode(in->c, fmi3False, 0.0, 0.0, fmi3False, 0.0), 1,
              "fmi3EnterInitializationMode");
        m->mode = INIT;
    }
    if (m->mode == INIT) {
        set_pending_again(in);
        for (int i = 0; i < nvars; i++) /* inputs in their normal bands (events happen) */
            if (vars[i].kind[0] == 'F' && vars[i].kind[1] == 'i' && pick(2)) {
                fmi3ValueReference vr = vars[i].vr;
                double x = vars[i].safe_lo + (vars[i].safe_hi - vars[i].safe_lo) * uniform();
                check(F.SetFloat64(in->c, &vr, 1, &x, 1), 1, "fmi3SetFloat64 of an input");
                m->value[i] = x;
                m->ext[i] = 0;
            }
        m->extreme = 0;
        for (int j = 0; j < nvars; j++) m->extreme |= m->ext[j];
        if (combination_refused(m)) {
            int s = index_of("sliding");
            fmi3ValueReference vr = vars[s].vr;
            fmi3Int64 one = 1;
            check(F.SetInt64(in->c, &vr, 1, &one, 1), 1, "fmi3SetInt64 sliding = 1");
            m->value[s] = 1;
        }
        check(F.ExitInitializationMode(in->c), 1, "fmi3ExitInitializationMode");
        m->mode = m->event_mode ? EVENT : STEP;
    }
    if (m->mode == EVENT) settle_events(in);
}

/* Save a state, run K steps, restore, replay (from the state, from its serialized bytes and
 * in a fresh instance made alike): outputs, times and early returns agree bit for bit. */
static void replay_check(Inst *in) {
    enum { K = 4 };
    fmi3FMUState s = NULL, s2 = NULL;
    op_name = "replay";
    check(F.GetFMUState(in->c, &s), 1, "fmi3GetFMUState");
    size_t n = 0;
    check(F.SerializedFMUStateSize(in->c, s, &n), 1, "fmi3SerializedFMUStateSize");
    fmi3Byte *blob = malloc(n);
    check(F.SerializeFMUState(in->c, s, blob, n), 1, "fmi3SerializeFMUState");
    Model saved = in->m;
    double h[K], run[K][MAXV + 1];
    fmi3Int32 runi[K][MAXV];
    for (int k = 0; k < K; k++) h[k] = pow(10.0, -6.0 + 3.0 * uniform());
    Inst fresh = {0};
    uint64_t rng_saved = rng;
    for (int pass = 0; pass < 4; pass++) {
        Inst *who = in;
        rng = rng_saved; /* the same choices (Event Mode or not) in every pass */
        if (pass == 1) check(F.SetFMUState(in->c, s), 1, "fmi3SetFMUState");
        if (pass == 2) {
            check(F.DeserializeFMUState(in->c, blob, n, &s2), 1, "fmi3DeserializeFMUState");
            check(F.SetFMUState(in->c, s2), 1, "fmi3SetFMUState (deserialized)");
            check(F.FreeFMUState(in->c, &s2), 1, "fmi3FreeFMUState (deserialized)");
        }
        if (pass == 3) {
            instantiate(&fresh, "fresh", saved.event_mode, saved.early);
            check(F.DeserializeFMUState(fresh.c, blob, n, &s2), 1,
                  "fmi3DeserializeFMUState (fresh)");
            check(F.SetFMUState(fresh.c, s2), 1, "fmi3SetFMUState (fresh)");
            check(F.FreeFMUState(fresh.c, &s2), 1, "fmi3FreeFMUState (fresh)");
            who = &fresh;
        }
        who->m = saved;
        for (int k = 0; k < K; k++) {
            int discarded;
            legal_step(who, h[k], &discarded);
            if (discarded) fail("a discarded step in a replay");
            double f[MAXV + 1];
            fmi3Int32 iv[MAXV];
            expect_outputs(who, f, iv);
            f[n_out_f] = who->m.t;
            if (pass == 0) {
                memcpy(run[k], f, sizeof f);
                memcpy(runi[k], iv, sizeof iv);
            } else if (memcmp(run[k], f, sizeof(double) * (size_t)(n_out_f + 1)) ||
                       memcmp(runi[k], iv, sizeof(fmi3Int32) * (size_t)n_out_i)) {
                fail("replay pass %d differs at step %d (not bit-identical)", pass, k);
            }
        }
    }
    check(F.Terminate(fresh.c), 1, "fmi3Terminate (fresh)");
    F.FreeInstance(fresh.c);
    check(F.FreeFMUState(in->c, &s), 1, "fmi3FreeFMUState");
    free(blob);
    n_replays++;
}

static int corrupt_state(Inst *in) {
    fmi3FMUState s = NULL, s2 = NULL;
    op_name = "corrupt serialized state";
    check(F.GetFMUState(in->c, &s), 1, "fmi3GetFMUState");
    size_t n = 0;
    check(F.SerializedFMUStateSize(in->c, s, &n), 1, "fmi3SerializedFMUStateSize");
    fmi3Byte *blob = malloc(n);
    check(F.SerializeFMUState(in->c, s, blob, n), 1, "fmi3SerializeFMUState");
    check(F.FreeFMUState(in->c, &s), 1, "fmi3FreeFMUState");
    size_t m = n;
    if (pick(2)) {
        m = (size_t)pick((int)n); /* truncated */
    } else {
        for (int k = 1 + pick(3); k > 0; k--) blob[pick((int)n)] ^= (fmi3Byte)(1u << pick(8));
    }
    fmi3Status st = F.DeserializeFMUState(in->c, blob, m, &s2);
    int refused = st > fmi3Warning;
    if (!refused) { /* a flip that cancelled out (the same bit twice) */
        n_calls++;
        if (m != n) fail("a truncated state was accepted");
        check(F.FreeFMUState(in->c, &s2), 1, "fmi3FreeFMUState");
    } else {
        check(st, 0, "fmi3DeserializeFMUState of altered bytes");
        n_corrupt++;
    }
    free(blob);
    return refused;
}

int main(int argc, char **argv) {
    if (argc != 7) {
        fprintf(stderr, "usage: %s UNZIPDIR MODEL_ID TOKEN SPEC SEED N_CALLS\n", argv[0]);
        return 2;
    }
    snprintf(token, sizeof token, "%s", argv[3]);
    rng = strtoull(argv[5], NULL, 10) * 0x9E3779B97F4A7C15ull + 1;
    long max_calls = strtol(argv[6], NULL, 10);
    FILE *f = fopen(argv[4], "r");
    if (!f) return 2;
    while (nvars < MAXV && fscanf(f, "%2s %u %lf %lf %lf %lf %63s", vars[nvars].kind,
                                  &vars[nvars].vr, &vars[nvars].lo, &vars[nvars].hi,
                                  &vars[nvars].safe_lo, &vars[nvars].safe_hi,
                                  vars[nvars].name) == 7) {
        Var *v = &vars[nvars];
        if (v->kind[1] == 'o' && v->kind[0] == 'F') out_f[n_out_f++] = v->vr;
        if (v->kind[1] == 'o' && v->kind[0] == 'I') out_i[n_out_i++] = v->vr;
        if (v->kind[1] == 't') i_time = nvars;
        nvars++;
    }
    fclose(f);

    char path[4096];
    snprintf(path, sizeof path, "%s/binaries/%s/%s%s", argv[1], FMI3_PLATFORM, argv[2],
             FMU_SUFFIX);
    snprintf(resources, sizeof resources, "%s/resources/", argv[1]);
    fmu_lib lib = fmu_dlopen(path);
    if (!lib) {
        fprintf(stderr, "loading %s: %s\n", path, fmu_dlerror());
        return 2;
    }
#define LOAD(name) F.name = (fmi3##name##TYPE *)sym(lib, "fmi3" #name)
    LOAD(InstantiateCoSimulation); LOAD(InstantiateModelExchange); LOAD(FreeInstance);
    LOAD(EnterInitializationMode); LOAD(ExitInitializationMode); LOAD(EnterEventMode);
    LOAD(UpdateDiscreteStates); LOAD(EnterStepMode); LOAD(DoStep); LOAD(Terminate);
    LOAD(Reset); LOAD(GetFloat64); LOAD(GetInt32); LOAD(GetInt64); LOAD(GetBoolean);
    LOAD(GetFloat32); LOAD(SetFloat64); LOAD(SetInt32); LOAD(SetInt64); LOAD(SetBoolean);
    LOAD(GetFMUState); LOAD(SetFMUState); LOAD(FreeFMUState); LOAD(SerializedFMUStateSize);
    LOAD(SerializeFMUState); LOAD(DeserializeFMUState); LOAD(EnterConfigurationMode);
    LOAD(GetDirectionalDerivative); LOAD(GetOutputDerivatives); LOAD(SetTime);

    Inst in;
    instantiate(&in, "fuzz", pick(2), pick(2));
    enum { N_OP = 26 };
    long counts[N_OP] = {0};
    for (op_no = 0; n_calls < max_calls; op_no++) {
        Model *m = &in.m;
        double f0[MAXV], f1[MAXV];
        fmi3Int32 i0[MAXV], i1[MAXV];
        int had = IS(m->mode, GET_OK) && outputs(&in, f0, i0) <= fmi3Warning;
        int op = pick(N_OP), refused = 0, discarded;
        counts[op]++;
        fmi3Status st;
        switch (op) {
        case 0: case 1: case 2: case 3: /* set a variable, of its type or not */
            refused = set_one(&in, pick(nvars), pick(6) == 0);
            break;
        case 4: case 5: case 6: case 7: case 8: { /* a step, legal or not */
            op_name = "fmi3DoStep";
            double t = m->t, h = pow(10.0, -7.0 + 4.0 * uniform());
            int kind = pick(8);
            if (kind == 0) h = 0.0;
            if (kind == 1) h = -h;
            if (kind == 2) h = NAN;
            if (kind == 3) t = m->t + 1e-3 * (1 + pick(3));
            if (kind == 4) t = pick(2) ? NAN : m->t - 1e-4;
            if (kind >= 5 && m->mode == STEP) {
                legal_step(&in, h, &discarded);
            } else {
                fmi3Boolean e, tm, er;
                fmi3Float64 last;
                check(F.DoStep(in.c, t, h, fmi3True, &e, &tm, &er, &last), 0,
                      "fmi3DoStep (illegal)");
                refused = 1;
            }
            break;
        }
        case 9: /* outputs, in any state */
            op_name = "get outputs";
            if (IS(m->mode, GET_OK)) {
                expect_outputs(&in, f1, i1);
            } else {
                check(outputs(&in, f1, i1), 0, "get outputs (illegal state)");
                n_calls--;
            }
            break;
        case 10: { /* the wrong type, wrong nValues, an unknown reference, time set */
            op_name = "invalid reference";
            fmi3ValueReference vr = 100000u + (unsigned)pick(100), fo = out_f[pick(n_out_f)];
            double x = 1.0;
            fmi3Int32 y;
            float z;
            int ok_state = IS(m->mode, GET_OK);
            check(F.GetFloat64(in.c, &vr, 1, &x, 1), 0, "fmi3GetFloat64 of an unknown vr");
            check(F.GetInt32(in.c, &fo, 1, &y, 1), 0, "fmi3GetInt32 of a Float64");
            check(F.GetFloat64(in.c, &fo, 1, &x, 2), 0, "fmi3GetFloat64 with nValues 2");
            check(F.GetFloat32(in.c, &fo, 1, &z, 1), 0, "fmi3GetFloat32 of a Float64");
            check(F.GetFloat32(in.c, NULL, 0, NULL, 0), ok_state, "fmi3GetFloat32 of none");
            check(F.SetFloat64(in.c, &fo, 1, &x, 1), 0, "fmi3SetFloat64 of an output");
            if (i_time >= 0) {
                fmi3ValueReference tv = vars[i_time].vr;
                check(F.SetFloat64(in.c, &tv, 1, &x, 1), 0, "fmi3SetFloat64 of time");
            }
            refused = 1;
            break;
        }
        case 11: { /* what the FMU does not provide */
            op_name = "not provided";
            fmi3ValueReference vr = out_f[0];
            double x = 0.0, d = 0.0;
            fmi3Int32 order = 1;
            check(F.EnterConfigurationMode(in.c), 0, "fmi3EnterConfigurationMode");
            check(F.GetDirectionalDerivative(in.c, &vr, 1, &vr, 1, &x, 1, &d, 1), 0,
                  "fmi3GetDirectionalDerivative");
            check(F.GetOutputDerivatives(in.c, &vr, 1, &order, &d, 1), 0,
                  "fmi3GetOutputDerivatives");
            check(F.SetTime(in.c, 0.0), 0, "fmi3SetTime");
            fmi3Instance me = F.InstantiateModelExchange("me", token, resources, fmi3False,
                                                         fmi3False, NULL, logger);
            n_calls++;
            if (me) fail("fmi3InstantiateModelExchange gave an instance");
            fmi3Instance bad = F.InstantiateCoSimulation("bad", "not the token", resources,
                                                         fmi3False, fmi3False, fmi3False,
                                                         fmi3False, NULL, 0, NULL, logger,
                                                         NULL);
            n_calls++;
            if (bad) fail("a wrong instantiationToken gave an instance");
            refused = 1;
            break;
        }
        case 12:
            op_name = "fmi3EnterInitializationMode";
            if (pick(3) == 0) { /* a start time that is not finite, a stop before it */
                check(F.EnterInitializationMode(in.c, fmi3False, 0.0, pick(2) ? NAN : 1.0,
                                                fmi3True, 0.5), 0, op_name);
                refused = 1;
                break;
            }
            st = F.EnterInitializationMode(in.c, fmi3False, 0.0, 0.0, fmi3False, 0.0);
            check(st, m->mode == INST, op_name);
            refused = m->mode != INST;
            if (!refused) m->mode = INIT;
            break;
        case 13:
            op_name = "fmi3ExitInitializationMode";
            st = F.ExitInitializationMode(in.c);
            if (m->mode == INIT && (combination_refused(m) || m->n_pending)) {
                check(st, 0, "fmi3ExitInitializationMode with a refused value or combination");
                refused = 1;
            } else {
                check(st, m->mode == INIT, op_name);
                refused = m->mode != INIT;
                if (!refused) m->mode = m->event_mode ? EVENT : STEP;
            }
            break;
        case 14:
            op_name = "fmi3EnterEventMode";
            st = F.EnterEventMode(in.c);
            check(st, m->mode == STEP && m->event_mode, op_name);
            refused = !(m->mode == STEP && m->event_mode);
            if (!refused) m->mode = EVENT;
            break;
        case 15: { /* fmi3UpdateDiscreteStates, legal in Event Mode only */
            op_name = "fmi3UpdateDiscreteStates";
            fmi3Boolean a, b, c, d, e;
            fmi3Float64 next;
            check(F.UpdateDiscreteStates(in.c, &a, &b, &c, &d, &e, &next), m->mode == EVENT,
                  op_name);
            refused = m->mode != EVENT;
            break;
        }
        case 16:
            op_name = "fmi3EnterStepMode";
            check(F.EnterStepMode(in.c), m->mode == EVENT, op_name);
            refused = m->mode != EVENT;
            if (!refused) m->mode = STEP;
            break;
        case 17:
            op_name = "fmi3Terminate";
            if ((m->mode == STEP || m->mode == EVENT) && pick(3)) break; /* rarer */
            check(F.Terminate(in.c), m->mode == STEP || m->mode == EVENT, op_name);
            refused = !(m->mode == STEP || m->mode == EVENT);
            if (!refused) m->mode = TERM;
            break;
        case 18:
            op_name = "fmi3Reset";
            if (pick(4)) break; /* rarer: resets undo much of the sequence */
            check(F.Reset(in.c), 1, op_name);
            defaults(m);
            break;
        case 19: /* save, step, restore, replay */
            if (m->mode == STEP && !m->extreme && !pick(3)) replay_check(&in);
            break;
        case 20: { /* get a state, maybe set it back at once, free it */
            op_name = "get/set/free FMU state";
            fmi3FMUState s = NULL, none = NULL;
            check(F.GetFMUState(in.c, &s), 1, "fmi3GetFMUState");
            if (pick(2)) check(F.SetFMUState(in.c, s), 1, "fmi3SetFMUState");
            check(F.FreeFMUState(in.c, &s), 1, "fmi3FreeFMUState");
            check(F.FreeFMUState(in.c, &none), 1, "fmi3FreeFMUState(NULL)");
            check(F.SetFMUState(in.c, (fmi3FMUState)&none), 0, "fmi3SetFMUState of a stranger");
            break;
        }
        case 21:
            refused = corrupt_state(&in);
            break;
        case 22: /* free the instance and make a new one, with new flags */
            op_name = "free and instantiate";
            if (pick(8)) break;
            F.FreeInstance(in.c);
            n_calls++;
            instantiate(&in, "fuzz", pick(2), pick(2));
            break;
        case 23: case 24: case 25: /* to Step Mode, then steps: the sequence otherwise
                                      spends most calls outside it */
            op_name = "to step mode";
            if (pick(4) == 0) {
                check(F.Reset(in.c), 1, "fmi3Reset");
                defaults(m);
            }
            to_step_mode(&in);
            for (int k = 1 + pick(6); k > 0 && !m->extreme; k--)
                legal_step(&in, pow(10.0, -5.0 + 2.0 * uniform()), &discarded);
            break;
        }
        if (refused && IS(m->mode, GET_OK)) { /* a refused call changed nothing */
            expect_outputs(&in, f1, i1);
            if (had && (memcmp(f0, f1, sizeof(double) * (size_t)n_out_f) ||
                        memcmp(i0, i1, sizeof(fmi3Int32) * (size_t)n_out_i)))
                fail("a refused call changed the outputs");
        }
    }
    if (in.m.mode == STEP || in.m.mode == EVENT) check(F.Terminate(in.c), 1, "fmi3Terminate");
    F.FreeInstance(in.c);
    printf("calls %ld in %ld ops; logged: ok %ld, warning %ld, discard %ld, error %ld, "
           "fatal %ld\n", n_calls, op_no, n_logged[0], n_logged[1], n_logged[2], n_logged[3],
           n_logged[4]);
    printf("legal steps %ld (early returns %ld, events %ld), discarded %ld, replays %ld, "
           "altered states refused %ld\n", n_steps, n_early, n_events, n_discards, n_replays,
           n_corrupt);
    printf("op counts:");
    for (int k = 0; k < N_OP; k++) printf(" %ld", counts[k]);
    putchar('\n');
    return 0;
}
