/* The generic FMI 2.0 layer's FMU states: a state is a snapshot of bytes (the mode, the
 * times, every variable's value and the model part's own state, fmu.h), kept in a list per
 * instance, so that a pointer the instance did not hand out is refused, not dereferenced.
 * Serialized, a state carries a trailer (format tag, mode, length, CRC-32), so a truncated
 * or altered state is refused before the model part sees it. */
#define _GNU_SOURCE
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2_layer.h"

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

/* -- FMU state --------------------------------------------------------------------------- */
static FmuState *known_state(Instance *s, fmi2FMUstate p, const char *fn) {
    FmuState *st = p ? find_state(s, p, NULL) : NULL;
    if (!st) fmu_log(s, fmi2Error, "%s: not an FMU state of this instance (freed, or from "
                     "elsewhere)", fn);
    return st;
}

EXPORT fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state) {
    Instance *s = c;
    if (!s || !fmi2_allowed(s, ANY_LIVE, "fmi2GetFMUstate")) return fmi2Error;
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
    if (!s || !fmi2_allowed(s, ANY_LIVE, "fmi2SetFMUstate")) return fmi2Error;
    FmuState *st = known_state(s, state, "fmi2SetFMUstate");
    if (!st) return fmi2Error;
    return restore(s, st->bytes, st->size, "fmi2SetFMUstate");
}

EXPORT fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    Instance *s = c;
    if (!s || !fmi2_allowed(s, ANY_LIVE, "fmi2FreeFMUstate")) return fmi2Error;
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
    if (!s || !fmi2_allowed(s, ANY_LIVE, "fmi2SerializedFMUstateSize")) return fmi2Error;
    FmuState *st = known_state(s, state, "fmi2SerializedFMUstateSize");
    if (!st || !size) return fmi2Error;
    *size = st->size + TRAILER_SIZE;
    return fmi2OK;
}

EXPORT fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte bytes[],
                                        size_t size) {
    Instance *s = c;
    if (!s || !fmi2_allowed(s, ANY_LIVE, "fmi2SerializeFMUstate")) return fmi2Error;
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
    if (!s || !fmi2_allowed(s, ANY_LIVE, "fmi2DeSerializeFMUstate")) return fmi2Error;
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
