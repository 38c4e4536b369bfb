/* Seeded FMI 2.0 call-sequence fuzzer for a co-simulation FMU (tests/test_fmu_fuzz.py).
 *
 *   fmi2_fuzz UNZIPDIR MODEL_ID GUID SPEC SEED N_OPS
 *
 * SPEC lists the variables, one a line: KIND VR LO HI SAFE_LO SAFE_HI NAME, KIND one of
 * Ri (Real input), Rp (Real parameter), Ip (Integer parameter), Bp (Boolean parameter),
 * Ro (Real output), Io (Integer output). [LO, HI] is the declared range, [SAFE_LO, SAFE_HI]
 * the band the fuzzer draws normal values from.
 *
 * The driver keeps its own model of the FMI 2.0 co-simulation state machine and knows for
 * each call whether it is legal; it draws random legal and illegal calls (values normal, at
 * the range ends, out of range, NaN, infinite; steps of every size, zero, negative, NaN, at
 * a wrong communication point; FMU states got, set, freed, serialized and deserialized,
 * also truncated or with flipped bits; reset; calls out of order) and checks:
 *   - no call returns fmi2Fatal;
 *   - a call the model says is legal returns fmi2OK (a step may also return fmi2Discard
 *     after extreme inputs), an illegal one fmi2Error;
 *   - after a refused call the outputs are unchanged and finite, and a legal step works;
 *   - replaying steps from a saved state, from a deserialized one and in a fresh instance
 *     gives bit-identical outputs.
 * Exit status 0 when all held; otherwise it prints the failing call and exits 1.
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "fmu_dl.h" /* examples/hosts: dlopen, or LoadLibrary on Windows */

#define MAXV 128
typedef struct {
    char kind[3];
    unsigned vr;
    double lo, hi, safe_lo, safe_hi;
    char name[64];
} Var;

static Var vars[MAXV];
static int nvars;
static uint64_t rng;
static long op_no;
static const char *op_name = "";
static int quiet_errors;

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
    fprintf(stderr, "FUZZ FAILURE at op %ld (%s): ", op_no, op_name);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
    exit(1);
}

static long n_logged[5];
static long n_steps, n_discards, n_replays, n_corrupt;
static void logger(fmi2ComponentEnvironment env, fmi2String inst, fmi2Status st,
                   fmi2String cat, fmi2String msg, ...) {
    (void)env, (void)inst, (void)cat;
    if (st >= 0 && st <= 4) n_logged[st]++;
    if (!quiet_errors || st == fmi2Fatal) {
        va_list ap;
        va_start(ap, msg);
        fprintf(stderr, "[log %d] ", (int)st);
        vfprintf(stderr, msg, ap);
        fputc('\n', stderr);
        va_end(ap);
    }
}

/* -- the FMU ------------------------------------------------------------------------------ */
static struct {
    fmi2InstantiateTYPE *instantiate;
    fmi2FreeInstanceTYPE *free_instance;
    fmi2SetupExperimentTYPE *setup;
    fmi2EnterInitializationModeTYPE *enter;
    fmi2ExitInitializationModeTYPE *exit_init;
    fmi2TerminateTYPE *terminate;
    fmi2ResetTYPE *reset;
    fmi2GetRealTYPE *get_real;
    fmi2GetIntegerTYPE *get_int;
    fmi2SetRealTYPE *set_real;
    fmi2SetIntegerTYPE *set_int;
    fmi2SetBooleanTYPE *set_bool;
    fmi2DoStepTYPE *do_step;
    fmi2GetFMUstateTYPE *get_state;
    fmi2SetFMUstateTYPE *set_state;
    fmi2FreeFMUstateTYPE *free_state;
    fmi2SerializedFMUstateSizeTYPE *state_size;
    fmi2SerializeFMUstateTYPE *serialize;
    fmi2DeSerializeFMUstateTYPE *deserialize;
    fmi2GetDirectionalDerivativeTYPE *dir_der;
    fmi2CancelStepTYPE *cancel;
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
enum { INST, INIT, STEP, TERM };
static const unsigned GET_OK = 1u << INIT | 1u << STEP | 1u << TERM;
static const unsigned SET_OK = 1u << INST | 1u << INIT | 1u << STEP;

typedef struct {
    int mode;
    double t;
    double value[MAXV]; /* current value of every parameter and input, by index */
    int extreme;        /* an input is at the end of its range: a step may be discarded */
    char ext[MAXV];     /* which inputs are */
    char pending[MAXV]; /* a set refused before initialization ended, not set validly since:
                           fmi2ExitInitializationMode refuses until it is */
    int n_pending;
} Model;

typedef struct {
    fmi2Component c;
    Model m;
} Inst;

static char uri[4200], guid[256], model_id[256];
static fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};

static void defaults(Model *m) {
    memset(m, 0, sizeof *m);
    m->mode = INST;
    for (int i = 0; i < nvars; i++) m->value[i] = NAN; /* unknown start: read later */
}

static void instantiate(Inst *in, const char *name) {
    in->c = F.instantiate(name, fmi2CoSimulation, guid, uri, &cb, fmi2False, fmi2False);
    if (!in->c) fail("fmi2Instantiate returned NULL");
    defaults(&in->m);
}

static void check(fmi2Status st, int legal, const char *what) {
    if (st == fmi2Fatal) fail("%s returned fmi2Fatal", what);
    if (legal && st != fmi2OK && st != fmi2Warning)
        fail("%s is legal here but returned %d", what, (int)st);
    if (!legal && st != fmi2Error) fail("%s is illegal here but returned %d", what, (int)st);
}

/* All outputs (Real then Integer, as raw bits). Returns the status. */
static int n_out_r, n_out_i;
static fmi2ValueReference out_r[MAXV], out_i[MAXV];
static fmi2Status outputs(Inst *in, double *r, int *iv) {
    fmi2Status st = F.get_real(in->c, out_r, (size_t)n_out_r, r);
    if (st > fmi2Warning) return st;
    return F.get_int(in->c, out_i, (size_t)n_out_i, iv);
}

static void expect_finite_outputs(Inst *in, double *r, int *iv) {
    fmi2Status st = outputs(in, r, iv);
    check(st, 1, "fmi2GetReal/fmi2GetInteger of the outputs");
    for (int k = 0; k < n_out_r; k++)
        if (!isfinite(r[k])) fail("output vr %u is not finite: %g", out_r[k], r[k]);
}

static double draw_real(const Var *v, int *valid, int *extreme) {
    *extreme = 0;
    switch (pick(10)) {
    case 0: *valid = 0; return NAN;
    case 1: *valid = 0; return pick(2) ? INFINITY : -INFINITY;
    case 2: *valid = 0; return v->hi + fabs(v->hi) * 0.5 + 1.0;
    case 3: *valid = 0; return v->lo - fabs(v->lo) * 0.5 - 1.0;
    case 4:
        if (v->kind[1] == 'i') { /* range ends of an input: legal, perhaps hard */
            *valid = 1;
            *extreme = 1;
            return pick(2) ? v->hi : v->lo;
        }
        /* fall through */
    default:
        *valid = 1;
        return v->safe_lo + (v->safe_hi - v->safe_lo) * uniform();
    }
}

static int index_of(const char *name) {
    for (int i = 0; i < nvars; i++)
        if (!strcmp(vars[i].name, name)) return i;
    return -1;
}

/* Whether the driver's model of the parameters is a combination the FMU refuses. */
static int combination_refused(const Model *m) {
    int d = index_of("dof"), f = index_of("friction_law"), s = index_of("sliding");
    if (d < 0 || f < 0 || s < 0) return 0;
    double dv = isnan(m->value[d]) ? 0 : m->value[d], fv = isnan(m->value[f]) ? 3 : m->value[f],
           sv = isnan(m->value[s]) ? 0 : m->value[s];
    return dv == 1 && fv == 3 && sv == 0;
}

/* Set every variable with a refused value pending to the value it kept (valid: it was
 * taken or is the start value), as a master correcting the user's input would. */
static void set_pending_again(Inst *in) {
    for (int i = 0; i < nvars && in->m.n_pending; i++) {
        if (!in->m.pending[i]) continue;
        fmi2ValueReference vr = vars[i].vr;
        if (vars[i].kind[0] == 'R') {
            double x;
            check(F.get_real(in->c, &vr, 1, &x), 1, "fmi2GetReal of a refused variable");
            check(F.set_real(in->c, &vr, 1, &x), 1, "fmi2SetReal of the kept value");
        } else {
            int x;
            check(F.get_int(in->c, &vr, 1, &x), 1, "fmi2GetInteger of a refused variable");
            check(F.set_int(in->c, &vr, 1, &x), 1, "fmi2SetInteger of the kept value");
        }
        in->m.pending[i] = 0;
        in->m.n_pending--;
    }
}

/* A refused call changed nothing: same outputs (where they can be read), and a legal step
 * works afterwards. */
static void after_refusal(Inst *in, const double *r0, const int *i0, int had_outputs) {
    if (!(GET_OK >> in->m.mode & 1u)) return;
    double r[MAXV];
    int iv[MAXV];
    expect_finite_outputs(in, r, iv);
    if (had_outputs && (memcmp(r, r0, sizeof(double) * (size_t)n_out_r) ||
                        memcmp(iv, i0, sizeof(int) * (size_t)n_out_i)))
        fail("a refused call changed the outputs");
    if (in->m.mode == STEP && !in->m.extreme) {
        op_name = "legal step after a refusal";
        check(F.do_step(in->c, in->m.t, 1e-5, fmi2True), 1, "fmi2DoStep after a refusal");
        in->m.t += 1e-5;
    }
}

static void do_legal_step(Inst *in, double h) {
    fmi2Status st = F.do_step(in->c, in->m.t, h, fmi2True);
    if (st == fmi2Discard && in->m.extreme) { /* allowed: the state is the step start */
        n_discards++;
        return;
    }
    check(st, 1, "fmi2DoStep");
    in->m.t += h;
    n_steps++;
}

/* Save a state, run k steps, restore, replay (from the state, from its serialized bytes and
 * in a fresh instance): the outputs must agree bit for bit. */
static void replay_check(Inst *in) {
    enum { K = 3 };
    fmi2FMUstate s = NULL, s2 = NULL;
    op_name = "replay";
    check(F.get_state(in->c, &s), 1, "fmi2GetFMUstate");
    size_t n = 0;
    check(F.state_size(in->c, s, &n), 1, "fmi2SerializedFMUstateSize");
    char *blob = malloc(n);
    check(F.serialize(in->c, s, blob, n), 1, "fmi2SerializeFMUstate");
    Model saved = in->m;
    double h[K], torque[K], run[1][K][MAXV];
    int runi[1][K][MAXV];
    int it = index_of("torque");
    for (int k = 0; k < K; k++) {
        h[k] = pow(10.0, -6.0 + 3.0 * uniform());
        torque[k] = 1000.0 + 4000.0 * uniform();
    }
    Inst fresh = {0};
    for (int pass = 0; pass < 4; pass++) {
        Inst *who = in;
        if (pass == 1) check(F.set_state(in->c, s), 1, "fmi2SetFMUstate");
        if (pass == 2) {
            check(F.deserialize(in->c, blob, n, &s2), 1, "fmi2DeSerializeFMUstate");
            check(F.set_state(in->c, s2), 1, "fmi2SetFMUstate (deserialized)");
        }
        if (pass == 3) { /* a fresh instance, never initialized */
            instantiate(&fresh, "fresh");
            check(F.deserialize(fresh.c, blob, n, &s2), 1, "fmi2DeSerializeFMUstate (fresh)");
            check(F.set_state(fresh.c, s2), 1, "fmi2SetFMUstate (fresh)");
            check(F.free_state(fresh.c, &s2), 1, "fmi2FreeFMUstate (fresh)");
            who = &fresh;
        }
        who->m = saved;
        for (int k = 0; k < K; k++) {
            if (it >= 0) {
                fmi2ValueReference vr = vars[it].vr;
                check(F.set_real(who->c, &vr, 1, &torque[k]), 1, "fmi2SetReal torque (replay)");
            }
            fmi2Status st = F.do_step(who->c, who->m.t, h[k], fmi2True);
            check(st, 1, "fmi2DoStep (replay)");
            who->m.t += h[k];
            double r[MAXV];
            int iv[MAXV];
            expect_finite_outputs(who, r, iv);
            if (pass == 0) {
                memcpy(run[0][k], r, sizeof r);
                memcpy(runi[0][k], iv, sizeof iv);
            }
            if (pass > 0 && (memcmp(run[0][k], r, sizeof(double) * (size_t)n_out_r) ||
                             memcmp(runi[0][k], iv, sizeof(int) * (size_t)n_out_i)))
                fail("replay pass %d differs at step %d (not bit-identical)", pass, k);
        }
        if (pass == 2) check(F.free_state(in->c, &s2), 1, "fmi2FreeFMUstate (deserialized)");
    }
    check(F.terminate(fresh.c), 1, "fmi2Terminate (fresh)");
    F.free_instance(fresh.c);
    check(F.free_state(in->c, &s), 1, "fmi2FreeFMUstate");
    free(blob);
    n_replays++;
}

static void corrupt_state(Inst *in) {
    fmi2FMUstate s = NULL, s2 = NULL;
    op_name = "corrupt serialized state";
    check(F.get_state(in->c, &s), 1, "fmi2GetFMUstate");
    size_t n = 0;
    check(F.state_size(in->c, s, &n), 1, "fmi2SerializedFMUstateSize");
    char *blob = malloc(n);
    check(F.serialize(in->c, s, blob, n), 1, "fmi2SerializeFMUstate");
    check(F.free_state(in->c, &s), 1, "fmi2FreeFMUstate");
    size_t m = n;
    if (pick(2)) {
        m = (size_t)pick((int)n); /* truncated */
    } else {
        int flips = 1 + pick(3);
        for (int k = 0; k < flips; k++) blob[pick((int)n)] ^= (char)(1u << pick(8));
    }
    double r0[MAXV];
    int i0[MAXV];
    int had = (GET_OK >> in->m.mode & 1u) && outputs(in, r0, i0) <= fmi2Warning;
    fmi2Status st = F.deserialize(in->c, blob, m, &s2);
    if (st <= fmi2Warning) { /* a flip that cancelled out (the same bit twice) */
        if (m != n) fail("a truncated state was accepted");
        check(F.set_state(in->c, s2), 1, "fmi2SetFMUstate");
        check(F.free_state(in->c, &s2), 1, "fmi2FreeFMUstate");
    } else {
        check(st, 0, "fmi2DeSerializeFMUstate of altered bytes");
        after_refusal(in, r0, i0, had);
        n_corrupt++;
    }
    free(blob);
}

int main(int argc, char **argv) {
    if (argc != 7) {
        fprintf(stderr, "usage: %s UNZIPDIR MODEL_ID GUID SPEC SEED N_OPS\n", argv[0]);
        return 2;
    }
    snprintf(model_id, sizeof model_id, "%s", argv[2]);
    snprintf(guid, sizeof guid, "%s", argv[3]);
    rng = strtoull(argv[5], NULL, 10) * 0x9E3779B97F4A7C15ull + 1;
    long n_ops = strtol(argv[6], NULL, 10);
    FILE *f = fopen(argv[4], "r");
    if (!f) return 2;
    while (nvars < MAXV && fscanf(f, "%2s %u %lf %lf %lf %lf %63s", vars[nvars].kind,
                                  &vars[nvars].vr, &vars[nvars].lo, &vars[nvars].hi,
                                  &vars[nvars].safe_lo, &vars[nvars].safe_hi,
                                  vars[nvars].name) == 7) {
        if (vars[nvars].kind[1] == 'o') {
            if (vars[nvars].kind[0] == 'R')
                out_r[n_out_r++] = vars[nvars].vr;
            else
                out_i[n_out_i++] = vars[nvars].vr;
        }
        nvars++;
    }
    fclose(f);

    char path[4096];
    fmu_binary_path(argv[1], model_id, path, sizeof path);
    fmu_resource_uri(argv[1], uri, sizeof uri);
    fmu_lib lib = fmu_dlopen(path);
    if (!lib) {
        fprintf(stderr, "loading %s: %s\n", path, fmu_dlerror());
        return 2;
    }
    F.instantiate = (fmi2InstantiateTYPE *)sym(lib, "fmi2Instantiate");
    F.free_instance = (fmi2FreeInstanceTYPE *)sym(lib, "fmi2FreeInstance");
    F.setup = (fmi2SetupExperimentTYPE *)sym(lib, "fmi2SetupExperiment");
    F.enter = (fmi2EnterInitializationModeTYPE *)sym(lib, "fmi2EnterInitializationMode");
    F.exit_init = (fmi2ExitInitializationModeTYPE *)sym(lib, "fmi2ExitInitializationMode");
    F.terminate = (fmi2TerminateTYPE *)sym(lib, "fmi2Terminate");
    F.reset = (fmi2ResetTYPE *)sym(lib, "fmi2Reset");
    F.get_real = (fmi2GetRealTYPE *)sym(lib, "fmi2GetReal");
    F.get_int = (fmi2GetIntegerTYPE *)sym(lib, "fmi2GetInteger");
    F.set_real = (fmi2SetRealTYPE *)sym(lib, "fmi2SetReal");
    F.set_int = (fmi2SetIntegerTYPE *)sym(lib, "fmi2SetInteger");
    F.set_bool = (fmi2SetBooleanTYPE *)sym(lib, "fmi2SetBoolean");
    F.do_step = (fmi2DoStepTYPE *)sym(lib, "fmi2DoStep");
    F.get_state = (fmi2GetFMUstateTYPE *)sym(lib, "fmi2GetFMUstate");
    F.set_state = (fmi2SetFMUstateTYPE *)sym(lib, "fmi2SetFMUstate");
    F.free_state = (fmi2FreeFMUstateTYPE *)sym(lib, "fmi2FreeFMUstate");
    F.state_size = (fmi2SerializedFMUstateSizeTYPE *)sym(lib, "fmi2SerializedFMUstateSize");
    F.serialize = (fmi2SerializeFMUstateTYPE *)sym(lib, "fmi2SerializeFMUstate");
    F.deserialize = (fmi2DeSerializeFMUstateTYPE *)sym(lib, "fmi2DeSerializeFMUstate");
    F.dir_der = (fmi2GetDirectionalDerivativeTYPE *)sym(lib, "fmi2GetDirectionalDerivative");
    F.cancel = (fmi2CancelStepTYPE *)sym(lib, "fmi2CancelStep");

    quiet_errors = 1;
    Inst in;
    instantiate(&in, "fuzz");
    long counts[24] = {0};
    for (op_no = 0; op_no < n_ops; op_no++) {
        Model *m = &in.m;
        double r0[MAXV];
        int i0[MAXV];
        int had = (GET_OK >> m->mode & 1u) && outputs(&in, r0, i0) <= fmi2Warning;
        int op = pick(24);
        counts[op]++;
        fmi2Status st;
        int legal, refused = 0;
        switch (op) {
        case 0: case 1: case 2: case 3: case 4: { /* set an input or a parameter */
            int i;
            do i = pick(nvars); while (vars[i].kind[1] == 'o');
            Var *v = &vars[i];
            fmi2ValueReference vr = v->vr;
            int valid = 1, extreme = 0;
            op_name = v->name;
            int settable = (SET_OK >> m->mode & 1u) && (v->kind[1] == 'i' || m->mode != STEP);
            if (v->kind[0] == 'R') {
                double x = draw_real(v, &valid, &extreme);
                st = F.set_real(in.c, &vr, 1, &x);
                legal = settable && valid;
                if (legal) {
                    m->value[i] = x;
                    m->ext[i] = (char)extreme;
                    m->extreme = 0;
                    for (int k = 0; k < nvars; k++) m->extreme |= m->ext[k];
                }
            } else if (v->kind[0] == 'I') {
                int x = pick(4) ? (int)v->safe_lo + pick((int)(v->safe_hi - v->safe_lo) + 1)
                                : (pick(2) ? (int)v->hi + 1 + pick(5) : (int)v->lo - 1 - pick(5));
                valid = x >= v->lo && x <= v->hi;
                st = F.set_int(in.c, &vr, 1, &x);
                legal = settable && valid;
                if (legal) m->value[i] = x;
            } else {
                fmi2Boolean x = pick(2);
                st = F.set_bool(in.c, &vr, 1, &x);
                legal = settable;
                if (legal) m->value[i] = x;
            }
            check(st, legal, "fmi2Set*");
            refused = !legal;
            if (legal && m->pending[i]) {
                m->pending[i] = 0;
                m->n_pending--;
            } else if (!legal && (m->mode == INST || m->mode == INIT) && !m->pending[i]) {
                m->pending[i] = 1;
                m->n_pending++;
            }
            break;
        }
        case 5: case 6: case 7: case 8: case 9: { /* a step, legal or not */
            op_name = "fmi2DoStep";
            double t = m->t, h = pow(10.0, -7.0 + 4.0 * uniform());
            int kind = pick(8);
            if (kind == 0) h = 0.0;
            if (kind == 1) h = -h;
            if (kind == 2) h = NAN;
            if (kind == 3) t = m->t + 1e-3 * (1 + pick(3));
            if (kind == 4) t = pick(2) ? NAN : m->t - 1e-4;
            int valid = kind >= 5;
            if (valid && m->mode == STEP) {
                do_legal_step(&in, h);
            } else {
                st = F.do_step(in.c, t, h, fmi2True);
                check(st, 0, "fmi2DoStep (illegal)");
                refused = 1;
            }
            break;
        }
        case 10: /* outputs */
            op_name = "get outputs";
            if (GET_OK >> m->mode & 1u) {
                double r[MAXV];
                int iv[MAXV];
                expect_finite_outputs(&in, r, iv);
            } else {
                double r[MAXV];
                int iv[MAXV];
                check(outputs(&in, r, iv), 0, "get outputs (illegal mode)");
            }
            break;
        case 11: { /* an unknown value reference, an output set, unsupported calls */
            op_name = "invalid reference";
            fmi2ValueReference vr = 100000u + (unsigned)pick(100);
            double x = 1.0, d = 0.0;
            check(F.get_real(in.c, &vr, 1, &x), 0, "fmi2GetReal of an unknown vr");
            if (n_out_r) check(F.set_real(in.c, &out_r[0], 1, &x), 0, "fmi2SetReal of an output");
            check(F.dir_der(in.c, &vr, 1, &vr, 1, &x, &d), 0, "fmi2GetDirectionalDerivative");
            check(F.cancel(in.c), 0, "fmi2CancelStep");
            refused = 1;
            break;
        }
        case 12: /* lifecycle calls, in any order */
            op_name = "fmi2SetupExperiment";
            check(F.setup(in.c, fmi2False, 0.0, 0.0, fmi2False, 0.0), m->mode == INST,
                  op_name);
            refused = m->mode != INST;
            if (!refused) m->t = 0.0;
            break;
        case 13:
            op_name = "fmi2EnterInitializationMode";
            st = F.enter(in.c);
            check(st, m->mode == INST, op_name);
            refused = m->mode != INST;
            if (!refused) m->mode = INIT;
            break;
        case 14: case 15:
            op_name = "fmi2ExitInitializationMode";
            st = F.exit_init(in.c);
            if (m->mode == INIT && (combination_refused(m) || m->n_pending)) {
                check(st, 0, "fmi2ExitInitializationMode with a refused value or combination");
                set_pending_again(&in);
                if (combination_refused(m)) { /* correct it: sliding = 1 (full) */
                    int s = index_of("sliding");
                    fmi2ValueReference vr = vars[s].vr;
                    int one = 1;
                    check(F.set_int(in.c, &vr, 1, &one), 1, "fmi2SetInteger sliding = 1");
                    m->value[s] = 1;
                }
                check(F.exit_init(in.c), 1, "fmi2ExitInitializationMode after the correction");
                m->mode = STEP;
            } else {
                check(st, m->mode == INIT, op_name);
                refused = m->mode != INIT;
                if (!refused) m->mode = STEP;
            }
            break;
        case 16:
            op_name = "fmi2Terminate";
            if (m->mode == STEP && pick(3)) break; /* rarer: it ends the stepping */
            st = F.terminate(in.c);
            check(st, m->mode == STEP, op_name);
            refused = m->mode != STEP;
            if (!refused) m->mode = TERM;
            break;
        case 17:
            op_name = "fmi2Reset";
            if (pick(3)) break; /* rarer: resets undo much of the sequence */
            check(F.reset(in.c), 1, op_name);
            defaults(m);
            break;
        case 18: case 19: /* save, step, restore, replay */
            if (m->mode == STEP && !m->extreme) replay_check(&in);
            break;
        case 20: /* get a state, maybe set it back at once, free it */
        {
            op_name = "get/set/free FMU state";
            fmi2FMUstate s = NULL;
            check(F.get_state(in.c, &s), 1, "fmi2GetFMUstate");
            if (pick(2)) check(F.set_state(in.c, s), 1, "fmi2SetFMUstate");
            check(F.free_state(in.c, &s), 1, "fmi2FreeFMUstate");
            fmi2FMUstate null_state = NULL;
            check(F.free_state(in.c, &null_state), 1, "fmi2FreeFMUstate(NULL)");
            break;
        }
        case 21:
            corrupt_state(&in);
            break;
        case 22: /* free the instance and start a new one */
            op_name = "free and instantiate";
            if (pick(4)) break;
            F.free_instance(in.c);
            instantiate(&in, "fuzz");
            break;
        case 23: /* back to step mode quickly: the sequence otherwise spends most calls
                    outside it */
            op_name = "to step mode";
            if (m->mode == TERM || pick(2)) {
                check(F.reset(in.c), 1, "fmi2Reset");
                defaults(m);
            }
            if (m->mode == INST) {
                check(F.setup(in.c, fmi2False, 0.0, 0.0, fmi2False, 0.0), 1, "fmi2SetupExperiment");
                check(F.enter(in.c), 1, "fmi2EnterInitializationMode");
                m->mode = INIT;
            }
            if (m->mode == INIT) {
                set_pending_again(&in);
                if (combination_refused(m)) {
                    int s = index_of("sliding");
                    fmi2ValueReference vr = vars[s].vr;
                    int one = 1;
                    check(F.set_int(in.c, &vr, 1, &one), 1, "fmi2SetInteger sliding = 1");
                    m->value[s] = 1;
                }
                check(F.exit_init(in.c), 1, "fmi2ExitInitializationMode");
                m->mode = STEP;
            }
            break;
        }
        if (refused) after_refusal(&in, r0, i0, had);
    }
    if (in.m.mode == STEP) check(F.terminate(in.c), 1, "fmi2Terminate");
    F.free_instance(in.c);
    printf("ops %ld; logged: ok %ld, warning %ld, discard %ld, error %ld, fatal %ld\n", n_ops,
           n_logged[0], n_logged[1], n_logged[2], n_logged[3], n_logged[4]);
    printf("legal steps %ld, discarded %ld, replays %ld, altered states refused %ld\n",
           n_steps, n_discards, n_replays, n_corrupt);
    printf("op counts:");
    for (int k = 0; k < 24; k++) printf(" %ld", counts[k]);
    putchar('\n');
    return 0;
}
