/* A model part (fmu.h) that does nothing: initialization and steps succeed and leave every
 * value as it is. With GearPair's variable table it is the floor of the bench
 * (gearpair.bench: the generic FMI layer's own cost per call, without any model). */
#include "fmu.h"

int model_new(Instance *inst) {
    inst->model = NULL;
    return 0;
}
void model_free(Instance *inst) { (void)inst; }
void model_reset(Instance *inst) { (void)inst; }
int model_gone(Instance *inst, const char *fn) { return (void)inst, (void)fn, 0; }
void model_setup_experiment(Instance *inst, int tol_defined, double tol) {
    (void)inst, (void)tol_defined, (void)tol;
}
fmi2Status model_exit_init(Instance *inst) { return (void)inst, fmi2OK; }
fmi2Status model_do_step(Instance *inst, double t, double h) {
    return (void)inst, (void)t, (void)h, fmi2OK;
}
fmi2Status model_state_size(Instance *inst, size_t *n) {
    (void)inst;
    *n = 0;
    return fmi2OK;
}
fmi2Status model_state_save(Instance *inst, unsigned char *out, size_t n) {
    return (void)inst, (void)out, (void)n, fmi2OK;
}
fmi2Status model_state_load(Instance *inst, const unsigned char *in, size_t n,
                            const double *values) {
    (void)in, (void)values;
    if (n) fmu_log(inst, fmi2Error, "fmi2SetFMUstate refused: not a state of this FMU");
    return n ? fmi2Error : fmi2OK;
}
