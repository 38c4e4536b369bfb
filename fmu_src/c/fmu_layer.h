/* What the generic FMI layers of every version (FMI 2.0: fmi2Functions.c, fmi2States.c; FMI
 * 3.0: fmi3Functions.c, fmi3_states.c, fmi3_none.c) share, in files of its own that name no
 * model and no FMI version: logging (fmu_log.c), the checks of values against the generated
 * variable table and the values refused before initialization ended (fmu_values.c), and FMU
 * states as snapshots of bytes with their serialized format (fmu_states.c). A layer tells
 * them what its API calls things (FmuApi, FmuStateFormat) and keeps only what its standard's
 * API differs in. Internal to the layers: no model part includes it. */
#ifndef FMU_LAYER_H
#define FMU_LAYER_H

#include <stdio.h> /* first: mingw-w64 defines the printf format fmu.h's fmu_log checks */

#include "fmu.h"

#define IN(m, set) (((set) >> (m)) & 1u)
#define B(m) (1u << (m))

/* -- logging (fmu_log.c; fmu_log itself is declared in fmu.h) -------------------------- */
/* Whether messages of status OK in this category reach the host (logging on, and the
 * category enabled or none chosen). */
int fmu_debug_enabled(const Instance *s, const char *category);
/* The category of a message of this status: logStatusWarning ... logStatusFatal, logAll. */
const char *fmu_status_category(fmi2Status status);
/* The set-debug-logging call fn: logging on or off for these n categories (none: all);
 * 0, or -1 (after logging why for a null array) with nothing changed. */
int fmu_set_debug_logging(Instance *s, const char *fn, int on, size_t n,
                          const char *const categories[]);
/* Free what an instance owns beside the struct itself: the model part's data, the FMU
 * states, the categories, the resources folder and the name. */
void fmu_release(Instance *s);

/* -- values (fmu_values.c) -------------------------------------------------------------- */
/* How an FMI version's API types and names the table's variables. A variable's kind is 'R'
 * (Real), 'B' (Boolean), 'I' (Integer) or, when `enumeration` names a type, 'E' (an
 * Integer with codes). */
typedef struct {
    const char *real, *integer, *boolean, *enumeration; /* enumeration NULL: none */
    int time_vr;    /* the value reference of the independent variable (index MODEL_NVARS) or -1 */
    const char *exit_init; /* the call that ends initialization */
    const char *init_mode; /* the name of the mode it ends */
} FmuApi;

/* The MODEL_VARS index of value reference vr of this kind, MODEL_NVARS for the independent
 * variable (a Real), or -1. */
int fmu_find_var(const FmuApi *api, unsigned vr, char kind);
/* Whether nvr value references of this kind with nv values (a null array only for none)
 * name variables of the table; logs why not. */
int fmu_check_refs(Instance *s, const FmuApi *api, const char *fn, char kind,
                   const unsigned vr[], size_t nvr, const void *values, size_t nv);
/* A set call fn of nvr values of this kind (given as src, as doubles in x): every one
 * checked first, none taken when one is refused (outputs, the independent variable, fixed
 * parameters once `initialized`, non-finite or out-of-range values and codes outside their
 * choices; logged, the old values kept). Refused before initialization ended, the call is
 * remembered until the variables are set again (fmu_refused_report). 0, or -1 refused. */
int fmu_set_values(Instance *s, const FmuApi *api, const char *fn, char kind,
                   const unsigned vr[], size_t nvr, const void *src, size_t nv, const double *x,
                   int initialized);
/* The refusal of api->exit_init while values set before are refused (s->n_refused),
 * naming them; logged. */
void fmu_refused_report(Instance *s, const FmuApi *api);
/* Every variable at its start value, nothing refused, the times of a new instance. */
void fmu_start_values(Instance *s);
/* Whether the arguments of a step call fn from t over h can be taken (finite, h > 0);
 * logs why not. */
int fmu_step_ok(Instance *s, const char *fn, double t, double h);
/* Whether an experiment from start (to stop when stop_defined) can be set up; logs why
 * not. */
int fmu_times_ok(Instance *s, const char *fn, double start, int stop_defined, double stop);

/* -- FMU states (fmu_states.c) -------------------------------------------------------- */
/* How a layer's FMU states look: a snapshot is `n_head` header words (the first: the state
 * of the state machine, at most max_state; the layer writes and reads them), every
 * variable's value and the model part's bytes; serialized, a trailer of 20 bytes follows
 * (the 8-character tag, the first header word, the length, a CRC-32). */
typedef struct {
    const char *tag;
    uint32_t magic;
    size_t n_head;
    unsigned max_state;
    const char *state_word; /* what the API calls an FMU state */
    const char *size_fn;    /* the API's call for the serialized size */
} FmuStateFormat;

/* The get-state call fn: a snapshot with these header words into *state (a new state when
 * *state is null, else the instance's state given, overwritten). */
fmi2Status fmu_state_get(Instance *s, const FmuStateFormat *fmt, const char *fn, void **state,
                         const double head[]);
/* The set-state call fn: the values and the model part's state of the instance's `state`;
 * its header words into head (the layer applies them when the status is OK or Warning). */
fmi2Status fmu_state_set(Instance *s, const FmuStateFormat *fmt, const char *fn,
                         const void *state, double head[]);
/* The free-state call fn: 0 (a null state is ignored), or -1 for a state not the
 * instance's (logged). */
int fmu_state_free(Instance *s, const char *fn, void **state);
/* The serialized size of the instance's `state`: 0, or -1 (logged when not its state). */
int fmu_state_serialized_size(Instance *s, const char *fn, const void *state, size_t *size);
/* The serialize and deserialize calls fn: 0, or -1 after logging why. */
int fmu_state_serialize(Instance *s, const FmuStateFormat *fmt, const char *fn,
                        const void *state, unsigned char bytes[], size_t size);
int fmu_state_deserialize(Instance *s, const FmuStateFormat *fmt, const char *fn,
                          const unsigned char bytes[], size_t size, void **state);
/* Free every FMU state of the instance. */
void fmu_states_free(Instance *s);

#endif
