/* The generic FMI 2.0 co-simulation layer: every fmi2 function, for any model part that
 * fulfils fmu.h. It names no model; the variables come from the generated table.
 *
 * - The FMI 2.0 co-simulation state machine per instance: a call not allowed in the
 *   instance's mode returns fmi2Error with a log message and changes nothing.
 * - fmi2Set* checks against the variable table (fmu_values.c): unknown value references,
 *   outputs, fixed parameters after initialization, non-finite or out-of-range values and
 *   integer codes outside their choices are refused with fmi2Error, the old value kept. A
 *   value refused before initialization ended is remembered until a valid one is set:
 *   fmi2ExitInitializationMode refuses naming it.
 * - Log messages of status warning and worse always reach the host's logger; status OK
 *   (information) follows loggingOn and fmi2SetDebugLogging (fmu_log.c; the message goes
 *   out through `fmu_emit` here).
 * - FMU states: fmi2States.c over fmu_states.c.
 * - The resource location is read in every local file: form (`resource_folder`).
 */
#define _GNU_SOURCE
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "fmi2_layer.h"

static const char *const MODE_NAME[] = {"instantiated", "initialization mode",
                                        "step mode (initialized)", "terminated",
                                        "fatal error"};

/* -- logging ---------------------------------------------------------------------------- */
/* The message goes out as the format argument itself with every '%' doubled: a C host
 * that formats it prints the text, and hosts that take it verbatim (fmpy's ctypes logger)
 * show it as it is (a literal "%" appears doubled there). */
void fmu_emit(Instance *s, fmi2Status status, const char *category, const char *msg) {
    if (!s->host.logger) return;
    if (status == fmi2OK && !fmu_debug_enabled(s, category)) return;
    size_t n = strlen(msg), extra = 0;
    for (size_t i = 0; i < n; i++) extra += msg[i] == '%';
    char small[2048], *buf = n + extra < sizeof small ? small : malloc(n + extra + 1);
    if (!buf) return;
    char *o = buf;
    for (size_t i = 0; i < n; i++) {
        *o++ = msg[i];
        if (msg[i] == '%') *o++ = '%';
    }
    *o = 0;
    s->host.logger(s->host.componentEnvironment, s->name, status,
                   category ? category : fmu_status_category(status), buf);
    if (buf != small) free(buf);
}

/* -- checks ----------------------------------------------------------------------------- */
/* Refuse a call not allowed in the instance's mode (or when the model can no longer run). */
int fmi2_allowed(Instance *s, unsigned modes, const char *fn) {
    if (model_gone(s, fn)) return 0;
    if (IN(s->mode, modes)) return 1;
    fmu_log(s, fmi2Error, "%s is not allowed in %s%s", fn, MODE_NAME[s->mode],
            s->mode == M_INIT && !strcmp(fn, "fmi2DoStep")
                ? ": call fmi2ExitInitializationMode first"
            : s->mode == M_INSTANTIATED && !strcmp(fn, "fmi2DoStep")
                ? ": call fmi2EnterInitializationMode and fmi2ExitInitializationMode first"
                : "");
    return 0;
}

/* What the FMI 2.0 API calls the table's types and the end of initialization. */
static const FmuApi API = {"Real", "Integer", "Boolean", NULL, -1, "fmi2ExitInitializationMode",
                           "initialization mode"};

/* -- get and set, for any type ------------------------------------------------------------ */
#define GET_MODES (B(M_INIT) | B(M_STEP) | B(M_TERMINATED))
#define SET_MODES (B(M_INSTANTIATED) | B(M_INIT) | B(M_STEP))

/* fmi2Get* of nvr values of `type` into dst: allowed and every value reference known. */
static int get_values(Instance *s, const char *fn, char type, const fmi2ValueReference vr[],
                      size_t nvr, const void *dst) {
    if (!s || !fmi2_allowed(s, GET_MODES, fn)) return 0;
    return fmu_check_refs(s, &API, fn, type, vr, nvr, dst, nvr);
}

/* fmi2Set* (x: the values as doubles): every value checked first; none taken when one is
 * refused. */
static fmi2Status set_values(Instance *s, const char *fn, char type,
                             const fmi2ValueReference vr[], size_t nvr, const void *src,
                             const double *x) {
    if (!s || !fmi2_allowed(s, SET_MODES, fn)) return fmi2Error;
    return fmu_set_values(s, &API, fn, type, vr, nvr, src, nvr, x, s->mode == M_STEP)
               ? fmi2Error : fmi2OK;
}

/* fmi2SetInteger and fmi2SetBoolean: the values as doubles (a Boolean as 0 or 1). */
static fmi2Status set_ints(Instance *s, const char *fn, char type,
                           const fmi2ValueReference vr[], size_t nvr, const int *value) {
    double small[64] = {0}, *x = nvr <= 64 ? small : malloc(nvr * sizeof *x);
    if (!s || !x) return fmi2Error;
    for (size_t i = 0; value && i < nvr; i++)
        x[i] = type == 'B' ? (value[i] != 0) : (double)value[i];
    fmi2Status st = set_values(s, fn, type, vr, nvr, value, x);
    if (x != small) free(x);
    return st;
}

static int hexval(char c) {
    return c >= '0' && c <= '9' ? c - '0' : c >= 'a' && c <= 'f' ? c - 'a' + 10
           : c >= 'A' && c <= 'F' ? c - 'A' + 10 : -1;
}

/* The folder a resource location names, as an absolute path (percent-decoded), or -1.
 * Masters write the same folder in several forms: file:///abs (the usual), file:////abs
 * (OMSimulator: "file:///" + an absolute path), file:/abs and file://localhost/abs; a
 * plain absolute path is taken as it is. On Windows the path after the slashes starts
 * with a drive (file:///C:/abs names C:/abs), and a plain C:\abs is taken as it is. */
#ifdef _WIN32
#define DRIVE(q) ((((q)[0] | 0x20) >= 'a' && ((q)[0] | 0x20) <= 'z') && (q)[1] == ':')
#else
#define DRIVE(q) 0
#endif
static int resource_folder(const char *uri, char *out, size_t n) {
    if (!uri || !n) return -1;
    const char *p = uri;
    if (!strncasecmp(p, "file:", 5)) {
        p += 5;
        if (p[0] == '/' && p[1] == '/') { /* an authority: empty or localhost */
            const char *auth = p + 2, *end = strchr(auth, '/');
            size_t len = end ? (size_t)(end - auth) : strlen(auth);
            if (len && !(len == 9 && !strncasecmp(auth, "localhost", 9))) return -1;
            p = end ? end : auth + len;
        }
    }
    if (p[0] == '/') {
        while (p[1] == '/') p++; /* //abs names /abs here (POSIX leaves // to the system) */
        if (DRIVE(p + 1)) p++;   /* Windows: /C:/abs names C:/abs */
    } else if (!DRIVE(p)) {
        return -1;
    }
    size_t o = 0;
    for (; *p; p++) {
        int c = (unsigned char)*p, hi, lo;
        if (c == '%' && (hi = hexval(p[1])) >= 0 && (lo = hexval(p[2])) >= 0) {
            c = hi * 16 + lo;
            p += 2;
        }
        if (o + 1 >= n) return -1;
        out[o++] = (char)c;
    }
    out[o] = 0;
    return 0;
}

/* ======================================================================================== */
EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }
EXPORT const char *fmi2GetVersion(void) { return "2.0"; }

EXPORT fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid,
                                     fmi2String resources, const fmi2CallbackFunctions *cb,
                                     fmi2Boolean visible, fmi2Boolean logging_on) {
    (void)visible;
    if (!cb) return NULL;
    Instance *s = calloc(1, sizeof *s);
    char folder[4096];
    if (!s) return NULL;
    s->host = *cb;
    s->name = strdup(name ? name : "");
    s->logging_on = logging_on == fmi2True;
    s->mode = M_INSTANTIATED;
    fmu_start_values(s);
    if (!s->name) goto fail;
    if (type != fmi2CoSimulation) {
        fmu_log(s, fmi2Error, "fmi2Instantiate: this FMU supports co-simulation only");
        goto fail;
    }
    if (!guid || strcmp(guid, MODEL_GUID)) {
        fmu_log(s, fmi2Error, "fmi2Instantiate: GUID %s does not match this FMU's %s",
                guid ? guid : "(null)", MODEL_GUID);
        goto fail;
    }
    if (resource_folder(resources, folder, sizeof folder)) {
        fmu_log(s, fmi2Error, "fmi2Instantiate: the resource location %s is not a local "
                "file URI (file:///path)", resources ? resources : "(null)");
        goto fail;
    }
    s->resources = strdup(folder);
    if (!s->resources || model_new(s)) goto fail;
    return s;
fail:
    free(s->resources);
    free(s->name);
    free(s);
    return NULL;
}

EXPORT void fmi2FreeInstance(fmi2Component c) {
    Instance *s = c;
    if (!s) return;
    fmu_release(s);
    free(s);
}

EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n,
                                      const fmi2String categories[]) {
    Instance *s = c;
    if (!s) return fmi2Error;
    return fmu_set_debug_logging(s, "fmi2SetDebugLogging", on == fmi2True, n, categories)
               ? fmi2Error : fmi2OK;
}

EXPORT fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tol_defined, fmi2Real tol,
                                      fmi2Real start, fmi2Boolean stop_defined, fmi2Real stop) {
    Instance *s = c;
    if (!s || !fmi2_allowed(s, B(M_INSTANTIATED), "fmi2SetupExperiment")) return fmi2Error;
    if (!fmu_times_ok(s, "fmi2SetupExperiment", start, stop_defined != 0, stop))
        return fmi2Error;
    s->start_time = start;
    model_setup_experiment(s, tol_defined == fmi2True, tol);
    return fmi2OK;
}

EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    Instance *s = c;
    if (!s || !fmi2_allowed(s, B(M_INSTANTIATED), "fmi2EnterInitializationMode")) return fmi2Error;
    s->mode = M_INIT;
    return fmi2OK;
}

EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Instance *s = c;
    if (!s || !fmi2_allowed(s, B(M_INIT), "fmi2ExitInitializationMode")) return fmi2Error;
    if (s->n_refused) {
        fmu_refused_report(s, &API);
        return fmi2Error;
    }
    /* refused (e.g. a combination of parameters): the instance stays in initialization
     * mode, so the master may correct a parameter and call this again */
    fmi2Status st = model_exit_init(s);
    if (st <= fmi2Warning) s->mode = M_STEP;
    s->last_successful_time = NAN;
    return st;
}

EXPORT fmi2Status fmi2Terminate(fmi2Component c) {
    Instance *s = c;
    if (s && model_gone(s, "fmi2Terminate")) { /* nothing to end: the process is ending */
        s->mode = M_TERMINATED;
        return fmi2OK;
    }
    if (!s || !fmi2_allowed(s, B(M_STEP), "fmi2Terminate")) return fmi2Error;
    s->mode = M_TERMINATED;
    return fmi2OK;
}

EXPORT fmi2Status fmi2Reset(fmi2Component c) {
    Instance *s = c;
    if (!s || !fmi2_allowed(s, ANY_LIVE, "fmi2Reset")) return fmi2Error;
    model_reset(s);
    fmu_start_values(s);
    s->mode = M_INSTANTIATED;
    return fmi2OK;
}

/* -- get/set ----------------------------------------------------------------------------- */
EXPORT fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                              fmi2Real value[]) {
    Instance *s = c;
    if (!get_values(s, "fmi2GetReal", 'R', vr, nvr, value)) return fmi2Error;
    for (size_t i = 0; i < nvr; i++) value[i] = s->value[fmu_find_var(&API, vr[i], 'R')];
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                 fmi2Integer value[]) {
    Instance *s = c;
    if (!get_values(s, "fmi2GetInteger", 'I', vr, nvr, value)) return fmi2Error;
    for (size_t i = 0; i < nvr; i++)
        value[i] = (fmi2Integer)s->value[fmu_find_var(&API, vr[i], 'I')];
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                 fmi2Boolean value[]) {
    Instance *s = c;
    if (!get_values(s, "fmi2GetBoolean", 'B', vr, nvr, value)) return fmi2Error;
    for (size_t i = 0; i < nvr; i++)
        value[i] = s->value[fmu_find_var(&API, vr[i], 'B')] != 0.0 ? fmi2True : fmi2False;
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                fmi2String value[]) {
    Instance *s = c;
    (void)vr;
    (void)value;
    if (!s || !fmi2_allowed(s, GET_MODES, "fmi2GetString")) return fmi2Error;
    if (!nvr) return fmi2OK;
    fmu_log(s, fmi2Error, "fmi2GetString: this FMU has no String variables");
    return fmi2Error;
}

EXPORT fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                              const fmi2Real value[]) {
    return set_values(c, "fmi2SetReal", 'R', vr, nvr, value, value);
}

EXPORT fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                 const fmi2Integer value[]) {
    return set_ints(c, "fmi2SetInteger", 'I', vr, nvr, value);
}

EXPORT fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                 const fmi2Boolean value[]) {
    return set_ints(c, "fmi2SetBoolean", 'B', vr, nvr, value);
}

EXPORT fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                const fmi2String value[]) {
    Instance *s = c;
    (void)vr;
    (void)value;
    if (!s || !fmi2_allowed(s, SET_MODES, "fmi2SetString")) return fmi2Error;
    if (!nvr) return fmi2OK;
    fmu_log(s, fmi2Error, "fmi2SetString: this FMU has no String variables");
    return fmi2Error;
}

/* -- stepping ---------------------------------------------------------------------------- */
EXPORT fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean no_set) {
    Instance *s = c;
    (void)no_set;
    if (!s || !fmi2_allowed(s, B(M_STEP), "fmi2DoStep")) return fmi2Error;
    if (!fmu_step_ok(s, "fmi2DoStep", t, h)) return fmi2Error;
    /* A refused step (fmi2Error) or one failed inside (fmi2Discard) leaves the state of the
     * step start, so the instance stays in step mode either way: the master may repeat the
     * step with other inputs or a smaller size. */
    fmi2Status st = model_do_step(s, t, h);
    if (st <= fmi2Warning)
        s->last_successful_time = t + h;
    else if (st == fmi2Discard)
        s->last_successful_time = t;
    return st;
}

EXPORT fmi2Status fmi2CancelStep(fmi2Component c) {
    Instance *s = c;
    if (s) fmu_log(s, fmi2Error, "fmi2CancelStep: steps are synchronous, there is none to "
                   "cancel");
    return fmi2Error;
}

#define STATUS_MODES (B(M_STEP) | B(M_TERMINATED))

EXPORT fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind k, fmi2Status *v) {
    (void)k;
    (void)v;
    if (!c || !fmi2_allowed(c, STATUS_MODES, "fmi2GetStatus")) return fmi2Error;
    return fmi2Discard; /* no asynchronous step: no status to report */
}

EXPORT fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind k, fmi2Real *v) {
    Instance *s = c;
    if (!s || !fmi2_allowed(s, STATUS_MODES, "fmi2GetRealStatus")) return fmi2Error;
    if (k != fmi2LastSuccessfulTime || !v) return fmi2Discard;
    *v = s->last_successful_time;
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind k, fmi2Integer *v) {
    (void)k;
    (void)v;
    if (!c || !fmi2_allowed(c, STATUS_MODES, "fmi2GetIntegerStatus")) return fmi2Error;
    return fmi2Discard;
}

EXPORT fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind k, fmi2Boolean *v) {
    if (!c || !fmi2_allowed(c, STATUS_MODES, "fmi2GetBooleanStatus")) return fmi2Error;
    if (k != fmi2Terminated || !v) return fmi2Discard;
    *v = fmi2False; /* the model never asks to end the simulation */
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind k, fmi2String *v) {
    (void)k;
    (void)v;
    if (!c || !fmi2_allowed(c, STATUS_MODES, "fmi2GetStringStatus")) return fmi2Error;
    return fmi2Discard;
}

static fmi2Status unsupported(fmi2Component c, const char *fn) {
    if (c) fmu_log(c, fmi2Error, "%s is not supported by this FMU", fn);
    return fmi2Error;
}

EXPORT fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[],
                                               size_t nu, const fmi2ValueReference z[],
                                               size_t nz, const fmi2Real dv[], fmi2Real dz[]) {
    (void)u, (void)nu, (void)z, (void)nz, (void)dv, (void)dz;
    return unsupported(c, "fmi2GetDirectionalDerivative (providesDirectionalDerivative is "
                          "false)");
}

EXPORT fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                              size_t nvr, const fmi2Integer order[],
                                              const fmi2Real value[]) {
    (void)vr, (void)nvr, (void)order, (void)value;
    return unsupported(c, "fmi2SetRealInputDerivatives (canInterpolateInputs is false)");
}

EXPORT fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                               size_t nvr, const fmi2Integer order[],
                                               fmi2Real value[]) {
    (void)vr, (void)nvr, (void)order, (void)value;
    return unsupported(c, "fmi2GetRealOutputDerivatives (maxOutputDerivativeOrder is 0)");
}
