/* FMU states of the FMI 3.0 layer (fmi3_layer.h): bytes holding the instance's state of the
 * state machine, its times, every variable's value and the model's state (fmu.h), kept in a
 * list per instance (a pointer the instance did not hand out is refused, not dereferenced).
 * Serialized, they carry a trailer (format tag, state, length, CRC-32), so that a truncated
 * or altered state is refused before the model sees it; the tag differs from the FMI 2
 * layer's, whose states are not this layer's. */
#include <stdlib.h>
#include <string.h>

#include "fmi3_layer.h"

/* An FMU state: one block of bytes (`snapshot`), in the instance's list. */
struct FmuState {
    uint32_t magic;
    size_t size;
    unsigned char *bytes;
    FmuState *next;
};
#define STATE_MAGIC 0x47505333u

void fmi3_free_states(Fmi3 *f) {
    for (FmuState *st = f->base.states, *nx; st; st = nx) {
        nx = st->next;
        st->magic = 0;
        free(st->bytes);
        free(st);
    }
    f->base.states = NULL;
}

/* A snapshot: header words (state, start time, last successful time, time, event pending),
 * the values, the model's bytes. */
#define SNAP_HEAD 5
#define SNAP_VALUES ((SNAP_HEAD + MODEL_NVARS) * sizeof(double))

static FmuState *find_state(Instance *s, fmi3FMUState p, FmuState ***link) {
    FmuState **l = &s->states;
    for (FmuState *st = s->states; st; l = &st->next, st = st->next)
        if ((void *)st == p) {
            if (link) *link = l;
            return st;
        }
    return NULL;
}

static fmi3Status snapshot(Fmi3 *f, unsigned char **bytes, size_t *size) {
    Instance *s = &f->base;
    size_t n = 0;
    fmi2Status r = model_state_size(s, &n);
    if (r > fmi2Warning) return (fmi3Status)r;
    unsigned char *b = malloc(SNAP_VALUES + n);
    if (!b) {
        ERR(f, "fmi3GetFMUState: out of memory");
        return fmi3Error;
    }
    double head[SNAP_HEAD] = {(double)f->state, s->start_time, s->last_successful_time,
                              f->time, (double)f->event_pending};
    memcpy(b, head, sizeof head);
    memcpy(b + sizeof head, s->value, sizeof s->value);
    r = model_state_save(s, b + SNAP_VALUES, n);
    if (r > fmi2Warning) {
        free(b);
        return (fmi3Status)r;
    }
    *bytes = b;
    *size = SNAP_VALUES + n;
    return (fmi3Status)r;
}

static fmi3Status restore(Fmi3 *f, const unsigned char *b, size_t size) {
    Instance *s = &f->base;
    double head[SNAP_HEAD], values[MODEL_NVARS];
    memcpy(head, b, sizeof head);
    memcpy(values, b + sizeof head, sizeof values);
    fmi2Status r = model_state_load(s, b + SNAP_VALUES, size - SNAP_VALUES, values);
    if (r > fmi2Warning) return (fmi3Status)r;
    f->state = (State)head[0];
    s->start_time = head[1];
    s->last_successful_time = head[2];
    f->time = head[3];
    f->event_pending = head[4] != 0.0;
    memcpy(s->value, values, sizeof values);
    s->n_refused = 0;
    memset(s->refused, 0, sizeof s->refused);
    return (fmi3Status)r;
}

/* CRC-32 (IEEE 802.3 polynomial, reflected) for serialized states. */
static uint32_t crc32_of(const unsigned char *p, size_t n) {
    uint32_t crc = ~0u;
    for (size_t i = 0; i < n; i++) {
        crc ^= p[i];
        for (int k = 0; k < 8; k++) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
    }
    return ~crc;
}

/* Trailer after a serialized state: tag, state, payload length, CRC-32 of payload and the
 * preceding trailer fields (little-endian). */
#define TRAILER_TAG "GPFMUST3"
#define TRAILER_SIZE 20

static void put32(unsigned char *p, uint32_t x) {
    for (int i = 0; i < 4; i++) p[i] = (unsigned char)(x >> (8 * i));
}
static uint32_t get32(const unsigned char *p) {
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

/* -- the fmi3 functions ------------------------------------------------------------------ */
static FmuState *known_state(Fmi3 *f, fmi3FMUState p, const char *fn) {
    FmuState *st = p ? find_state(&f->base, p, NULL) : NULL;
    if (!st) ERR(f, "%s: not an FMU state of this instance (freed, or from elsewhere)", fn);
    return st;
}

FMI3_Export fmi3Status fmi3GetFMUState(fmi3Instance c, fmi3FMUState *state) {
    Fmi3 *f = c;
    if (!f || !fmi3_allowed(f, ANY, "fmi3GetFMUState")) return fmi3Error;
    if (!state) {
        ERR(f, "fmi3GetFMUState: null state pointer");
        return fmi3Error;
    }
    FmuState *own = *state ? find_state(&f->base, *state, NULL) : NULL;
    if (*state && !own) {
        ERR(f, "fmi3GetFMUState: *FMUState is neither null nor a state of this instance");
        return fmi3Error;
    }
    unsigned char *bytes;
    size_t size;
    fmi3Status r = snapshot(f, &bytes, &size);
    if (r > fmi3Warning) return r;
    if (!own) {
        own = calloc(1, sizeof *own);
        if (!own) {
            free(bytes);
            ERR(f, "fmi3GetFMUState: out of memory");
            return fmi3Error;
        }
        own->magic = STATE_MAGIC;
        own->next = f->base.states;
        f->base.states = own;
        *state = own;
    }
    free(own->bytes); /* a given state is overwritten, as the standard allows */
    own->bytes = bytes;
    own->size = size;
    return r;
}

FMI3_Export fmi3Status fmi3SetFMUState(fmi3Instance c, fmi3FMUState state) {
    Fmi3 *f = c;
    if (!f || !fmi3_allowed(f, ANY, "fmi3SetFMUState")) return fmi3Error;
    FmuState *st = known_state(f, state, "fmi3SetFMUState");
    return st ? restore(f, st->bytes, st->size) : fmi3Error;
}

FMI3_Export fmi3Status fmi3FreeFMUState(fmi3Instance c, fmi3FMUState *state) {
    Fmi3 *f = c;
    if (!f || !fmi3_allowed(f, ANY, "fmi3FreeFMUState")) return fmi3Error;
    if (!state || !*state) return fmi3OK; /* the standard: a null state is ignored */
    FmuState **link;
    FmuState *st = find_state(&f->base, *state, &link);
    if (!st) {
        ERR(f, "fmi3FreeFMUState: not an FMU state of this instance (freed already, or from "
            "elsewhere)");
        return fmi3Error;
    }
    *link = st->next;
    st->magic = 0;
    free(st->bytes);
    free(st);
    *state = NULL;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3SerializedFMUStateSize(fmi3Instance c, fmi3FMUState state,
                                                  size_t *size) {
    Fmi3 *f = c;
    if (!f || !fmi3_allowed(f, ANY, "fmi3SerializedFMUStateSize")) return fmi3Error;
    FmuState *st = known_state(f, state, "fmi3SerializedFMUStateSize");
    if (!st || !size) return fmi3Error;
    *size = st->size + TRAILER_SIZE;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3SerializeFMUState(fmi3Instance c, fmi3FMUState state,
                                             fmi3Byte bytes[], size_t size) {
    Fmi3 *f = c;
    if (!f || !fmi3_allowed(f, ANY, "fmi3SerializeFMUState")) return fmi3Error;
    FmuState *st = known_state(f, state, "fmi3SerializeFMUState");
    if (!st) return fmi3Error;
    size_t n = st->size;
    if (!bytes || size != n + TRAILER_SIZE || n > 0xFFFFFFFFu) {
        ERR(f, "fmi3SerializeFMUState: the buffer must have the size "
            "fmi3SerializedFMUStateSize gave (%zu bytes), got %zu", n + TRAILER_SIZE, size);
        return fmi3Error;
    }
    memcpy(bytes, st->bytes, n);
    double head;
    memcpy(&head, st->bytes, sizeof head);
    unsigned char *t = bytes + n;
    memcpy(t, TRAILER_TAG, 8);
    put32(t + 8, (uint32_t)head);
    put32(t + 12, (uint32_t)n);
    put32(t + 16, crc32_of(bytes, n + 16));
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3DeserializeFMUState(fmi3Instance c, const fmi3Byte bytes[],
                                               size_t size, fmi3FMUState *state) {
    Fmi3 *f = c;
    if (!f || !fmi3_allowed(f, ANY, "fmi3DeserializeFMUState")) return fmi3Error;
    if (!state || (size && !bytes)) {
        ERR(f, "fmi3DeserializeFMUState: null argument");
        return fmi3Error;
    }
    const unsigned char *t = size >= TRAILER_SIZE + SNAP_VALUES ? bytes + size - TRAILER_SIZE
                                                                : NULL;
    if (!t || memcmp(t, TRAILER_TAG, 8) || get32(t + 12) != size - TRAILER_SIZE ||
        get32(t + 8) > S_TERMINATED || crc32_of(bytes, size - 4) != get32(t + 16)) {
        ERR(f, "fmi3DeserializeFMUState: the %zu bytes are not a complete, unaltered "
            "serialized state of this FMU (format tag, length or checksum wrong); nothing was "
            "restored", size);
        return fmi3Error;
    }
    FmuState *nw = calloc(1, sizeof *nw);
    unsigned char *copy = malloc(size - TRAILER_SIZE);
    if (!nw || !copy) {
        free(nw);
        free(copy);
        ERR(f, "fmi3DeserializeFMUState: out of memory");
        return fmi3Error;
    }
    memcpy(copy, bytes, size - TRAILER_SIZE);
    nw->magic = STATE_MAGIC;
    nw->bytes = copy;
    nw->size = size - TRAILER_SIZE;
    nw->next = f->base.states;
    f->base.states = nw;
    *state = nw;
    return fmi3OK;
}
