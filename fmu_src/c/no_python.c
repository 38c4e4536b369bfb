/* The Python slave's stand-in for a binary that loads no Python (python_slave.h): the
 * win64 binary of GearPair.fmu. Its default engine (engine = 0) is compiled into it and
 * needs nothing; the scipy reference engine (engine = 1) runs in Python through pythonfmu,
 * which this binary does not load. Choosing it ends in one clear error at the call that
 * needs it (fmi2ExitInitializationMode, or fmi2SetFMUstate of a state the reference engine
 * made on Linux), naming what to do instead; nothing is changed and nothing crashes. */
#include "python_slave.h"

#ifndef GP_PLATFORM
#define GP_PLATFORM "win64"
#endif

PySlave *py_slave_new(Instance *inst, const char *why) {
    fmu_log(inst, fmi2Error,
            "%s: the scipy reference engine runs in Python (pythonfmu), which the %s binary "
            "of this FMU does not load. Use engine = 0 (the default: the fast engine compiled "
            "into this binary, no Python needed), or run the reference engine where Python "
            "is: this FMU's linux64 binary with Python and its packages, or the Python API "
            "(gearpair.reference.ReferenceEngine); see docs/hosts.md", why, GP_PLATFORM);
    return NULL;
}

/* Never reached: py_slave_new hands out no slave. */
void py_slave_free(PySlave *p) { (void)p; }

fmi2Status py_slave_init(PySlave *p, double *v, double t0) {
    (void)p, (void)v, (void)t0;
    return fmi2Error;
}

fmi2Status py_slave_step(PySlave *p, double *v, double t, double h) {
    (void)p, (void)v, (void)t, (void)h;
    return fmi2Error;
}

fmi2Status py_slave_state_size(PySlave *p, size_t *n) {
    (void)p, (void)n;
    return fmi2Error;
}

fmi2Status py_slave_state_save(PySlave *p, unsigned char *out, size_t n) {
    (void)p, (void)out, (void)n;
    return fmi2Error;
}

fmi2Status py_slave_state_load(PySlave *p, const unsigned char *in, size_t n) {
    (void)p, (void)in, (void)n;
    return fmi2Error;
}

int py_slave_gone(PySlave *p, const char *fn) {
    (void)p, (void)fn;
    return 0;
}
