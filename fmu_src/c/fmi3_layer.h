/* The generic FMI 3.0 co-simulation layer's own declarations, shared by its files:
 * fmi3Functions.c (instances, states of the state machine, values, steps and events),
 * fmi3_states.c (FMU states) and fmi3_none.c (what the FMU does not provide), beside what
 * every version's layer shares (fmu_layer.h). The model part sees an instance as the
 * Instance of fmu.h, its first member. */
#ifndef FMI3_LAYER_H
#define FMI3_LAYER_H

#include "fmu_layer.h"

#include "fmi3Functions.h"

/* The states of an instance (FMI 3.0 co-simulation, section 4.2): the layer provides no
 * Configuration Mode (no structural parameters), no Intermediate Update Mode, and no state
 * of its own after a failed step (a discarded step leaves the state of its start, in Step
 * Mode). */
typedef enum { S_INSTANTIATED, S_INIT, S_EVENT, S_STEP, S_TERMINATED } State;
#define ANY (B(S_INSTANTIATED) | B(S_INIT) | B(S_EVENT) | B(S_STEP) | B(S_TERMINATED))
#define GET_STATES (B(S_INIT) | B(S_EVENT) | B(S_STEP) | B(S_TERMINATED))
#define SET_STATES (B(S_INSTANTIATED) | B(S_INIT) | B(S_EVENT) | B(S_STEP))

/* An instance: the model part's view first (an Instance * is one of these). */
typedef struct {
    Instance base;
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
    State state;
    int event_mode_used;
    int event_pending; /* the last step returned early at an event: Event Mode settles it */
    double time;       /* the FMU's time: the start time, then where the last step ended */
} Fmi3;
#define F(inst) ((Fmi3 *)(inst))
#define ERR(f, ...) fmu_log(&(f)->base, fmi2Error, __VA_ARGS__)

/* Whether the call fn is allowed in the instance's state (one of `states`) and the model
 * can still run; logs why not (fmi3Functions.c). */
int fmi3_allowed(Fmi3 *f, unsigned states, const char *fn);
#endif
