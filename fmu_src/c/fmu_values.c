/* The values of an instance, for the generic FMI layers of every version (fmu_layer.h):
 * value references looked up in the generated variable table (config.h), the checks of a
 * set (causality, variability, range, integer codes), the values refused before
 * initialization ended, and the checks of the times a layer is given. The layer says what
 * its API calls the types and calls (FmuApi). */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "fmu_layer.h"

static char kind_of(const FmuApi *api, const FmuVar *v) {
    return v->type == 'I' && v->codes && api->enumeration ? 'E' : v->type;
}

static const char *kind_name(const FmuApi *api, char kind) {
    return kind == 'R' ? api->real : kind == 'I' ? api->integer
           : kind == 'E' ? api->enumeration : api->boolean;
}

int fmu_find_var(const FmuApi *api, unsigned vr, char kind) {
    if (api->time_vr >= 0 && vr == (unsigned)api->time_vr) return kind == 'R' ? MODEL_NVARS
                                                                              : -1;
    if (vr < MODEL_NVARS && MODEL_VARS[vr].vr == vr)
        return kind_of(api, &MODEL_VARS[vr]) == kind ? (int)vr : -1;
    for (int i = 0; i < MODEL_NVARS; i++)
        if (MODEL_VARS[i].vr == vr && kind_of(api, &MODEL_VARS[i]) == kind) return i;
    return -1;
}

int fmu_check_refs(Instance *s, const FmuApi *api, const char *fn, char kind,
                   const unsigned vr[], size_t nvr, const void *values, size_t nv) {
    if (nvr == 0 && nv == 0) return 1;
    if (!vr || !values) {
        fmu_log(s, fmi2Error, "%s: null value reference or value array for %zu values", fn, nvr);
        return 0;
    }
    if (nv != nvr) {
        fmu_log(s, fmi2Error, "%s: nValues = %zu must equal nValueReferences = %zu (this FMU's "
                "variables are scalars)", fn, nv, nvr);
        return 0;
    }
    for (size_t i = 0; i < nvr; i++)
        if (fmu_find_var(api, vr[i], kind) < 0) {
            fmu_log(s, fmi2Error, "%s: value reference %u is not a %s variable of this FMU", fn,
                    vr[i], kind_name(api, kind));
            return 0;
        }
    return 1;
}

/* What values variable v allows, in words. */
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

/* Whether variable v may be set now; logs why not. */
static int settable(Instance *s, const FmuApi *api, const char *fn, const FmuVar *v,
                    int initialized) {
    if (v->causality == 'o') {
        fmu_log(s, fmi2Error, "%s: %s is an output and cannot be set", fn, v->name);
        return 0;
    }
    if (initialized && !v->tunable) {
        fmu_log(s, fmi2Error, "%s: parameter %s is fixed (variability fixed): it can be set "
                "only before %s; it keeps its value (reset the FMU to change it)", fn, v->name,
                api->exit_init);
        return 0;
    }
    return 1;
}

/* Whether x is a value variable v allows; logs why not. Integers are whole numbers here,
 * printed as such (%.0f, also beyond the range of an int). */
static int value_ok(Instance *s, const char *fn, const FmuVar *v, double x) {
    int ok = isfinite(x) && !(v->has_lo && (v->lo_open ? x <= v->lo : x < v->lo)) &&
             !(v->has_hi && x > v->hi);
    if (!ok) {
        char r[256];
        range_text(v, r, sizeof r);
        if (v->type == 'I')
            fmu_log(s, fmi2Error, "%s: %s = %.0f is out of range; %s. The value is not taken: "
                    "%s keeps its value", fn, v->name, x, r, v->name);
        else
            fmu_log(s, fmi2Error, "%s: %s = %.10g%s%s is %s; %s. The value is not taken: %s "
                    "keeps its value", fn, v->name, x, v->unit[0] ? " " : "", v->unit,
                    isfinite(x) ? "out of range" : "not finite", r, v->name);
    }
    return ok;
}

/* Remember a refused set call fn before initialization ended: the value at `bad` was
 * refused, the others of the call were not taken either. */
static void refuse(Instance *s, const FmuApi *api, const char *fn, const unsigned vr[],
                   size_t nvr, size_t bad, char kind, const double *x) {
    for (size_t i = 0; i < nvr; i++) {
        int k = fmu_find_var(api, vr[i], kind);
        if (k < 0 || k == MODEL_NVARS || MODEL_VARS[k].causality == 'o') continue;
        if (!s->refused[k].what) s->n_refused++;
        s->refused[k].what = i == bad ? 'r' : 'n';
        s->refused[k].fn = fn;
        if (kind == 'B')
            snprintf(s->refused[k].text, sizeof s->refused[k].text, "%s",
                     x[i] != 0.0 ? "true" : "false");
        else
            snprintf(s->refused[k].text, sizeof s->refused[k].text,
                     kind == 'R' ? "%.10g" : "%.0f", x[i]);
    }
}

/* A set that went through: its variables hold values the user asked for again. */
static void taken(Instance *s, const FmuApi *api, const unsigned vr[], size_t nvr, char kind) {
    for (size_t i = 0; s->n_refused && i < nvr; i++) {
        int k = fmu_find_var(api, vr[i], kind);
        if (k >= 0 && k < MODEL_NVARS && s->refused[k].what) {
            s->refused[k].what = 0;
            s->n_refused--;
        }
    }
}

int fmu_set_values(Instance *s, const FmuApi *api, const char *fn, char kind,
                   const unsigned vr[], size_t nvr, const void *src, size_t nv, const double *x,
                   int initialized) {
    if (!fmu_check_refs(s, api, fn, kind, vr, nvr, src, nv)) return -1;
    for (size_t i = 0; i < nvr; i++) {
        int k = fmu_find_var(api, vr[i], kind);
        int ok = k < MODEL_NVARS;
        if (!ok)
            fmu_log(s, fmi2Error, "%s: time is the independent variable and cannot be set", fn);
        else
            ok = settable(s, api, fn, &MODEL_VARS[k], initialized) &&
                 (kind == 'B' || value_ok(s, fn, &MODEL_VARS[k], x[i]));
        if (!ok) {
            if (!initialized) refuse(s, api, fn, vr, nvr, i, kind, x);
            return -1;
        }
    }
    for (size_t i = 0; i < nvr; i++) s->value[fmu_find_var(api, vr[i], kind)] = x[i];
    taken(s, api, vr, nvr, kind);
    return 0;
}

void fmu_refused_report(Instance *s, const FmuApi *api) {
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
    fmu_log(s, fmi2Error, "%s refused: %s; set %s or leave %s unset (the FMU stays in %s)",
            api->exit_init, list, s->n_refused > 1 ? "valid values" : "a valid value",
            s->n_refused > 1 ? "them" : "it", api->init_mode);
}

void fmu_start_values(Instance *s) {
    for (int i = 0; i < MODEL_NVARS; i++) s->value[i] = MODEL_VARS[i].start;
    memset(s->refused, 0, sizeof s->refused);
    s->n_refused = 0;
    s->start_time = 0.0;
    s->last_successful_time = NAN;
}

int fmu_step_ok(Instance *s, const char *fn, double t, double h) {
    if (isfinite(t) && isfinite(h) && h > 0.0) return 1;
    fmu_log(s, fmi2Error, "%s refused: currentCommunicationPoint = %.17g s and "
            "communicationStepSize = %.17g s must be finite and the step size > 0; the FMU "
            "state is unchanged", fn, t, h);
    return 0;
}

int fmu_times_ok(Instance *s, const char *fn, double start, int stop_defined, double stop) {
    if (isfinite(start) && !(stop_defined && !(stop >= start))) return 1;
    fmu_log(s, fmi2Error, "%s: startTime = %.17g s must be finite and stopTime (%.17g s) not "
            "before it", fn, start, stop_defined ? stop : start);
    return 0;
}
