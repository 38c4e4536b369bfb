/* GearPair's model part of the FMU (fmu.h): the variables' values into gear data and
 * choices (the generated gearpair_config.h says which variable goes where), the checks of
 * the combinations the model refuses, and the engine: the fast engine compiled into this
 * binary (gearpair_model.h) for engine = 0, the Python slave (python_slave.h) for the scipy
 * reference engine, engine = 1, the only path that needs Python. */
#define _GNU_SOURCE
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmu.h"
#include "gearpair_config.h"
#include "gearpair_model.h"
#include "python_slave.h"

typedef struct {
    GpModel *fast;                 /* engine 0, once initialized */
    double built[MODEL_NVARS];     /* the values it was built with (parameters compared) */
    PySlave *py;                   /* engine 1, once initialized */
    int stepped;                   /* a step was taken since initialization */
} Gp;

#define GP(inst) ((Gp *)(inst)->model)
#define GP_PY_WHY "engine = 1 (reference) needs Python"

int model_new(Instance *inst) {
    inst->model = calloc(1, sizeof(Gp));
    if (!inst->model) return -1;
    return 0;
}

static void drop_engines(Gp *g) {
    gp_model_free(g->fast);
    g->fast = NULL;
    py_slave_free(g->py);
    g->py = NULL;
    g->stepped = 0;
}

void model_free(Instance *inst) {
    if (!inst->model) return;
    drop_engines(GP(inst));
    free(inst->model);
    inst->model = NULL;
}

void model_reset(Instance *inst) { drop_engines(GP(inst)); }

int model_gone(Instance *inst, const char *fn) {
    return inst->model && GP(inst)->py && py_slave_gone(GP(inst)->py, fn);
}

void model_setup_experiment(Instance *inst, int tol_defined, double tol) {
    if (tol_defined)
        fmu_log(inst, fmi2OK, "the master's tolerance %g is not used; the parameter rtol "
                "(%g) sets the integrator tolerance", tol, inst->value[GP_VAR_RTOL]);
}

static int is_reference(const double *v) { return v[GP_VAR_ENGINE] != 0.0; }

/* -- checks ---------------------------------------------------------------------------- */
/* A double as Python's repr writes it (shortest text that reads back, "0.5", "1e-05",
 * "2.0"), for messages that say what the Python API says. */
static void py_repr(double x, char *out, size_t n) {
    if (!isfinite(x)) {
        snprintf(out, n, "%s", isnan(x) ? "nan" : x > 0 ? "inf" : "-inf");
        return;
    }
    for (int p = 1; p <= 17; p++) {
        snprintf(out, n, "%.*g", p, x);
        if (strtod(out, NULL) == x) break;
    }
    const char *e = strchr(out, 'e');
    int ex = e ? atoi(e + 1) : 0;
    if (e && ex >= -4 && ex < 16) { /* Python writes these without an exponent */
        char digits[40];
        snprintf(digits, sizeof digits, "%.*s", (int)(e - out), out);
        int decimals = 0;
        const char *dot = strchr(digits, '.');
        if (dot) decimals = (int)strlen(dot + 1);
        decimals -= ex;
        snprintf(out, n, "%.*f", decimals > 0 ? decimals : 0, x);
    }
    if (!strpbrk(out, ".en")) strncat(out, ".0", n - strlen(out) - 1);
}

/* equations.check_friction_coefficients in the FMU's names (mu_static 0: equal to mu). */
static int friction_refuses(const double *v, char *msg, size_t n) {
    double ms = v[GP_VAR_MU_STATIC], mu = v[GP_VAR_MU];
    char r[40];
    if (ms == 0.0 || ms == mu) return 0;
    py_repr(ms, r, sizeof r);
    if (ms < mu) {
        snprintf(msg, n, "mu_static = %s is out of range; allowed [mu, 1] = [%g, 1] (static "
                 "friction is at least the kinetic mu), or None for mu", r, mu);
        return 1;
    }
    int law = (int)v[GP_VAR_FRICTION];
    if (law == GP_FRICTION_OFF || law == GP_FRICTION_NOMINAL) {
        snprintf(msg, n, "mu_static = %s (> mu = %g) needs friction = 'stick_slip' or "
                 "'regularized': friction = '%s' has no static friction", r, mu,
                 GP_FRICTION_NAMES[law]);
        return 1;
    }
    if (law == GP_FRICTION_REGULARIZED && v[GP_VAR_STRIBECK] == 0.0) {
        snprintf(msg, n, "mu_static = %s (> mu = %g) with friction = 'regularized' needs "
                 "stribeck_velocity: the regularized law has no stick state and sees "
                 "mu_static only through the Stribeck curve", r, mu);
        return 1;
    }
    return 0;
}

/* The gear data and choices the values select (GP_ROLE). */
static void vectors(const double *v, double *gear, double *choice) {
    memcpy(choice, GP_CHOICE_DEFAULT, sizeof GP_CHOICE_DEFAULT);
    for (int i = 0; i < MODEL_NVARS; i++) {
        const GpRole *r = &GP_ROLE[i];
        if (r->role == ROLE_GEAR) {
            gear[r->slot] = v[i];
        } else if (r->role == ROLE_CHOICE) {
            double x = r->ncodes ? r->code[(int)v[i]] : v[i];
            if (!r->ncodes && v[i] == 0.0 && r->none != NONE_ZERO)
                x = r->none == NONE_NAN ? NAN : v[GP_VAR_MU]; /* NONE_MU: equal to mu */
            choice[r->slot] = x;
        }
    }
}

/* The message of a refused set of parameters, or 0. */
static int parameters_refused(const double *v, char *msg, size_t n) {
    return gp_rule_refuses(v, msg, n) || friction_refuses(v, msg, n);
}

/* -- the fast engine ---------------------------------------------------------------------- */
static void put_inputs(const double *v, double *x) {
    x[GP_X_TORQUE] = v[GP_VAR_TORQUE];
    x[GP_X_SPEED] = v[GP_VAR_SPEED];
    x[GP_X_LOAD] = v[GP_VAR_LOAD_SPEED];
    x[GP_X_LOADON] = v[GP_VAR_LOADON] != 0.0 ? 1.0 : 0.0;
}

static void take_outputs(double *v, const double *x) {
    for (int i = 0; i < MODEL_NVARS; i++)
        if (GP_ROLE[i].role == ROLE_OUTPUT) v[i] = x[GP_X_REC + GP_ROLE[i].slot];
}

/* A new fast engine of the values v, or NULL with the reason in msg. */
static GpModel *build_fast(const double *v, char *msg, size_t n) {
    double gear[GP_N_GEAR], choice[GP_N_CHOICE];
    vectors(v, gear, choice);
    int64_t status = 0;
    double eps = NAN;
    GpModel *m = gp_model_new(gear, choice, &status, &eps);
    if (!m) {
        if (status < 0 || status >= (int64_t)(sizeof GP_SETUP_TEXT / sizeof *GP_SETUP_TEXT))
            snprintf(msg, n, "engine construction failed: out of memory (set-up status %lld)",
                     (long long)status);
        else
            snprintf(msg, n, GP_SETUP_TEXT[status], eps);
    }
    return m;
}

static int same_parameters(const double *a, const double *b) {
    for (int i = 0; i < MODEL_NVARS; i++)
        if (MODEL_VARS[i].causality == 'p' && a[i] != b[i]) return 0;
    return 1;
}

fmi2Status model_exit_init(Instance *inst) {
    Gp *g = GP(inst);
    double *v = inst->value;
    char msg[2048];
    drop_engines(g);
    if (parameters_refused(v, msg, sizeof msg)) {
        fmu_log(inst, fmi2Error, "fmi2ExitInitializationMode refused: invalid parameters: %s",
                msg);
        return fmi2Error;
    }
    if (is_reference(v)) {
        g->py = py_slave_new(inst, GP_PY_WHY);
        if (!g->py) return fmi2Error; /* it said why */
        if (py_slave_init(g->py, v, inst->start_time) > fmi2Warning) {
            drop_engines(g);
            return fmi2Error;
        }
        memcpy(g->built, v, sizeof g->built);
        return fmi2OK;
    }
    g->fast = build_fast(v, msg, sizeof msg);
    if (!g->fast) {
        fmu_log(inst, fmi2Error, "fmi2ExitInitializationMode refused: invalid parameters: %s",
                msg);
        return fmi2Error;
    }
    double *x = gp_model_block(g->fast);
    put_inputs(v, x);
    int64_t code = gp_model_init(g->fast, inst->start_time);
    if (code != GP_STEP_DONE) {
        fmu_log(inst, fmi2Error, "fmi2ExitInitializationMode refused: %s",
                code == GP_STEP_FAILED ? "initialization failed: the static equilibrium under "
                "the torque has no solution" : code == GP_STEP_NONFINITE
                ? "initialization failed: an output is not finite"
                : "input refused: an input is out of range");
        drop_engines(g);
        return fmi2Error;
    }
    take_outputs(v, x);
    memcpy(g->built, v, sizeof g->built);
    return fmi2OK;
}

/* Why the fast engine's step failed, from its summary (`FastEngine._raise_failure`);
 * returns 1 when the failure is for good (fmi2Error), 0 when a smaller step may do. */
static int failure_text(GpModel *m, char *out, size_t n) {
    const double *s = gp_model_summary(m);
    int status = (int)s[GP_O_STATUS];
    if (status == GP_STATUS_MISSED || status == GP_STATUS_UNBOUNDED) {
        int cs = (int)s[GP_O_CFAIL];
        const char *where = cs >= 0 && cs < 3 ? GP_FLANK_STATE[cs] : "?";
        if (status == GP_STATUS_MISSED)
            snprintf(out, n, GP_FAIL_MISSED, s[GP_O_TFAIL], where, s[GP_O_DFAIL]);
        else
            snprintf(out, n, GP_FAIL_UNBOUNDED, s[GP_O_TFAIL], where, s[GP_O_DFAIL],
                     s[GP_O_BFAIL]);
        return 1;
    }
    if (status == GP_STATUS_EVENTS)
        snprintf(out, n, "RuntimeError: more than %lld contact switches in one step (t = %.9g "
                 "s): the run stalls (docs/limits.md, event-count rule)",
                 (long long)gp_model_max_events(m), s[GP_O_TFAIL]);
    else
        snprintf(out, n, "Runge-Kutta step size underflow at t = %.9g s", s[GP_O_TFAIL]);
    return 0;
}

fmi2Status model_do_step(Instance *inst, double t, double h) {
    Gp *g = GP(inst);
    double *v = inst->value;
    if (g->py) return py_slave_step(g->py, v, t, h);
    double *x = gp_model_block(g->fast);
    put_inputs(v, x);
    gp_model_early_return(g->fast, inst->early_return);
    int64_t code = gp_model_step(g->fast, t, h);
    if (code == GP_STEP_DONE) {
        take_outputs(v, x);
        g->stepped = 1;
        if (inst->early_return && gp_model_time(g->fast) < t + h)
            inst->step_end = gp_model_time(g->fast); /* stopped at a contact event */
        return fmi2OK;
    }
    char why[2048], r1[40], r2[40];
    if (code == GP_STEP_REFUSED) {
        double now = gp_model_time(g->fast);
        py_repr(t, r1, sizeof r1);
        py_repr(now, r2, sizeof r2);
        if (!(t + h > now))
            fmu_log(inst, fmi2Error, "step refused: t_end = %.17g must be after the current "
                    "time %s", t + h, r2);
        else
            fmu_log(inst, fmi2Error, "step refused: currentCommunicationPoint = %s s does not "
                    "match the FMU's time %s s (restore an FMU state to go back)", r1, r2);
        return fmi2Error;
    }
    int for_good = 0;
    if (code == GP_STEP_FAILED)
        for_good = failure_text(g->fast, why, sizeof why);
    else
        snprintf(why, sizeof why, "output %s is not finite",
                 GP_RECORD_NAMES[(int)x[GP_X_BAD]]);
    /* the compiled step rolled the state back to the step start */
    fmu_log(inst, for_good ? fmi2Error : fmi2Discard, "step from t = %g s with h = %g s "
            "failed: %s; the state is that of the step start", t, h, why);
    return for_good ? fmi2Error : fmi2Discard;
}

/* -- the model's state: a tag, then the fast engine's state words or the Python slave's
 *    serialized state ------------------------------------------------------------------- */
enum { TAG_NONE = 0, TAG_FAST = 1, TAG_PY = 2 };
#define STATE_HEAD (2 * sizeof(double)) /* tag, stepped */

fmi2Status model_state_size(Instance *inst, size_t *n) {
    Gp *g = GP(inst);
    size_t body = 0;
    if (g->fast) body = gp_model_state_words(g->fast) * sizeof(double);
    if (g->py && py_slave_state_size(g->py, &body) > fmi2Warning) return fmi2Error;
    *n = STATE_HEAD + body;
    return fmi2OK;
}

fmi2Status model_state_save(Instance *inst, unsigned char *out, size_t n) {
    Gp *g = GP(inst);
    double head[2] = {g->fast ? TAG_FAST : g->py ? TAG_PY : TAG_NONE, g->stepped};
    memcpy(out, head, sizeof head);
    if (g->fast) gp_model_get_state(g->fast, (double *)(out + STATE_HEAD));
    if (g->py) return py_slave_state_save(g->py, out + STATE_HEAD, n - STATE_HEAD);
    return fmi2OK;
}

fmi2Status model_state_load(Instance *inst, const unsigned char *in, size_t n,
                            const double *values) {
    Gp *g = GP(inst);
    double head[2];
    char msg[2048];
    if (n < STATE_HEAD) goto bad;
    memcpy(head, in, sizeof head);
    in += STATE_HEAD;
    n -= STATE_HEAD;
    if (head[0] == TAG_NONE) {
        if (n) goto bad;
        drop_engines(g);
        return fmi2OK;
    }
    if (head[0] == TAG_FAST) {
        GpModel *m = g->fast;
        int same = m && same_parameters(values, g->built);
        if (!same && !(m = build_fast(values, msg, sizeof msg))) {
            fmu_log(inst, fmi2Error, "fmi2SetFMUstate refused: %s; the FMU keeps its current "
                    "state", msg);
            return fmi2Error;
        }
        if (n != gp_model_state_words(m) * sizeof(double)) {
            if (m != g->fast) gp_model_free(m);
            goto bad;
        }
        double *words = malloc(n);
        if (!words) {
            if (m != g->fast) gp_model_free(m);
            return fmi2Error;
        }
        memcpy(words, in, n); /* the bytes need not be aligned */
        gp_model_set_state(m, words);
        free(words);
        if (m != g->fast) {
            drop_engines(g);
            g->fast = m;
            memcpy(g->built, values, sizeof g->built);
        }
        g->stepped = head[1] != 0.0;
        return fmi2OK;
    }
    if (head[0] == TAG_PY) {
        PySlave *p = g->py;
        if (!p && !(p = py_slave_new(inst, GP_PY_WHY))) return fmi2Error;
        if (py_slave_state_load(p, in, n) > fmi2Warning) {
            if (p != g->py) py_slave_free(p);
            return fmi2Error;
        }
        if (p != g->py) {
            drop_engines(g);
            g->py = p;
        }
        memcpy(g->built, values, sizeof g->built);
        g->stepped = head[1] != 0.0;
        return fmi2OK;
    }
bad:
    fmu_log(inst, fmi2Error, "fmi2SetFMUstate refused: the state is from a GearPair FMU with "
            "another interface; the FMU keeps its current state");
    return fmi2Error;
}
