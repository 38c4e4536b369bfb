/* The Python slave (python_slave.c): the model run by pythonfmu's library and the slave in
 * the FMU's resources, for what needs Python (GearPair's scipy reference engine). Each call
 * logs through the instance why it failed; a refusal the slave logged returns fmi2Error. */
#ifndef PYTHON_SLAVE_H
#define PYTHON_SLAVE_H

#include "fmu.h"

typedef struct PySlave PySlave;

/* Load Python and pythonfmu's library once per process, then a slave instance; NULL after
 * logging `why` Python is needed and why it cannot run (which Python, what is missing, the
 * fix). */
PySlave *py_slave_new(Instance *inst, const char *why);
void py_slave_free(PySlave *p);
/* Every parameter and input of v to the slave, its initialization at t0, its outputs into v. */
fmi2Status py_slave_init(PySlave *p, double *v, double t0);
/* The inputs of v to the slave, one step, its outputs into v. */
fmi2Status py_slave_step(PySlave *p, double *v, double t, double h);
fmi2Status py_slave_state_size(PySlave *p, size_t *n);
fmi2Status py_slave_state_save(PySlave *p, unsigned char *out, size_t n);
fmi2Status py_slave_state_load(PySlave *p, const unsigned char *in, size_t n);
/* Whether the host's interpreter has finalized (the process is ending); says so once. */
int py_slave_gone(PySlave *p, const char *fn);

#endif
