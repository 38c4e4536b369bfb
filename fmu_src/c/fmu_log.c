/* Logging and what an instance owns, for the generic FMI layers of every version
 * (fmu_layer.h): the message formatted once (fmu_log) and handed to the layer's fmu_emit,
 * which knows its host's logger; the categories of debug logging. */
#define _GNU_SOURCE
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmu_layer.h"

int fmu_debug_enabled(const Instance *s, const char *category) {
    if (!s->logging_on) return 0;
    if (!s->categories) return 1;
    for (size_t i = 0; i < s->n_categories; i++)
        if (category && !strcmp(s->categories[i], category)) return 1;
    return 0;
}

const char *fmu_status_category(fmi2Status st) {
    switch (st) {
    case fmi2Warning: return "logStatusWarning";
    case fmi2Discard: return "logStatusDiscard";
    case fmi2Error: return "logStatusError";
    case fmi2Fatal: return "logStatusFatal";
    default: return "logAll";
    }
}

void fmu_log(Instance *s, fmi2Status status, const char *fmt, ...) {
    char buf[8192];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    fmu_emit(s, status, fmu_status_category(status), buf);
}

static void free_categories(Instance *s) {
    for (size_t i = 0; i < s->n_categories; i++) free(s->categories[i]);
    free(s->categories);
}

int fmu_set_debug_logging(Instance *s, const char *fn, int on, size_t n,
                          const char *const categories[]) {
    if (n && !categories) {
        fmu_log(s, fmi2Error, "%s: %zu categories but a null array", fn, n);
        return -1;
    }
    char **copy = NULL;
    if (n) {
        copy = calloc(n, sizeof *copy);
        if (!copy) return -1;
        for (size_t i = 0; i < n; i++) copy[i] = strdup(categories[i] ? categories[i] : "");
    }
    free_categories(s);
    s->categories = copy;
    s->n_categories = n;
    s->logging_on = on;
    return 0;
}

void fmu_release(Instance *s) {
    fmu_states_free(s);
    model_free(s);
    free_categories(s);
    free(s->resources);
    free(s->name);
}
