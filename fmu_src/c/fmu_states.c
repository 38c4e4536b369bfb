/* FMU states for the generic FMI layers of every version (fmu_layer.h). A state is a
 * snapshot of bytes: the layer's header words (the state of its state machine first, then
 * its times), every variable's value and the model part's own state (fmu.h). The states
 * are kept in a list per instance, so that a pointer the instance did not hand out is
 * refused, not dereferenced. Serialized, a state carries a trailer (format tag, first
 * header word, length, CRC-32), so that a truncated or altered state is refused before the
 * model part sees it; each layer has a tag of its own (FmuStateFormat), so that the states
 * of one are not taken by another. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "fmu_layer.h"

/* An FMU state: one block of bytes (a snapshot), in the instance's list. */
struct FmuState {
    uint32_t magic;
    size_t size;
    unsigned char *bytes;
    FmuState *next;
};

/* The bytes before the model part's: the header words and the values. */
static size_t values_end(const FmuStateFormat *fmt) {
    return (fmt->n_head + MODEL_NVARS) * sizeof(double);
}

static FmuState *find_state(Instance *s, const void *p, FmuState ***link) {
    FmuState **l = &s->states;
    for (FmuState *st = s->states; st; l = &st->next, st = st->next)
        if ((const void *)st == p) {
            if (link) *link = l;
            return st;
        }
    return NULL;
}

/* The instance's state p, or NULL after logging that it is not. */
static FmuState *known_state(Instance *s, const void *p, const char *fn) {
    FmuState *st = p ? find_state(s, p, NULL) : NULL;
    if (!st) fmu_log(s, fmi2Error, "%s: not an FMU state of this instance (freed, or from "
                     "elsewhere)", fn);
    return st;
}

/* A new state of these bytes at the head of the instance's list, or NULL. */
static FmuState *new_state(Instance *s, const FmuStateFormat *fmt, unsigned char *bytes,
                           size_t size) {
    FmuState *st = calloc(1, sizeof *st);
    if (!st) return NULL;
    st->magic = fmt->magic;
    st->bytes = bytes;
    st->size = size;
    st->next = s->states;
    s->states = st;
    return st;
}

static void drop(FmuState *st) {
    st->magic = 0;
    free(st->bytes);
    free(st);
}

void fmu_states_free(Instance *s) {
    for (FmuState *st = s->states, *nx; st; st = nx) {
        nx = st->next;
        drop(st);
    }
    s->states = NULL;
}

/* The snapshot: the header words, the values, the model part's bytes. */
static fmi2Status snapshot(Instance *s, const FmuStateFormat *fmt, const char *fn,
                           const double head[], unsigned char **bytes, size_t *size) {
    size_t n = 0, at = values_end(fmt);
    fmi2Status r = model_state_size(s, &n);
    if (r > fmi2Warning) return r;
    unsigned char *b = malloc(at + n);
    if (!b) {
        fmu_log(s, fmi2Error, "%s: out of memory", fn);
        return fmi2Error;
    }
    memcpy(b, head, fmt->n_head * sizeof(double));
    memcpy(b + fmt->n_head * sizeof(double), s->value, sizeof s->value);
    r = model_state_save(s, b + at, n);
    if (r > fmi2Warning) {
        free(b);
        return r;
    }
    *bytes = b;
    *size = at + n;
    return r;
}

fmi2Status fmu_state_get(Instance *s, const FmuStateFormat *fmt, const char *fn, void **state,
                         const double head[]) {
    if (!state) {
        fmu_log(s, fmi2Error, "%s: null state pointer", fn);
        return fmi2Error;
    }
    FmuState *own = *state ? find_state(s, *state, NULL) : NULL;
    if (*state && !own) {
        fmu_log(s, fmi2Error, "%s: *%s is neither null nor a state of this instance", fn,
                fmt->state_word);
        return fmi2Error;
    }
    unsigned char *bytes;
    size_t size;
    fmi2Status r = snapshot(s, fmt, fn, head, &bytes, &size);
    if (r > fmi2Warning) return r;
    if (!own) {
        own = new_state(s, fmt, NULL, 0);
        if (!own) {
            free(bytes);
            fmu_log(s, fmi2Error, "%s: out of memory", fn);
            return fmi2Error;
        }
        *state = own;
    }
    free(own->bytes); /* a given state is overwritten, as the standard allows */
    own->bytes = bytes;
    own->size = size;
    return r;
}

fmi2Status fmu_state_set(Instance *s, const FmuStateFormat *fmt, const char *fn,
                         const void *state, double head[]) {
    FmuState *st = known_state(s, state, fn);
    if (!st) return fmi2Error;
    size_t at = values_end(fmt);
    double values[MODEL_NVARS];
    if (st->size < at) {
        fmu_log(s, fmi2Error, "%s: not a state of this FMU", fn);
        return fmi2Error;
    }
    memcpy(head, st->bytes, fmt->n_head * sizeof(double));
    memcpy(values, st->bytes + fmt->n_head * sizeof(double), sizeof values);
    fmi2Status r = model_state_load(s, st->bytes + at, st->size - at, values);
    if (r > fmi2Warning) return r;
    memcpy(s->value, values, sizeof values);
    s->n_refused = 0;
    memset(s->refused, 0, sizeof s->refused);
    return r;
}

int fmu_state_free(Instance *s, const char *fn, void **state) {
    if (!state || !*state) return 0; /* the standard: a null state is ignored */
    FmuState **link;
    FmuState *st = find_state(s, *state, &link);
    if (!st) {
        fmu_log(s, fmi2Error, "%s: not an FMU state of this instance (freed already, or from "
                "elsewhere)", fn);
        return -1;
    }
    *link = st->next;
    drop(st);
    *state = NULL;
    return 0;
}

/* -- the serialized format ------------------------------------------------------------ */
/* CRC-32 (IEEE 802.3 polynomial, reflected). */
static uint32_t crc32_of(const unsigned char *p, size_t n) {
    uint32_t crc = ~0u;
    for (size_t i = 0; i < n; i++) {
        crc ^= p[i];
        for (int k = 0; k < 8; k++) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
    }
    return ~crc;
}

/* The trailer after the snapshot: the tag (8 bytes), the first header word, the snapshot's
 * length and the CRC-32 of the snapshot and the trailer's fields before it (little-endian
 * 32-bit words). */
#define TRAILER_SIZE 20

static void put32(unsigned char *p, uint32_t x) {
    for (int i = 0; i < 4; i++) p[i] = (unsigned char)(x >> (8 * i));
}
static uint32_t get32(const unsigned char *p) {
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

int fmu_state_serialized_size(Instance *s, const char *fn, const void *state, size_t *size) {
    FmuState *st = known_state(s, state, fn);
    if (!st || !size) return -1;
    *size = st->size + TRAILER_SIZE;
    return 0;
}

int fmu_state_serialize(Instance *s, const FmuStateFormat *fmt, const char *fn,
                        const void *state, unsigned char bytes[], size_t size) {
    FmuState *st = known_state(s, state, fn);
    if (!st) return -1;
    size_t n = st->size;
    if (!bytes || size != n + TRAILER_SIZE || n > 0xFFFFFFFFu) {
        fmu_log(s, fmi2Error, "%s: the buffer must have the size %s gave (%zu bytes), got %zu",
                fn, fmt->size_fn, n + TRAILER_SIZE, size);
        return -1;
    }
    memcpy(bytes, st->bytes, n);
    double first;
    memcpy(&first, st->bytes, sizeof first);
    unsigned char *t = bytes + n;
    memcpy(t, fmt->tag, 8);
    put32(t + 8, (uint32_t)first);
    put32(t + 12, (uint32_t)n);
    put32(t + 16, crc32_of(bytes, n + 16));
    return 0;
}

int fmu_state_deserialize(Instance *s, const FmuStateFormat *fmt, const char *fn,
                          const unsigned char bytes[], size_t size, void **state) {
    if (!state || (size && !bytes)) {
        fmu_log(s, fmi2Error, "%s: null argument", fn);
        return -1;
    }
    const unsigned char *t = size >= TRAILER_SIZE + values_end(fmt) ? bytes + size - TRAILER_SIZE
                                                                     : NULL;
    if (!t || memcmp(t, fmt->tag, 8) || get32(t + 12) != size - TRAILER_SIZE ||
        get32(t + 8) > fmt->max_state || crc32_of(bytes, size - 4) != get32(t + 16)) {
        fmu_log(s, fmi2Error, "%s: the %zu bytes are not a complete, unaltered serialized state "
                "of this FMU (format tag, length or checksum wrong); nothing was restored", fn,
                size);
        return -1;
    }
    unsigned char *copy = malloc(size - TRAILER_SIZE);
    FmuState *nw = copy ? new_state(s, fmt, copy, size - TRAILER_SIZE) : NULL;
    if (!nw) {
        free(copy);
        fmu_log(s, fmi2Error, "%s: out of memory", fn);
        return -1;
    }
    memcpy(copy, bytes, size - TRAILER_SIZE);
    *state = nw;
    return 0;
}
