/* The generic FMI 3.0 co-simulation layer (with fmi3_states.c and fmi3_none.c): every
 * fmi3 function, for any model part that fulfils fmu.h. It is the FMI 2.0 layer's sibling (fmi2Functions.c) over the same contract
 * and the same generated variable table (config.h); it names no model. FMI 3 adds the
 * independent variable `time` (value reference MODEL_TIME_VR, given by the build) and types
 * the variables of the table as Float64 (Real), Int32 (Integer), Boolean, and Enumeration
 * (an Integer with codes: set and got as Int64), as the FMI 3 modelDescription declares them.
 *
 * - The FMI 3.0 co-simulation state machine (Instantiated, Initialization Mode, Event Mode,
 *   Step Mode, Terminated): a call not allowed in the instance's state returns fmi3Error
 *   with a log message and changes nothing. Configuration Mode (structural parameters),
 *   clocks, intermediate update and Model Exchange are not provided: refused the same way.
 * - eventModeUsed: fmi3ExitInitializationMode enters Event Mode, fmi3EnterStepMode leaves
 *   it. earlyReturnAllowed: fmi3DoStep may end at the first event inside the step that the
 *   model part reports (inst->early_return, inst->step_end; fmu.h), with earlyReturn = true,
 *   lastSuccessfulTime = the event's time and eventHandlingNeeded = true with Event Mode
 *   used. A master that goes on stepping from lastSuccessfulTime without Event Mode gets the
 *   same results: the model part has handled the event when it returns.
 * - fmi3Set* checks as in FMI 2: unknown value references, outputs, fixed parameters after
 *   initialization, non-finite or out-of-range values and codes outside their choices are
 *   refused with fmi3Error, the old value kept; a value refused before initialization ended
 *   makes fmi3ExitInitializationMode refuse, naming it.
 * - Messages of status warning and worse always reach the host's logger; status OK follows
 *   loggingOn and fmi3SetDebugLogging.
 * - FMU states: fmi3_states.c; what the FMU does not provide: fmi3_none.c.
 */
#define _GNU_SOURCE
#include <ctype.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3_layer.h"

#ifndef MODEL_TIME_VR
#error "MODEL_TIME_VR (the value reference of the independent variable time) must be given"
#endif

static const char *const STATE_NAME[] = {"Instantiated", "Initialization Mode", "Event Mode",
                                         "Step Mode", "Terminated"};

/* -- logging ---------------------------------------------------------------------------- */
static int debug_enabled(const Instance *s, const char *category) {
    if (!s->logging_on) return 0;
    if (!s->categories) return 1;
    for (size_t i = 0; i < s->n_categories; i++)
        if (category && !strcmp(s->categories[i], category)) return 1;
    return 0;
}

static const char *status_category(fmi2Status st) {
    switch (st) {
    case fmi2Warning: return "logStatusWarning";
    case fmi2Discard: return "logStatusDiscard";
    case fmi2Error: return "logStatusError";
    case fmi2Fatal: return "logStatusFatal";
    default: return "logAll";
    }
}

/* The message as it is (an FMI 3 logger formats nothing). The model part's messages name
 * the FMI 2 calls of the shared contract ("fmi2ExitInitializationMode", "fmi2SetFMUstate"):
 * they are given the names of their FMI 3 counterparts (same length: fmi2X -> fmi3X,
 * FMUstate -> FMUState). The status codes of both standards are the same numbers. */
void fmu_emit(Instance *s, fmi2Status status, const char *category, const char *msg) {
    Fmi3 *f = F(s);
    if (!f->log) return;
    if (status == fmi2OK && !debug_enabled(s, category)) return;
    size_t n = strlen(msg);
    char small[2048], *buf = n < sizeof small ? small : malloc(n + 1);
    if (!buf) return;
    memcpy(buf, msg, n + 1);
    for (char *p = buf; (p = strstr(p, "fmi2")) != NULL; p += 4)
        if (isupper((unsigned char)p[4])) p[3] = '3';
    for (char *p = buf; (p = strstr(p, "FMUstate")) != NULL; p += 8) p[3] = 'S';
    f->log(f->env, (fmi3Status)status, category ? category : status_category(status), buf);
    if (buf != small) free(buf);
}

void fmu_log(Instance *s, fmi2Status status, const char *fmt, ...) {
    char buf[8192];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    fmu_emit(s, status, status_category(status), buf);
}

/* -- checks ----------------------------------------------------------------------------- */
static const char *hint(const Fmi3 *f, const char *fn) {
    int step = !strcmp(fn, "fmi3DoStep");
    if (step && f->state == S_INSTANTIATED)
        return ": call fmi3EnterInitializationMode and fmi3ExitInitializationMode first";
    if (step && f->state == S_INIT) return ": call fmi3ExitInitializationMode first";
    if (step && f->state == S_EVENT) return ": call fmi3EnterStepMode first";
    if (!strcmp(fn, "fmi3EnterEventMode") && f->state == S_EVENT)
        return ": the instance is in Event Mode already";
    return "";
}

/* Refuse a call not allowed in the instance's state (or when the model can no longer run). */
int fmi3_allowed(Fmi3 *f, unsigned states, const char *fn) {
    if (model_gone(&f->base, fn)) return 0;
    if (IN(f->state, states)) return 1;
    ERR(f, "%s is not allowed in %s%s", fn, STATE_NAME[f->state], hint(f, fn));
    return 0;
}

/* FMI 3 types of the table's variables: 'F' Float64, 'I' Int32, 'B' Boolean, 'E' an
 * Enumeration (an Integer with codes; the modelDescription declares it so). */
static char kind_of(const FmuVar *v) {
    return v->type == 'R' ? 'F' : v->type == 'B' ? 'B' : v->codes ? 'E' : 'I';
}

static const char *kind_name(char k) {
    return k == 'F' ? "Float64" : k == 'I' ? "Int32" : k == 'E' ? "Enumeration" : "Boolean";
}

/* The MODEL_VARS index of value reference vr of this kind, MODEL_NVARS for time, or -1. */
static int find_var(unsigned vr, char kind) {
    if (vr == MODEL_TIME_VR) return kind == 'F' ? MODEL_NVARS : -1;
    int i = -1;
    if (vr < MODEL_NVARS && MODEL_VARS[vr].vr == vr) i = (int)vr;
    for (int k = 0; i < 0 && k < MODEL_NVARS; k++)
        if (MODEL_VARS[k].vr == vr) i = k;
    return i >= 0 && kind_of(&MODEL_VARS[i]) == kind ? i : -1;
}

static int check_refs(Fmi3 *f, const char *fn, const fmi3ValueReference vr[], size_t nvr,
                      const void *values, size_t nv, char kind) {
    if (nvr == 0 && nv == 0) return 1;
    if (!vr || !values) {
        ERR(f, "%s: null value reference or value array for %zu values", fn, nvr);
        return 0;
    }
    if (nv != nvr) {
        ERR(f, "%s: nValues = %zu must equal nValueReferences = %zu (this FMU's variables "
            "are scalars)", fn, nv, nvr);
        return 0;
    }
    for (size_t i = 0; i < nvr; i++)
        if (find_var(vr[i], kind) < 0) {
            ERR(f, "%s: value reference %u is not a %s variable of this FMU", fn, vr[i],
                kind_name(kind));
            return 0;
        }
    return 1;
}

static void range_text(const FmuVar *v, char *buf, size_t n) {
    const char *u = v->unit[0] ? " " : "";
    if (v->codes)
        snprintf(buf, n, "allowed %s", v->codes);
    else if (v->has_lo && v->has_hi)
        snprintf(buf, n, "allowed %c%.10g, %.10g]%s%s", v->lo_open ? '(' : '[', v->lo, v->hi,
                 u, v->unit);
    else if (v->has_lo)
        snprintf(buf, n, "allowed %s %.10g%s%s", v->lo_open ? ">" : ">=", v->lo, u, v->unit);
    else if (v->has_hi)
        snprintf(buf, n, "allowed <= %.10g%s%s", v->hi, u, v->unit);
    else
        snprintf(buf, n, "allowed any finite value");
}

/* Whether this instance may set variable v now; logs why not. */
static int settable(Fmi3 *f, const char *fn, const FmuVar *v) {
    if (v->causality == 'o') {
        ERR(f, "%s: %s is an output and cannot be set", fn, v->name);
        return 0;
    }
    if ((f->state == S_EVENT || f->state == S_STEP) && !v->tunable) {
        ERR(f, "%s: parameter %s is fixed (variability fixed): it can be set only before "
            "fmi3ExitInitializationMode; it keeps its value (reset the FMU to change it)", fn,
            v->name);
        return 0;
    }
    return 1;
}

static int value_ok(Fmi3 *f, const char *fn, const FmuVar *v, double x) {
    int ok = isfinite(x) && !(v->has_lo && (v->lo_open ? x <= v->lo : x < v->lo)) &&
             !(v->has_hi && x > v->hi);
    if (!ok) {
        char r[256];
        range_text(v, r, sizeof r);
        if (v->type == 'I')
            ERR(f, "%s: %s = %.0f is out of range; %s. The value is not taken: %s keeps its "
                "value", fn, v->name, x, r, v->name);
        else
            ERR(f, "%s: %s = %.10g%s%s is %s; %s. The value is not taken: %s keeps its value",
                fn, v->name, x, v->unit[0] ? " " : "", v->unit,
                isfinite(x) ? "out of range" : "not finite", r, v->name);
    }
    return ok;
}

/* -- values refused before initialization ended ----------------------------------------- */
/* Remember a refused fmi3Set* call (before or in Initialization Mode): the value at `bad`
 * was refused, the others of the call were not taken either. Returns fmi3Error. */
static fmi3Status refuse(Fmi3 *f, const char *fn, const fmi3ValueReference vr[], size_t nvr,
                         size_t bad, char kind, const double *values) {
    Instance *s = &f->base;
    if (f->state != S_INSTANTIATED && f->state != S_INIT) return fmi3Error;
    for (size_t i = 0; i < nvr; i++) {
        int k = find_var(vr[i], kind);
        if (k < 0 || k == MODEL_NVARS || MODEL_VARS[k].causality == 'o') continue;
        if (!s->refused[k].what) s->n_refused++;
        s->refused[k].what = i == bad ? 'r' : 'n';
        s->refused[k].fn = fn;
        if (kind == 'B')
            snprintf(s->refused[k].text, sizeof s->refused[k].text, "%s",
                     values[i] != 0.0 ? "true" : "false");
        else
            snprintf(s->refused[k].text, sizeof s->refused[k].text,
                     kind == 'F' ? "%.10g" : "%.0f", values[i]);
    }
    return fmi3Error;
}

/* A set that went through: its variables hold values the user asked for again. */
static void taken(Instance *s, const fmi3ValueReference vr[], size_t nvr, char kind) {
    for (size_t i = 0; s->n_refused && i < nvr; i++) {
        int k = find_var(vr[i], kind);
        if (k >= 0 && k < MODEL_NVARS && s->refused[k].what) {
            s->refused[k].what = 0;
            s->n_refused--;
        }
    }
}

static fmi3Status refused_report(Fmi3 *f) {
    Instance *s = &f->base;
    char list[4096];
    size_t o = 0;
    list[0] = 0;
    for (int k = 0; k < MODEL_NVARS && o < sizeof list; k++) {
        if (!s->refused[k].what) continue;
        o += (size_t)snprintf(list + o, sizeof list - o, "%s%s = %s was %s at %s",
                              o ? ", " : "", MODEL_VARS[k].name, s->refused[k].text,
                              s->refused[k].what == 'r' ? "refused"
                                                        : "not taken (refused with the call)",
                              s->refused[k].fn);
    }
    ERR(f, "fmi3ExitInitializationMode refused: %s; set %s or leave %s unset (the FMU stays "
        "in Initialization Mode)", list, s->n_refused > 1 ? "valid values" : "a valid value",
        s->n_refused > 1 ? "them" : "it");
    return fmi3Error;
}

/* -- get and set, for any type -------------------------------------------------------------- */
static int get_ok(Fmi3 *f, const char *fn, char kind, const fmi3ValueReference vr[],
                  size_t nvr, const void *dst, size_t nv) {
    return f && fmi3_allowed(f, GET_STATES, fn) && check_refs(f, fn, vr, nvr, dst, nv, kind);
}

/* The value of variable index k (time: the FMU's time). */
static double value_of(const Fmi3 *f, int k) {
    return k == MODEL_NVARS ? f->time : f->base.value[k];
}

/* fmi3Set*: the values as doubles in x, every one checked first; none taken when one is
 * refused. */
static fmi3Status set_values(Fmi3 *f, const char *fn, char kind, const fmi3ValueReference vr[],
                             size_t nvr, const void *src, size_t nv, const double *x) {
    if (!f || !fmi3_allowed(f, SET_STATES, fn) || !check_refs(f, fn, vr, nvr, src, nv, kind))
        return fmi3Error;
    for (size_t i = 0; i < nvr; i++) {
        int k = find_var(vr[i], kind);
        if (k == MODEL_NVARS) {
            ERR(f, "%s: time is the independent variable and cannot be set", fn);
            return refuse(f, fn, vr, nvr, i, kind, x);
        }
        if (!settable(f, fn, &MODEL_VARS[k]) || (kind != 'B' &&
                                                !value_ok(f, fn, &MODEL_VARS[k], x[i])))
            return refuse(f, fn, vr, nvr, i, kind, x);
    }
    for (size_t i = 0; i < nvr; i++) f->base.value[find_var(vr[i], kind)] = x[i];
    taken(&f->base, vr, nvr, kind);
    return fmi3OK;
}

/* The values of a typed array as doubles (x: nv of them, or NULL when out of memory). */
#define AS_DOUBLES(T, conv)                                                                  \
    double small[64] = {0}, *x = nv <= 64 ? small : calloc(nv, sizeof *x);                  \
    if (!x) return fmi3Error;                                                                \
    for (size_t i = 0; values && i < nv; i++) {                                              \
        T v_ = values[i];                                                                    \
        x[i] = conv;                                                                         \
    }

static void start_values(Fmi3 *f) {
    Instance *s = &f->base;
    for (int i = 0; i < MODEL_NVARS; i++) s->value[i] = MODEL_VARS[i].start;
    memset(s->refused, 0, sizeof s->refused);
    s->n_refused = 0;
    s->start_time = 0.0;
    s->last_successful_time = NAN;
    f->time = 0.0;
    f->event_pending = 0;
}

/* ======================================================================================== */
FMI3_Export const char *fmi3GetVersion(void) { return fmi3Version; }

FMI3_Export fmi3Instance fmi3InstantiateCoSimulation(
    fmi3String name, fmi3String token, fmi3String resources, fmi3Boolean visible,
    fmi3Boolean logging_on, fmi3Boolean event_mode_used, fmi3Boolean early_return_allowed,
    const fmi3ValueReference required[], size_t n_required, fmi3InstanceEnvironment env,
    fmi3LogMessageCallback log, fmi3IntermediateUpdateCallback intermediate) {
    (void)visible, (void)required, (void)intermediate;
    Fmi3 *f = calloc(1, sizeof *f);
    if (!f) return NULL;
    f->env = env;
    f->log = log;
    f->base.name = strdup(name ? name : "");
    f->base.logging_on = logging_on;
    f->base.early_return = early_return_allowed;
    f->event_mode_used = event_mode_used;
    f->state = S_INSTANTIATED;
    start_values(f);
    if (!f->base.name) goto fail;
    if (!token || strcmp(token, MODEL_GUID)) {
        ERR(f, "fmi3InstantiateCoSimulation: instantiationToken %s does not match this FMU's "
            "%s", token ? token : "(null)", MODEL_GUID);
        goto fail;
    }
    if (n_required) {
        ERR(f, "fmi3InstantiateCoSimulation: %zu required intermediate variables, but this "
            "FMU provides no intermediate update (providesIntermediateUpdate is false)",
            n_required);
        goto fail;
    }
    /* the resources folder: an absolute path, by FMI 3 with a trailing separator (dropped
     * here); none given: an empty path, which only the model parts that read it miss */
    f->base.resources = strdup(resources ? resources : "");
    if (!f->base.resources) goto fail;
    for (size_t n = strlen(f->base.resources); n > 1 && (f->base.resources[n - 1] == '/' ||
                                                         f->base.resources[n - 1] == '\\');)
        f->base.resources[--n] = 0;
    if (model_new(&f->base)) goto fail;
    return f;
fail:
    free(f->base.resources);
    free(f->base.name);
    free(f);
    return NULL;
}

static fmi3Instance not_provided(fmi3String name, fmi3InstanceEnvironment env,
                                 fmi3LogMessageCallback log, const char *what) {
    if (log) {
        char msg[256];
        snprintf(msg, sizeof msg, "this FMU provides co-simulation only, not %s", what);
        log(env, fmi3Error, "logStatusError", msg);
    }
    (void)name;
    return NULL;
}

FMI3_Export fmi3Instance fmi3InstantiateModelExchange(
    fmi3String name, fmi3String token, fmi3String resources, fmi3Boolean visible,
    fmi3Boolean logging_on, fmi3InstanceEnvironment env, fmi3LogMessageCallback log) {
    (void)token, (void)resources, (void)visible, (void)logging_on;
    return not_provided(name, env, log, "Model Exchange");
}

FMI3_Export fmi3Instance fmi3InstantiateScheduledExecution(
    fmi3String name, fmi3String token, fmi3String resources, fmi3Boolean visible,
    fmi3Boolean logging_on, fmi3InstanceEnvironment env, fmi3LogMessageCallback log,
    fmi3ClockUpdateCallback clock_update, fmi3LockPreemptionCallback lock,
    fmi3UnlockPreemptionCallback unlock) {
    (void)token, (void)resources, (void)visible, (void)logging_on, (void)clock_update;
    (void)lock, (void)unlock;
    return not_provided(name, env, log, "Scheduled Execution");
}

FMI3_Export void fmi3FreeInstance(fmi3Instance c) {
    Fmi3 *f = c;
    if (!f) return;
    fmi3_free_states(f);
    model_free(&f->base);
    for (size_t i = 0; i < f->base.n_categories; i++) free(f->base.categories[i]);
    free(f->base.categories);
    free(f->base.resources);
    free(f->base.name);
    free(f);
}

FMI3_Export fmi3Status fmi3SetDebugLogging(fmi3Instance c, fmi3Boolean on, size_t n,
                                           const fmi3String categories[]) {
    Fmi3 *f = c;
    if (!f) return fmi3Error;
    if (n && !categories) {
        ERR(f, "fmi3SetDebugLogging: %zu categories but a null array", n);
        return fmi3Error;
    }
    char **copy = NULL;
    if (n) {
        copy = calloc(n, sizeof *copy);
        if (!copy) return fmi3Error;
        for (size_t i = 0; i < n; i++) copy[i] = strdup(categories[i] ? categories[i] : "");
    }
    for (size_t i = 0; i < f->base.n_categories; i++) free(f->base.categories[i]);
    free(f->base.categories);
    f->base.categories = copy;
    f->base.n_categories = n;
    f->base.logging_on = on;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3EnterInitializationMode(fmi3Instance c, fmi3Boolean tol_defined,
                                                   fmi3Float64 tol, fmi3Float64 start,
                                                   fmi3Boolean stop_defined, fmi3Float64 stop) {
    Fmi3 *f = c;
    if (!f || !fmi3_allowed(f, B(S_INSTANTIATED), "fmi3EnterInitializationMode")) return fmi3Error;
    if (!isfinite(start) || (stop_defined && !(stop >= start))) {
        ERR(f, "fmi3EnterInitializationMode: startTime = %.17g s must be finite and stopTime "
            "(%.17g s) not before it", start, stop_defined ? stop : start);
        return fmi3Error;
    }
    f->base.start_time = start;
    f->time = start;
    model_setup_experiment(&f->base, tol_defined, tol);
    f->state = S_INIT;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3ExitInitializationMode(fmi3Instance c) {
    Fmi3 *f = c;
    if (!f || !fmi3_allowed(f, B(S_INIT), "fmi3ExitInitializationMode")) return fmi3Error;
    if (f->base.n_refused) return refused_report(f);
    /* refused (e.g. a combination of parameters): the instance stays in Initialization
     * Mode, so the master may correct a parameter and call this again */
    fmi2Status st = model_exit_init(&f->base);
    if (st <= fmi2Warning) f->state = f->event_mode_used ? S_EVENT : S_STEP;
    f->base.last_successful_time = NAN;
    f->time = f->base.start_time;
    f->event_pending = 0;
    return (fmi3Status)st;
}

FMI3_Export fmi3Status fmi3EnterEventMode(fmi3Instance c) {
    Fmi3 *f = c;
    if (!f || !fmi3_allowed(f, B(S_STEP), "fmi3EnterEventMode")) return fmi3Error;
    if (!f->event_mode_used) {
        ERR(f, "fmi3EnterEventMode: the instance was made with eventModeUsed = false");
        return fmi3Error;
    }
    f->state = S_EVENT;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3Terminate(fmi3Instance c) {
    Fmi3 *f = c;
    if (f && model_gone(&f->base, "fmi3Terminate")) { /* nothing to end: the process is ending */
        f->state = S_TERMINATED;
        return fmi3OK;
    }
    if (!f || !fmi3_allowed(f, B(S_EVENT) | B(S_STEP), "fmi3Terminate")) return fmi3Error;
    f->state = S_TERMINATED;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3Reset(fmi3Instance c) {
    Fmi3 *f = c;
    if (!f || !fmi3_allowed(f, ANY, "fmi3Reset")) return fmi3Error;
    model_reset(&f->base);
    start_values(f);
    f->state = S_INSTANTIATED;
    return fmi3OK;
}

/* -- get/set ----------------------------------------------------------------------------- */
FMI3_Export fmi3Status fmi3GetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                      fmi3Float64 values[], size_t nv) {
    if (!get_ok(c, "fmi3GetFloat64", 'F', vr, nvr, values, nv)) return fmi3Error;
    for (size_t i = 0; i < nvr; i++) values[i] = value_of(c, find_var(vr[i], 'F'));
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3GetInt32(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                    fmi3Int32 values[], size_t nv) {
    if (!get_ok(c, "fmi3GetInt32", 'I', vr, nvr, values, nv)) return fmi3Error;
    for (size_t i = 0; i < nvr; i++) values[i] = (fmi3Int32)value_of(c, find_var(vr[i], 'I'));
    return fmi3OK;
}

/* Enumerations are got and set as Int64 (FMI 3.0, 2.2.6.1). */
FMI3_Export fmi3Status fmi3GetInt64(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                    fmi3Int64 values[], size_t nv) {
    if (!get_ok(c, "fmi3GetInt64", 'E', vr, nvr, values, nv)) return fmi3Error;
    for (size_t i = 0; i < nvr; i++) values[i] = (fmi3Int64)value_of(c, find_var(vr[i], 'E'));
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3GetBoolean(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                      fmi3Boolean values[], size_t nv) {
    if (!get_ok(c, "fmi3GetBoolean", 'B', vr, nvr, values, nv)) return fmi3Error;
    for (size_t i = 0; i < nvr; i++) values[i] = value_of(c, find_var(vr[i], 'B')) != 0.0;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3SetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                      const fmi3Float64 values[], size_t nv) {
    return set_values(c, "fmi3SetFloat64", 'F', vr, nvr, values, nv, values);
}

FMI3_Export fmi3Status fmi3SetInt32(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                    const fmi3Int32 values[], size_t nv) {
    AS_DOUBLES(fmi3Int32, (double)v_)
    fmi3Status st = set_values(c, "fmi3SetInt32", 'I', vr, nvr, values, nv, x);
    if (x != small) free(x);
    return st;
}

FMI3_Export fmi3Status fmi3SetInt64(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                    const fmi3Int64 values[], size_t nv) {
    /* a code beyond +-2^53 is out of range either way: clamp it before the conversion */
    AS_DOUBLES(fmi3Int64, (double)(v_ > (1LL << 53) ? (1LL << 53) : v_ < -(1LL << 53)
                                                                    ? -(1LL << 53) : v_))
    fmi3Status st = set_values(c, "fmi3SetInt64", 'E', vr, nvr, values, nv, x);
    if (x != small) free(x);
    return st;
}

FMI3_Export fmi3Status fmi3SetBoolean(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                      const fmi3Boolean values[], size_t nv) {
    AS_DOUBLES(fmi3Boolean, v_ ? 1.0 : 0.0)
    fmi3Status st = set_values(c, "fmi3SetBoolean", 'B', vr, nvr, values, nv, x);
    if (x != small) free(x);
    return st;
}

/* -- stepping and events ------------------------------------------------------------------- */
FMI3_Export fmi3Status fmi3DoStep(fmi3Instance c, fmi3Float64 t, fmi3Float64 h,
                                  fmi3Boolean no_set_prior, fmi3Boolean *event_needed,
                                  fmi3Boolean *terminate, fmi3Boolean *early,
                                  fmi3Float64 *last_time) {
    Fmi3 *f = c;
    (void)no_set_prior;
    if (!f || !fmi3_allowed(f, B(S_STEP), "fmi3DoStep")) return fmi3Error;
    if (!event_needed || !terminate || !early || !last_time) {
        ERR(f, "fmi3DoStep: null eventHandlingNeeded, terminateSimulation, earlyReturn or "
            "lastSuccessfulTime");
        return fmi3Error;
    }
    *event_needed = *terminate = *early = fmi3False;
    *last_time = f->time;
    if (!isfinite(t) || !isfinite(h) || !(h > 0.0)) {
        ERR(f, "fmi3DoStep refused: currentCommunicationPoint = %.17g s and "
            "communicationStepSize = %.17g s must be finite and the step size > 0; the FMU "
            "state is unchanged", t, h);
        return fmi3Error;
    }
    /* A refused step (fmi3Error) or one failed inside (fmi3Discard) leaves the state of the
     * step start, so the instance stays in Step Mode either way: the master may repeat the
     * step with other inputs or a smaller size. */
    f->base.step_end = t + h;
    fmi2Status st = model_do_step(&f->base, t, h);
    if (st <= fmi2Warning) {
        double end = f->base.step_end;
        int stopped = end < t + h; /* the model part returned early at an event */
        f->time = f->base.last_successful_time = stopped ? end : t + h;
        *early = stopped;
        *event_needed = stopped && f->event_mode_used;
        f->event_pending = *event_needed;
    } else if (st == fmi2Discard) {
        f->base.last_successful_time = t;
    }
    *last_time = f->time;
    return (fmi3Status)st;
}

FMI3_Export fmi3Status fmi3EnterStepMode(fmi3Instance c) {
    Fmi3 *f = c;
    if (!f || !fmi3_allowed(f, B(S_EVENT), "fmi3EnterStepMode")) return fmi3Error;
    f->state = S_STEP;
    return fmi3OK;
}

/* In Event Mode: the event the last step stopped at is handled (the model part switched
 * the contact state when it located it); nothing further is pending at this instant. */
FMI3_Export fmi3Status fmi3UpdateDiscreteStates(fmi3Instance c, fmi3Boolean *need_update,
                                                fmi3Boolean *terminate,
                                                fmi3Boolean *nominals_changed,
                                                fmi3Boolean *values_changed,
                                                fmi3Boolean *next_defined,
                                                fmi3Float64 *next_time) {
    Fmi3 *f = c;
    if (!f || !fmi3_allowed(f, B(S_EVENT), "fmi3UpdateDiscreteStates")) return fmi3Error;
    if (!need_update || !terminate || !nominals_changed || !values_changed || !next_defined ||
        !next_time) {
        ERR(f, "fmi3UpdateDiscreteStates: a null argument");
        return fmi3Error;
    }
    *need_update = *terminate = *nominals_changed = *values_changed = fmi3False;
    *next_defined = fmi3False;
    *next_time = 0.0;
    f->event_pending = 0;
    return fmi3OK;
}
