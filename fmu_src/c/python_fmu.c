/* A model part (fmu.h) for any pythonfmu slave: the generic FMI layer over the Python slave
 * (python_slave.h). Every parameter and input goes to the slave at initialization, the
 * inputs before each step, the outputs come back after it. The driveline example's FMUs
 * get their binary this way (build_fmu.add_c_layer without an engine). */
#include <stdlib.h>
#include <string.h>

#include "fmu.h"
#include "python_slave.h"

#define SLAVE(inst) ((PySlave *)(inst)->model)

int model_new(Instance *inst) {
    inst->model = NULL;
    return 0;
}

void model_free(Instance *inst) {
    py_slave_free(SLAVE(inst));
    inst->model = NULL;
}

void model_reset(Instance *inst) { model_free(inst); }

int model_gone(Instance *inst, const char *fn) {
    return inst->model && py_slave_gone(SLAVE(inst), fn);
}

void model_setup_experiment(Instance *inst, int tol_defined, double tol) {
    (void)inst, (void)tol_defined, (void)tol;
}

fmi2Status model_exit_init(Instance *inst) {
    model_free(inst);
    inst->model = py_slave_new(inst, "the slave runs in Python");
    if (!inst->model) return fmi2Error;
    fmi2Status st = py_slave_init(SLAVE(inst), inst->value, inst->start_time);
    if (st > fmi2Warning) model_free(inst);
    return st;
}

fmi2Status model_do_step(Instance *inst, double t, double h) {
    return py_slave_step(SLAVE(inst), inst->value, t, h);
}

/* The state: 1 and the slave's serialized state, or 0 before initialization. */
fmi2Status model_state_size(Instance *inst, size_t *n) {
    size_t body = 0;
    if (inst->model && py_slave_state_size(SLAVE(inst), &body) > fmi2Warning) return fmi2Error;
    *n = 1 + body;
    return fmi2OK;
}

fmi2Status model_state_save(Instance *inst, unsigned char *out, size_t n) {
    out[0] = inst->model != NULL;
    return inst->model ? py_slave_state_save(SLAVE(inst), out + 1, n - 1) : fmi2OK;
}

fmi2Status model_state_load(Instance *inst, const unsigned char *in, size_t n,
                            const double *values) {
    (void)values;
    if (n < 1 || in[0] > 1 || (!in[0] && n != 1)) {
        fmu_log(inst, fmi2Error, "fmi2SetFMUstate refused: not a state of this FMU");
        return fmi2Error;
    }
    if (!in[0]) {
        model_free(inst);
        return fmi2OK;
    }
    PySlave *p = SLAVE(inst);
    if (!p && !(p = py_slave_new(inst, "the slave runs in Python"))) return fmi2Error;
    if (py_slave_state_load(p, in + 1, n - 1) > fmi2Warning) {
        if (p != SLAVE(inst)) py_slave_free(p);
        return fmi2Error;
    }
    inst->model = p;
    return fmi2OK;
}
