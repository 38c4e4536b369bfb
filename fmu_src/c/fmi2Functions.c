/* The generic FMI 2.0 co-simulation layer: every fmi2 function, for any model part that
 * fulfils fmu.h. It names no model; the variables come from the generated table.
 *
 * - The FMI 2.0 co-simulation state machine per instance: a call not allowed in the
 *   instance's mode returns fmi2Error with a log message and changes nothing.
 * - fmi2Set* checks against the variable table: unknown value references, outputs, fixed
 *   parameters after initialization, non-finite or out-of-range values and integer codes
 *   outside their choices are refused with fmi2Error, the old value kept. A value refused
 *   before initialization ended is remembered until a valid one is set:
 *   fmi2ExitInitializationMode refuses naming it (`refuse`, `taken`).
 * - Log messages of status warning and worse always reach the host's logger; status OK
 *   (information) follows loggingOn and fmi2SetDebugLogging.
 * - FMU states are bytes: the mode, the times, every variable's value and the model's state
 *   (fmu.h), kept in a list per instance (a pointer the instance did not hand out is
 *   refused, not dereferenced). Serialized, they carry a trailer (format tag, mode, length,
 *   CRC-32), so a truncated or altered state is refused before the model sees it.
 * - The resource location is read in every local file: form (`resource_folder`).
 */
#define _GNU_SOURCE
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "fmu.h"

#ifdef _WIN32 /* the win64 binary (mingw-w64): only the fmi2 functions are exported */
#define EXPORT __declspec(dllexport)
#else
#define EXPORT __attribute__((visibility("default")))
#endif

static const char *const MODE_NAME[] = {"instantiated", "initialization mode",
                                        "step mode (initialized)", "terminated",
                                        "fatal error"};
#define IN(m, set) (((set) >> (m)) & 1u)
#define B(m) (1u << (m))
#define ANY_LIVE (B(M_INSTANTIATED) | B(M_INIT) | B(M_STEP) | B(M_TERMINATED))

/* An FMU state: one block of bytes (`snapshot`), in the instance's list. */
struct FmuState {
    uint32_t magic;
    size_t size;
    unsigned char *bytes;
    FmuState *next;
};
#define STATE_MAGIC 0x47505354u

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

/* The message goes out as the format argument itself with every '%' doubled: a C host
 * that formats it prints the text, and hosts that take it verbatim (fmpy's ctypes logger)
 * show it as it is (a literal "%" appears doubled there). */
void fmu_emit(Instance *s, fmi2Status status, const char *category, const char *msg) {
    if (!s->host.logger) return;
    if (status == fmi2OK && !debug_enabled(s, category)) return;
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
                   category ? category : status_category(status), buf);
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
/* Refuse a call not allowed in the instance's mode (or when the model can no longer run). */
static int allowed(Instance *s, unsigned modes, const char *fn) {
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

/* The MODEL_VARS index of value reference vr of this type, or -1. */
static int find_var(unsigned vr, char type) {
    if (vr < MODEL_NVARS && MODEL_VARS[vr].vr == vr) return MODEL_VARS[vr].type == type ? (int)vr
                                                                                        : -1;
    for (int i = 0; i < MODEL_NVARS; i++)
        if (MODEL_VARS[i].vr == vr && MODEL_VARS[i].type == type) return i;
    return -1;
}

static const char *type_name(char t) {
    return t == 'R' ? "Real" : t == 'I' ? "Integer" : "Boolean";
}

static int check_refs(Instance *s, const char *fn, const fmi2ValueReference vr[], size_t nvr,
                      const void *values, char type) {
    if (nvr == 0) return 1;
    if (!vr || !values) {
        fmu_log(s, fmi2Error, "%s: null value reference or value array for %zu values", fn, nvr);
        return 0;
    }
    for (size_t i = 0; i < nvr; i++)
        if (find_var(vr[i], type) < 0) {
            fmu_log(s, fmi2Error, "%s: value reference %u is not a %s variable of this FMU", fn,
                    vr[i], type_name(type));
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
static int settable(Instance *s, const char *fn, const FmuVar *v) {
    if (v->causality == 'o') {
        fmu_log(s, fmi2Error, "%s: %s is an output and cannot be set", fn, v->name);
        return 0;
    }
    if (s->mode == M_STEP && !v->tunable) {
        fmu_log(s, fmi2Error, "%s: parameter %s is fixed (variability fixed): it can be set "
                "only before fmi2ExitInitializationMode; it keeps its value (reset the FMU to "
                "change it)", fn, v->name);
        return 0;
    }
    return 1;
}

static int value_ok(Instance *s, const char *fn, const FmuVar *v, double x) {
    int ok = isfinite(x) && !(v->has_lo && (v->lo_open ? x <= v->lo : x < v->lo)) &&
             !(v->has_hi && x > v->hi);
    if (!ok) {
        char r[256];
        range_text(v, r, sizeof r);
        if (v->type == 'I')
            fmu_log(s, fmi2Error, "%s: %s = %d is out of range; %s. The value is not taken: "
                    "%s keeps its value", fn, v->name, (int)x, r, v->name);
        else
            fmu_log(s, fmi2Error, "%s: %s = %.10g%s%s is %s; %s. The value is not taken: %s "
                    "keeps its value", fn, v->name, x, v->unit[0] ? " " : "", v->unit,
                    isfinite(x) ? "out of range" : "not finite", r, v->name);
    }
    return ok;
}

/* -- values refused before initialization ended ---------------------------------------------- */
/* Remember a refused fmi2Set* call (before or in initialization mode): the value at `bad`
 * was refused, the others of the call were not taken either. Returns fmi2Error. */
static fmi2Status refuse(Instance *s, const char *fn, const fmi2ValueReference vr[],
                         size_t nvr, size_t bad, char type, const double *values) {
    if (s->mode != M_INSTANTIATED && s->mode != M_INIT) return fmi2Error;
    for (size_t i = 0; i < nvr; i++) {
        int k = find_var(vr[i], type);
        if (k < 0 || MODEL_VARS[k].causality == 'o') continue;
        if (!s->refused[k].what) s->n_refused++;
        s->refused[k].what = i == bad ? 'r' : 'n';
        s->refused[k].fn = fn;
        if (type == 'R')
            snprintf(s->refused[k].text, sizeof s->refused[k].text, "%.10g", values[i]);
        else if (type == 'I')
            snprintf(s->refused[k].text, sizeof s->refused[k].text, "%d", (int)values[i]);
        else
            snprintf(s->refused[k].text, sizeof s->refused[k].text, "%s",
                     values[i] != 0.0 ? "true" : "false");
    }
    return fmi2Error;
}

/* A set that went through: its variables hold values the user asked for again. */
static void taken(Instance *s, const fmi2ValueReference vr[], size_t nvr, char type) {
    if (!s->n_refused) return;
    for (size_t i = 0; i < nvr; i++) {
        int k = find_var(vr[i], type);
        if (k >= 0 && s->refused[k].what) {
            s->refused[k].what = 0;
            s->n_refused--;
        }
    }
}

static fmi2Status refused_report(Instance *s) {
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
    fmu_log(s, fmi2Error, "fmi2ExitInitializationMode refused: %s; set %s or leave %s unset "
            "(the FMU stays in initialization mode)", list,
            s->n_refused > 1 ? "valid values" : "a valid value",
            s->n_refused > 1 ? "them" : "it");
    return fmi2Error;
}

/* -- get and set, for any type ------------------------------------------------------------ */
#define GET_MODES (B(M_INIT) | B(M_STEP) | B(M_TERMINATED))
#define SET_MODES (B(M_INSTANTIATED) | B(M_INIT) | B(M_STEP))

/* fmi2Get* of nvr values of `type` into out (as doubles: the caller converts). */
static int get_values(Instance *s, const char *fn, char type, const fmi2ValueReference vr[],
                      size_t nvr, const void *dst) {
    if (!s || !allowed(s, GET_MODES, fn)) return 0;
    return check_refs(s, fn, vr, nvr, dst, type);
}

/* fmi2Set*: every value checked first; none taken when one is refused. */
static fmi2Status set_values(Instance *s, const char *fn, char type,
                             const fmi2ValueReference vr[], size_t nvr, const void *src,
                             const double *x) {
    if (!s || !allowed(s, SET_MODES, fn)) return fmi2Error;
    if (!check_refs(s, fn, vr, nvr, src, type)) return fmi2Error;
    for (size_t i = 0; i < nvr; i++) {
        const FmuVar *v = &MODEL_VARS[find_var(vr[i], type)];
        if (!settable(s, fn, v) || (type != 'B' && !value_ok(s, fn, v, x[i])))
            return refuse(s, fn, vr, nvr, i, type, x);
    }
    for (size_t i = 0; i < nvr; i++) s->value[find_var(vr[i], type)] = x[i];
    taken(s, vr, nvr, type);
    return fmi2OK;
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

/* -- FMU states ---------------------------------------------------------------------------- */
/* A snapshot: header words (mode, start time, last successful time), the values, the
 * model's bytes. */
#define SNAP_HEAD 3
#define SNAP_VALUES ((SNAP_HEAD + MODEL_NVARS) * sizeof(double))

static FmuState *find_state(Instance *s, fmi2FMUstate p, FmuState ***link) {
    FmuState **l = &s->states;
    for (FmuState *st = s->states; st; l = &st->next, st = st->next)
        if ((void *)st == p) {
            if (link) *link = l;
            return st;
        }
    return NULL;
}

static fmi2Status snapshot(Instance *s, unsigned char **bytes, size_t *size) {
    size_t n = 0;
    fmi2Status r = model_state_size(s, &n);
    if (r > fmi2Warning) return r;
    unsigned char *b = malloc(SNAP_VALUES + n);
    if (!b) {
        fmu_log(s, fmi2Error, "fmi2GetFMUstate: out of memory");
        return fmi2Error;
    }
    double head[SNAP_HEAD] = {(double)s->mode, s->start_time, s->last_successful_time};
    memcpy(b, head, sizeof head);
    memcpy(b + sizeof head, s->value, sizeof s->value);
    r = model_state_save(s, b + SNAP_VALUES, n);
    if (r > fmi2Warning) {
        free(b);
        return r;
    }
    *bytes = b;
    *size = SNAP_VALUES + n;
    return r;
}

static fmi2Status restore(Instance *s, const unsigned char *b, size_t size, const char *fn) {
    double head[SNAP_HEAD], values[MODEL_NVARS];
    if (size < SNAP_VALUES) {
        fmu_log(s, fmi2Error, "%s: not a state of this FMU", fn);
        return fmi2Error;
    }
    memcpy(head, b, sizeof head);
    memcpy(values, b + sizeof head, sizeof values);
    fmi2Status r = model_state_load(s, b + SNAP_VALUES, size - SNAP_VALUES, values);
    if (r > fmi2Warning) return r;
    s->mode = (Mode)head[0];
    s->start_time = head[1];
    s->last_successful_time = head[2];
    memcpy(s->value, values, sizeof values);
    s->n_refused = 0;
    memset(s->refused, 0, sizeof s->refused);
    return r;
}

/* CRC-32 (IEEE 802.3 polynomial, reflected) for serialized states. */
static uint32_t crc32_of(const unsigned char *p, size_t n, uint32_t crc) {
    crc = ~crc;
    for (size_t i = 0; i < n; i++) {
        crc ^= p[i];
        for (int k = 0; k < 8; k++) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
    }
    return ~crc;
}

/* Trailer after a serialized state: tag, mode, payload length, CRC-32 of payload and the
 * preceding trailer fields (little-endian). */
#define TRAILER_TAG "GPFMUST2"
#define TRAILER_SIZE 20

static void put32(unsigned char *p, uint32_t x) {
    for (int i = 0; i < 4; i++) p[i] = (unsigned char)(x >> (8 * i));
}
static uint32_t get32(const unsigned char *p) {
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
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

static void start_values(Instance *s) {
    for (int i = 0; i < MODEL_NVARS; i++) s->value[i] = MODEL_VARS[i].start;
    memset(s->refused, 0, sizeof s->refused);
    s->n_refused = 0;
    s->start_time = 0.0;
    s->last_successful_time = NAN;
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
    start_values(s);
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
    for (FmuState *st = s->states, *nx; st; st = nx) {
        nx = st->next;
        st->magic = 0;
        free(st->bytes);
        free(st);
    }
    model_free(s);
    for (size_t i = 0; i < s->n_categories; i++) free(s->categories[i]);
    free(s->categories);
    free(s->resources);
    free(s->name);
    free(s);
}

EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n,
                                      const fmi2String categories[]) {
    Instance *s = c;
    if (!s) return fmi2Error;
    if (n && !categories) {
        fmu_log(s, fmi2Error, "fmi2SetDebugLogging: %zu categories but a null array", n);
        return fmi2Error;
    }
    char **copy = NULL;
    if (n) {
        copy = calloc(n, sizeof *copy);
        if (!copy) return fmi2Error;
        for (size_t i = 0; i < n; i++) copy[i] = strdup(categories[i] ? categories[i] : "");
    }
    for (size_t i = 0; i < s->n_categories; i++) free(s->categories[i]);
    free(s->categories);
    s->categories = copy;
    s->n_categories = n;
    s->logging_on = on == fmi2True;
    return fmi2OK;
}

EXPORT fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tol_defined, fmi2Real tol,
                                      fmi2Real start, fmi2Boolean stop_defined, fmi2Real stop) {
    Instance *s = c;
    if (!s || !allowed(s, B(M_INSTANTIATED), "fmi2SetupExperiment")) return fmi2Error;
    if (!isfinite(start) || (stop_defined && !(stop >= start))) {
        fmu_log(s, fmi2Error, "fmi2SetupExperiment: startTime = %.17g s must be finite and "
                "stopTime (%.17g s) not before it", start, stop_defined ? stop : start);
        return fmi2Error;
    }
    s->start_time = start;
    model_setup_experiment(s, tol_defined == fmi2True, tol);
    return fmi2OK;
}

EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    Instance *s = c;
    if (!s || !allowed(s, B(M_INSTANTIATED), "fmi2EnterInitializationMode")) return fmi2Error;
    s->mode = M_INIT;
    return fmi2OK;
}

EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Instance *s = c;
    if (!s || !allowed(s, B(M_INIT), "fmi2ExitInitializationMode")) return fmi2Error;
    if (s->n_refused) return refused_report(s);
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
    if (!s || !allowed(s, B(M_STEP), "fmi2Terminate")) return fmi2Error;
    s->mode = M_TERMINATED;
    return fmi2OK;
}

EXPORT fmi2Status fmi2Reset(fmi2Component c) {
    Instance *s = c;
    if (!s || !allowed(s, ANY_LIVE, "fmi2Reset")) return fmi2Error;
    model_reset(s);
    start_values(s);
    s->mode = M_INSTANTIATED;
    return fmi2OK;
}

/* -- get/set ----------------------------------------------------------------------------- */
EXPORT fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                              fmi2Real value[]) {
    Instance *s = c;
    if (!get_values(s, "fmi2GetReal", 'R', vr, nvr, value)) return fmi2Error;
    for (size_t i = 0; i < nvr; i++) value[i] = s->value[find_var(vr[i], 'R')];
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                 fmi2Integer value[]) {
    Instance *s = c;
    if (!get_values(s, "fmi2GetInteger", 'I', vr, nvr, value)) return fmi2Error;
    for (size_t i = 0; i < nvr; i++) value[i] = (fmi2Integer)s->value[find_var(vr[i], 'I')];
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                 fmi2Boolean value[]) {
    Instance *s = c;
    if (!get_values(s, "fmi2GetBoolean", 'B', vr, nvr, value)) return fmi2Error;
    for (size_t i = 0; i < nvr; i++)
        value[i] = s->value[find_var(vr[i], 'B')] != 0.0 ? fmi2True : fmi2False;
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                fmi2String value[]) {
    Instance *s = c;
    (void)vr;
    (void)value;
    if (!s || !allowed(s, GET_MODES, "fmi2GetString")) return fmi2Error;
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
    if (!s || !allowed(s, SET_MODES, "fmi2SetString")) return fmi2Error;
    if (!nvr) return fmi2OK;
    fmu_log(s, fmi2Error, "fmi2SetString: this FMU has no String variables");
    return fmi2Error;
}

/* -- stepping ---------------------------------------------------------------------------- */
EXPORT fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean no_set) {
    Instance *s = c;
    (void)no_set;
    if (!s || !allowed(s, B(M_STEP), "fmi2DoStep")) return fmi2Error;
    if (!isfinite(t) || !isfinite(h) || !(h > 0.0)) {
        fmu_log(s, fmi2Error, "fmi2DoStep refused: currentCommunicationPoint = %.17g s and "
                "communicationStepSize = %.17g s must be finite and the step size > 0; the "
                "FMU state is unchanged", t, h);
        return fmi2Error;
    }
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
    if (!c || !allowed(c, STATUS_MODES, "fmi2GetStatus")) return fmi2Error;
    return fmi2Discard; /* no asynchronous step: no status to report */
}

EXPORT fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind k, fmi2Real *v) {
    Instance *s = c;
    if (!s || !allowed(s, STATUS_MODES, "fmi2GetRealStatus")) return fmi2Error;
    if (k != fmi2LastSuccessfulTime || !v) return fmi2Discard;
    *v = s->last_successful_time;
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind k, fmi2Integer *v) {
    (void)k;
    (void)v;
    if (!c || !allowed(c, STATUS_MODES, "fmi2GetIntegerStatus")) return fmi2Error;
    return fmi2Discard;
}

EXPORT fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind k, fmi2Boolean *v) {
    if (!c || !allowed(c, STATUS_MODES, "fmi2GetBooleanStatus")) return fmi2Error;
    if (k != fmi2Terminated || !v) return fmi2Discard;
    *v = fmi2False; /* the model never asks to end the simulation */
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind k, fmi2String *v) {
    (void)k;
    (void)v;
    if (!c || !allowed(c, STATUS_MODES, "fmi2GetStringStatus")) return fmi2Error;
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

/* -- FMU state --------------------------------------------------------------------------- */
static FmuState *known_state(Instance *s, fmi2FMUstate p, const char *fn) {
    FmuState *st = p ? find_state(s, p, NULL) : NULL;
    if (!st) fmu_log(s, fmi2Error, "%s: not an FMU state of this instance (freed, or from "
                     "elsewhere)", fn);
    return st;
}

EXPORT fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state) {
    Instance *s = c;
    if (!s || !allowed(s, ANY_LIVE, "fmi2GetFMUstate")) return fmi2Error;
    if (!state) {
        fmu_log(s, fmi2Error, "fmi2GetFMUstate: null state pointer");
        return fmi2Error;
    }
    FmuState *own = *state ? find_state(s, *state, NULL) : NULL;
    if (*state && !own) {
        fmu_log(s, fmi2Error, "fmi2GetFMUstate: *FMUstate is neither null nor a state of "
                "this instance");
        return fmi2Error;
    }
    unsigned char *bytes;
    size_t size;
    fmi2Status r = snapshot(s, &bytes, &size);
    if (r > fmi2Warning) return r;
    if (!own) {
        own = calloc(1, sizeof *own);
        if (!own) {
            free(bytes);
            fmu_log(s, fmi2Error, "fmi2GetFMUstate: out of memory");
            return fmi2Error;
        }
        own->magic = STATE_MAGIC;
        own->next = s->states;
        s->states = own;
        *state = own;
    }
    free(own->bytes); /* a given state is overwritten, as the standard allows */
    own->bytes = bytes;
    own->size = size;
    return r;
}

EXPORT fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
    Instance *s = c;
    if (!s || !allowed(s, ANY_LIVE, "fmi2SetFMUstate")) return fmi2Error;
    FmuState *st = known_state(s, state, "fmi2SetFMUstate");
    if (!st) return fmi2Error;
    return restore(s, st->bytes, st->size, "fmi2SetFMUstate");
}

EXPORT fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    Instance *s = c;
    if (!s || !allowed(s, ANY_LIVE, "fmi2FreeFMUstate")) return fmi2Error;
    if (!state || !*state) return fmi2OK; /* the standard: a null state is ignored */
    FmuState **link;
    FmuState *st = find_state(s, *state, &link);
    if (!st) {
        fmu_log(s, fmi2Error, "fmi2FreeFMUstate: not an FMU state of this instance (freed "
                "already, or from elsewhere)");
        return fmi2Error;
    }
    *link = st->next;
    st->magic = 0;
    free(st->bytes);
    free(st);
    *state = NULL;
    return fmi2OK;
}

EXPORT fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size) {
    Instance *s = c;
    if (!s || !allowed(s, ANY_LIVE, "fmi2SerializedFMUstateSize")) return fmi2Error;
    FmuState *st = known_state(s, state, "fmi2SerializedFMUstateSize");
    if (!st || !size) return fmi2Error;
    *size = st->size + TRAILER_SIZE;
    return fmi2OK;
}

EXPORT fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte bytes[],
                                        size_t size) {
    Instance *s = c;
    if (!s || !allowed(s, ANY_LIVE, "fmi2SerializeFMUstate")) return fmi2Error;
    FmuState *st = known_state(s, state, "fmi2SerializeFMUstate");
    if (!st) return fmi2Error;
    size_t n = st->size;
    if (!bytes || size != n + TRAILER_SIZE || n > 0xFFFFFFFFu) {
        fmu_log(s, fmi2Error, "fmi2SerializeFMUstate: the buffer must have the size "
                "fmi2SerializedFMUstateSize gave (%zu bytes), got %zu", n + TRAILER_SIZE, size);
        return fmi2Error;
    }
    memcpy(bytes, st->bytes, n);
    unsigned char *t = (unsigned char *)bytes + n;
    double mode;
    memcpy(&mode, st->bytes, sizeof mode);
    memcpy(t, TRAILER_TAG, 8);
    put32(t + 8, (uint32_t)mode);
    put32(t + 12, (uint32_t)n);
    put32(t + 16, crc32_of((const unsigned char *)bytes, n + 16, 0));
    return fmi2OK;
}

EXPORT fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size,
                                          fmi2FMUstate *state) {
    Instance *s = c;
    if (!s || !allowed(s, ANY_LIVE, "fmi2DeSerializeFMUstate")) return fmi2Error;
    if (!state || (size && !bytes)) {
        fmu_log(s, fmi2Error, "fmi2DeSerializeFMUstate: null argument");
        return fmi2Error;
    }
    const unsigned char *b = (const unsigned char *)bytes;
    const unsigned char *t = size >= TRAILER_SIZE + SNAP_VALUES ? b + size - TRAILER_SIZE
                                                                : NULL;
    if (!t || memcmp(t, TRAILER_TAG, 8) || get32(t + 12) != size - TRAILER_SIZE ||
        get32(t + 8) > M_TERMINATED || crc32_of(b, size - 4, 0) != get32(t + 16)) {
        fmu_log(s, fmi2Error, "fmi2DeSerializeFMUstate: the %zu bytes are not a complete, "
                "unaltered serialized state of this FMU (format tag, length or checksum "
                "wrong); nothing was restored", size);
        return fmi2Error;
    }
    FmuState *nw = calloc(1, sizeof *nw);
    unsigned char *copy = malloc(size - TRAILER_SIZE);
    if (!nw || !copy) {
        free(nw);
        free(copy);
        fmu_log(s, fmi2Error, "fmi2DeSerializeFMUstate: out of memory");
        return fmi2Error;
    }
    memcpy(copy, b, size - TRAILER_SIZE);
    nw->magic = STATE_MAGIC;
    nw->bytes = copy;
    nw->size = size - TRAILER_SIZE;
    nw->next = s->states;
    s->states = nw;
    *state = nw;
    return fmi2OK;
}
