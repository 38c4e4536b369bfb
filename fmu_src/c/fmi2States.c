/* The generic FMI 2.0 layer's FMU states (fmu_states.c): a snapshot holds the mode, the
 * start time and the last successful time as its header words, every variable's value and
 * the model part's own state (fmu.h). Serialized, its trailer has the tag GPFMUST2 and the
 * mode, so a truncated or altered state, or one of another layer, is refused before the
 * model part sees it. */
#include "fmi2_layer.h"

/* Header words: mode, start time, last successful time. */
#define HEAD 3
static const FmuStateFormat FORMAT = {"GPFMUST2", 0x47505354u, HEAD, M_TERMINATED, "FMUstate",
                                      "fmi2SerializedFMUstateSize"};

EXPORT fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state) {
    Instance *s = c;
    if (!s || !fmi2_allowed(s, ANY_LIVE, "fmi2GetFMUstate")) return fmi2Error;
    double head[HEAD] = {(double)s->mode, s->start_time, s->last_successful_time};
    return fmu_state_get(s, &FORMAT, "fmi2GetFMUstate", state, head);
}

EXPORT fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
    Instance *s = c;
    if (!s || !fmi2_allowed(s, ANY_LIVE, "fmi2SetFMUstate")) return fmi2Error;
    double head[HEAD];
    fmi2Status r = fmu_state_set(s, &FORMAT, "fmi2SetFMUstate", state, head);
    if (r > fmi2Warning) return r;
    s->mode = (Mode)head[0];
    s->start_time = head[1];
    s->last_successful_time = head[2];
    return r;
}

EXPORT fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    Instance *s = c;
    if (!s || !fmi2_allowed(s, ANY_LIVE, "fmi2FreeFMUstate")) return fmi2Error;
    return fmu_state_free(s, "fmi2FreeFMUstate", state) ? fmi2Error : fmi2OK;
}

EXPORT fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size) {
    Instance *s = c;
    if (!s || !fmi2_allowed(s, ANY_LIVE, "fmi2SerializedFMUstateSize")) return fmi2Error;
    return fmu_state_serialized_size(s, "fmi2SerializedFMUstateSize", state, size) ? fmi2Error
                                                                                    : fmi2OK;
}

EXPORT fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte bytes[],
                                        size_t size) {
    Instance *s = c;
    if (!s || !fmi2_allowed(s, ANY_LIVE, "fmi2SerializeFMUstate")) return fmi2Error;
    return fmu_state_serialize(s, &FORMAT, "fmi2SerializeFMUstate", state,
                               (unsigned char *)bytes, size) ? fmi2Error : fmi2OK;
}

EXPORT fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size,
                                          fmi2FMUstate *state) {
    Instance *s = c;
    if (!s || !fmi2_allowed(s, ANY_LIVE, "fmi2DeSerializeFMUstate")) return fmi2Error;
    return fmu_state_deserialize(s, &FORMAT, "fmi2DeSerializeFMUstate",
                                 (const unsigned char *)bytes, size, state) ? fmi2Error : fmi2OK;
}
