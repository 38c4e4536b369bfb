/* The generic FMI 3.0 co-simulation layer (with fmi3_states.c and fmi3_none.c): every
 * fmi3 function, for any model part that fulfils fmu.h. It is the FMI 2.0 layer's sibling
 * (fmi2Functions.c) over the same contract, the same generated variable table (config.h)
 * and the same generic files (fmu_layer.h: fmu_log.c, fmu_values.c, fmu_states.c); it names
 * no model. FMI 3 adds the
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
 * - fmi3Set* checks as in FMI 2 (fmu_values.c): unknown value references, outputs, fixed
 *   parameters after initialization, non-finite or out-of-range values and codes outside
 *   their choices are refused with fmi3Error, the old value kept; a value refused before
 *   initialization ended makes fmi3ExitInitializationMode refuse, naming it.
 * - Messages of status warning and worse always reach the host's logger; status OK follows
 *   loggingOn and fmi3SetDebugLogging.
 * - FMU states: fmi3_states.c; what the FMU does not provide: fmi3_none.c.
 */
#define _GNU_SOURCE
#include <ctype.h>
#include <math.h>
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
/* The message as it is (an FMI 3 logger formats nothing). The model part's messages name
 * the FMI 2 calls of the shared contract ("fmi2ExitInitializationMode", "fmi2SetFMUstate"):
 * they are given the names of their FMI 3 counterparts (same length: fmi2X -> fmi3X,
 * FMUstate -> FMUState). The status codes of both standards are the same numbers. */
void fmu_emit(Instance *s, fmi2Status status, const char *category, const char *msg) {
    Fmi3 *f = F(s);
    if (!f->log) return;
    if (status == fmi2OK && !fmu_debug_enabled(s, category)) return;
    size_t n = strlen(msg);
    char small[2048], *buf = n < sizeof small ? small : malloc(n + 1);
    if (!buf) return;
    memcpy(buf, msg, n + 1);
    for (char *p = buf; (p = strstr(p, "fmi2")) != NULL; p += 4)
        if (isupper((unsigned char)p[4])) p[3] = '3';
    for (char *p = buf; (p = strstr(p, "FMUstate")) != NULL; p += 8) p[3] = 'S';
    f->log(f->env, (fmi3Status)status, category ? category : fmu_status_category(status), buf);
    if (buf != small) free(buf);
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

/* What the FMI 3.0 API calls the table's types ('R' Float64, 'I' Int32, 'B' Boolean, 'E' an
 * Enumeration: an Integer with codes, as the modelDescription declares it), its independent
 * variable and the end of initialization. */
static const FmuApi API = {"Float64", "Int32", "Boolean", "Enumeration", MODEL_TIME_VR,
                           "fmi3ExitInitializationMode", "Initialization Mode"};

/* -- get and set, for any type -------------------------------------------------------------- */
static int find_var(unsigned vr, char kind) { return fmu_find_var(&API, vr, kind); }

static int get_ok(Fmi3 *f, const char *fn, char kind, const fmi3ValueReference vr[],
                  size_t nvr, const void *dst, size_t nv) {
    return f && fmi3_allowed(f, GET_STATES, fn) &&
           fmu_check_refs(&f->base, &API, fn, kind, vr, nvr, dst, nv);
}

/* The value of variable index k (time: the FMU's time). */
static double value_of(const Fmi3 *f, int k) {
    return k == MODEL_NVARS ? f->time : f->base.value[k];
}

/* fmi3Set*: the values as doubles in x, every one checked first; none taken when one is
 * refused. */
static fmi3Status set_values(Fmi3 *f, const char *fn, char kind, const fmi3ValueReference vr[],
                             size_t nvr, const void *src, size_t nv, const double *x) {
    if (!f || !fmi3_allowed(f, SET_STATES, fn)) return fmi3Error;
    int initialized = f->state == S_EVENT || f->state == S_STEP;
    return fmu_set_values(&f->base, &API, fn, kind, vr, nvr, src, nv, x, initialized)
               ? fmi3Error : fmi3OK;
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
    fmu_start_values(&f->base);
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
    fmu_release(&f->base);
    free(f);
}

FMI3_Export fmi3Status fmi3SetDebugLogging(fmi3Instance c, fmi3Boolean on, size_t n,
                                           const fmi3String categories[]) {
    Fmi3 *f = c;
    if (!f) return fmi3Error;
    return fmu_set_debug_logging(&f->base, "fmi3SetDebugLogging", on, n, categories) ? fmi3Error
                                                                                     : fmi3OK;
}

FMI3_Export fmi3Status fmi3EnterInitializationMode(fmi3Instance c, fmi3Boolean tol_defined,
                                                   fmi3Float64 tol, fmi3Float64 start,
                                                   fmi3Boolean stop_defined, fmi3Float64 stop) {
    Fmi3 *f = c;
    if (!f || !fmi3_allowed(f, B(S_INSTANTIATED), "fmi3EnterInitializationMode")) return fmi3Error;
    if (!fmu_times_ok(&f->base, "fmi3EnterInitializationMode", start, stop_defined, stop))
        return fmi3Error;
    f->base.start_time = start;
    f->time = start;
    model_setup_experiment(&f->base, tol_defined, tol);
    f->state = S_INIT;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3ExitInitializationMode(fmi3Instance c) {
    Fmi3 *f = c;
    if (!f || !fmi3_allowed(f, B(S_INIT), "fmi3ExitInitializationMode")) return fmi3Error;
    if (f->base.n_refused) {
        fmu_refused_report(&f->base, &API);
        return fmi3Error;
    }
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
    if (!get_ok(c, "fmi3GetFloat64", 'R', vr, nvr, values, nv)) return fmi3Error;
    for (size_t i = 0; i < nvr; i++) values[i] = value_of(c, find_var(vr[i], 'R'));
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
    return set_values(c, "fmi3SetFloat64", 'R', vr, nvr, values, nv, values);
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
    if (!fmu_step_ok(&f->base, "fmi3DoStep", t, h)) return fmi3Error;
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
