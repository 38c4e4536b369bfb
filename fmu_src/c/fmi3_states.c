/* FMU states of the FMI 3.0 layer (fmu_states.c): a snapshot holds the state of the state
 * machine, the start time, the last successful time, the FMU's time and whether an event
 * is pending as its header words, every variable's value and the model part's own state
 * (fmu.h). Serialized, its trailer has the tag GPFMUST3 and the state, so a truncated or
 * altered state, or one of the FMI 2 layer, is refused before the model part sees it. */
#include "fmi3_layer.h"

/* Header words: state, start time, last successful time, time, event pending. */
#define HEAD 5
static const FmuStateFormat FORMAT = {"GPFMUST3", 0x47505333u, HEAD, S_TERMINATED, "FMUState",
                                      "fmi3SerializedFMUStateSize"};

FMI3_Export fmi3Status fmi3GetFMUState(fmi3Instance c, fmi3FMUState *state) {
    Fmi3 *f = c;
    if (!f || !fmi3_allowed(f, ANY, "fmi3GetFMUState")) return fmi3Error;
    double head[HEAD] = {(double)f->state, f->base.start_time, f->base.last_successful_time,
                         f->time, (double)f->event_pending};
    return (fmi3Status)fmu_state_get(&f->base, &FORMAT, "fmi3GetFMUState", state, head);
}

FMI3_Export fmi3Status fmi3SetFMUState(fmi3Instance c, fmi3FMUState state) {
    Fmi3 *f = c;
    if (!f || !fmi3_allowed(f, ANY, "fmi3SetFMUState")) return fmi3Error;
    double head[HEAD];
    fmi2Status r = fmu_state_set(&f->base, &FORMAT, "fmi3SetFMUState", state, head);
    if (r > fmi2Warning) return (fmi3Status)r;
    f->state = (State)head[0];
    f->base.start_time = head[1];
    f->base.last_successful_time = head[2];
    f->time = head[3];
    f->event_pending = head[4] != 0.0;
    return (fmi3Status)r;
}

FMI3_Export fmi3Status fmi3FreeFMUState(fmi3Instance c, fmi3FMUState *state) {
    Fmi3 *f = c;
    if (!f || !fmi3_allowed(f, ANY, "fmi3FreeFMUState")) return fmi3Error;
    return fmu_state_free(&f->base, "fmi3FreeFMUState", state) ? fmi3Error : fmi3OK;
}

FMI3_Export fmi3Status fmi3SerializedFMUStateSize(fmi3Instance c, fmi3FMUState state,
                                                  size_t *size) {
    Fmi3 *f = c;
    if (!f || !fmi3_allowed(f, ANY, "fmi3SerializedFMUStateSize")) return fmi3Error;
    return fmu_state_serialized_size(&f->base, "fmi3SerializedFMUStateSize", state, size)
               ? fmi3Error : fmi3OK;
}

FMI3_Export fmi3Status fmi3SerializeFMUState(fmi3Instance c, fmi3FMUState state,
                                             fmi3Byte bytes[], size_t size) {
    Fmi3 *f = c;
    if (!f || !fmi3_allowed(f, ANY, "fmi3SerializeFMUState")) return fmi3Error;
    return fmu_state_serialize(&f->base, &FORMAT, "fmi3SerializeFMUState", state, bytes, size)
               ? fmi3Error : fmi3OK;
}

FMI3_Export fmi3Status fmi3DeserializeFMUState(fmi3Instance c, const fmi3Byte bytes[],
                                               size_t size, fmi3FMUState *state) {
    Fmi3 *f = c;
    if (!f || !fmi3_allowed(f, ANY, "fmi3DeserializeFMUState")) return fmi3Error;
    return fmu_state_deserialize(&f->base, &FORMAT, "fmi3DeserializeFMUState", bytes, size,
                                 state) ? fmi3Error : fmi3OK;
}
