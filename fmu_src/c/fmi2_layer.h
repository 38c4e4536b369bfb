/* What the generic FMI 2.0 layer's two files share (fmi2Functions.c: the instance, values,
 * steps; fmi2States.c: FMU states), beside what every version's layer shares (fmu_layer.h).
 * Internal to the layer: no model part includes it. */
#ifndef FMI2_LAYER_H
#define FMI2_LAYER_H

#include "fmu_layer.h"

#ifdef _WIN32 /* the win64 binary (mingw-w64): only the fmi2 functions are exported */
#define EXPORT __declspec(dllexport)
#else
#define EXPORT __attribute__((visibility("default")))
#endif

#define ANY_LIVE (B(M_INSTANTIATED) | B(M_INIT) | B(M_STEP) | B(M_TERMINATED))

/* Whether the call fn is allowed in the instance's mode (a set of B(mode)); logs why not. */
int fmi2_allowed(Instance *s, unsigned modes, const char *fn);

#endif
