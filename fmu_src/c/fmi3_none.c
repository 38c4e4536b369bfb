/* What the FMI 3.0 layer does not provide, answered as the standard asks: every fmi3
 * function is exported, and these refuse with fmi3Error and a log message (changing
 * nothing). Get and set of a type the FMU has no variable of succeed for no values. Not
 * provided: Model Exchange and Scheduled Execution, clocks, Configuration Mode (no
 * structural parameters), derivatives, per-element dependencies, output derivatives and
 * fmi3EvaluateDiscreteStates. */
#include <stdio.h>

#include "fmi3_layer.h"

static fmi3Status none_of(fmi3Instance c, unsigned states, const char *fn, size_t nvr,
                          const char *type) {
    Fmi3 *f = c;
    if (!f || !fmi3_allowed(f, states, fn)) return fmi3Error;
    if (!nvr) return fmi3OK;
    ERR(f, "%s: this FMU has no %s variables", fn, type);
    return fmi3Error;
}

#define NO_TYPE(T, CT)                                                                       \
    FMI3_Export fmi3Status fmi3Get##T(fmi3Instance c, const fmi3ValueReference vr[],        \
                                      size_t nvr, CT values[], size_t nv) {                  \
        (void)vr, (void)values, (void)nv;                                                    \
        return none_of(c, GET_STATES, "fmi3Get" #T, nvr, #T);                                \
    }                                                                                        \
    FMI3_Export fmi3Status fmi3Set##T(fmi3Instance c, const fmi3ValueReference vr[],        \
                                      size_t nvr, const CT values[], size_t nv) {            \
        (void)vr, (void)values, (void)nv;                                                    \
        return none_of(c, SET_STATES, "fmi3Set" #T, nvr, #T);                                \
    }
NO_TYPE(Float32, fmi3Float32)
NO_TYPE(Int8, fmi3Int8)
NO_TYPE(UInt8, fmi3UInt8)
NO_TYPE(Int16, fmi3Int16)
NO_TYPE(UInt16, fmi3UInt16)
NO_TYPE(UInt32, fmi3UInt32)
NO_TYPE(UInt64, fmi3UInt64)
NO_TYPE(String, fmi3String)

FMI3_Export fmi3Status fmi3GetBinary(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                     size_t sizes[], fmi3Binary values[], size_t nv) {
    (void)vr, (void)sizes, (void)values, (void)nv;
    return none_of(c, GET_STATES, "fmi3GetBinary", nvr, "Binary");
}

FMI3_Export fmi3Status fmi3SetBinary(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                     const size_t sizes[], const fmi3Binary values[],
                                     size_t nv) {
    (void)vr, (void)sizes, (void)values, (void)nv;
    return none_of(c, SET_STATES, "fmi3SetBinary", nvr, "Binary");
}

FMI3_Export fmi3Status fmi3GetClock(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                    fmi3Clock values[]) {
    (void)vr, (void)values;
    return none_of(c, GET_STATES, "fmi3GetClock", nvr, "Clock");
}

FMI3_Export fmi3Status fmi3SetClock(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                    const fmi3Clock values[]) {
    (void)vr, (void)values;
    return none_of(c, SET_STATES, "fmi3SetClock", nvr, "Clock");
}

/* -- refused calls ------------------------------------------------------------------------- */
static fmi3Status refused(fmi3Instance c, const char *fn, const char *why) {
    if (c) ERR(F(c), "%s is not supported by this FMU (%s)", fn, why);
    return fmi3Error;
}

#define NO_ME "no Model Exchange"
#define NO_CLOCKS "no clocks"

FMI3_Export fmi3Status fmi3GetOutputDerivatives(fmi3Instance c, const fmi3ValueReference vr[],
                                                size_t nvr, const fmi3Int32 orders[],
                                                fmi3Float64 values[], size_t nv) {
    (void)vr, (void)nvr, (void)orders, (void)values, (void)nv;
    return refused(c, "fmi3GetOutputDerivatives", "maxOutputDerivativeOrder is 0");
}

FMI3_Export fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance c,
                                                           fmi3ValueReference vr, size_t *n) {
    (void)vr, (void)n;
    return refused(c, "fmi3GetNumberOfVariableDependencies",
                   "providesPerElementDependencies is false");
}

FMI3_Export fmi3Status fmi3GetVariableDependencies(fmi3Instance c, fmi3ValueReference dep,
                                                   size_t ei_dep[], fmi3ValueReference ind[],
                                                   size_t ei_ind[], fmi3DependencyKind kinds[],
                                                   size_t n) {
    (void)dep, (void)ei_dep, (void)ind, (void)ei_ind, (void)kinds, (void)n;
    return refused(c, "fmi3GetVariableDependencies", "providesPerElementDependencies is false");
}

#define NO_DERIVATIVE(NAME, FLAG)                                                            \
    FMI3_Export fmi3Status NAME(fmi3Instance c, const fmi3ValueReference u[], size_t nu,    \
                                const fmi3ValueReference k[], size_t nk,                     \
                                const fmi3Float64 seed[], size_t ns, fmi3Float64 sens[],     \
                                size_t nsens) {                                              \
        (void)u, (void)nu, (void)k, (void)nk, (void)seed, (void)ns, (void)sens, (void)nsens;  \
        return refused(c, #NAME, FLAG " is false");                                          \
    }
NO_DERIVATIVE(fmi3GetDirectionalDerivative, "providesDirectionalDerivatives")
NO_DERIVATIVE(fmi3GetAdjointDerivative, "providesAdjointDerivatives")

#define NO_CALL(NAME, WHY)                                                                   \
    FMI3_Export fmi3Status NAME(fmi3Instance c) { return refused(c, #NAME, WHY); }
NO_CALL(fmi3EnterConfigurationMode, "no structural parameters")
NO_CALL(fmi3ExitConfigurationMode, "no structural parameters")
NO_CALL(fmi3EvaluateDiscreteStates, "providesEvaluateDiscreteStates is false")
NO_CALL(fmi3EnterContinuousTimeMode, NO_ME)

FMI3_Export fmi3Status fmi3GetIntervalDecimal(fmi3Instance c, const fmi3ValueReference vr[],
                                              size_t nvr, fmi3Float64 x[],
                                              fmi3IntervalQualifier q[]) {
    (void)vr, (void)nvr, (void)x, (void)q;
    return refused(c, "fmi3GetIntervalDecimal", NO_CLOCKS);
}

FMI3_Export fmi3Status fmi3GetIntervalFraction(fmi3Instance c, const fmi3ValueReference vr[],
                                               size_t nvr, fmi3UInt64 x[], fmi3UInt64 r[],
                                               fmi3IntervalQualifier q[]) {
    (void)vr, (void)nvr, (void)x, (void)r, (void)q;
    return refused(c, "fmi3GetIntervalFraction", NO_CLOCKS);
}

FMI3_Export fmi3Status fmi3GetShiftDecimal(fmi3Instance c, const fmi3ValueReference vr[],
                                           size_t nvr, fmi3Float64 x[]) {
    (void)vr, (void)nvr, (void)x;
    return refused(c, "fmi3GetShiftDecimal", NO_CLOCKS);
}

FMI3_Export fmi3Status fmi3GetShiftFraction(fmi3Instance c, const fmi3ValueReference vr[],
                                            size_t nvr, fmi3UInt64 x[], fmi3UInt64 r[]) {
    (void)vr, (void)nvr, (void)x, (void)r;
    return refused(c, "fmi3GetShiftFraction", NO_CLOCKS);
}

FMI3_Export fmi3Status fmi3SetIntervalDecimal(fmi3Instance c, const fmi3ValueReference vr[],
                                              size_t nvr, const fmi3Float64 x[]) {
    (void)vr, (void)nvr, (void)x;
    return refused(c, "fmi3SetIntervalDecimal", NO_CLOCKS);
}

FMI3_Export fmi3Status fmi3SetIntervalFraction(fmi3Instance c, const fmi3ValueReference vr[],
                                               size_t nvr, const fmi3UInt64 x[],
                                               const fmi3UInt64 r[]) {
    (void)vr, (void)nvr, (void)x, (void)r;
    return refused(c, "fmi3SetIntervalFraction", NO_CLOCKS);
}

FMI3_Export fmi3Status fmi3SetShiftDecimal(fmi3Instance c, const fmi3ValueReference vr[],
                                           size_t nvr, const fmi3Float64 x[]) {
    (void)vr, (void)nvr, (void)x;
    return refused(c, "fmi3SetShiftDecimal", NO_CLOCKS);
}

FMI3_Export fmi3Status fmi3SetShiftFraction(fmi3Instance c, const fmi3ValueReference vr[],
                                            size_t nvr, const fmi3UInt64 x[],
                                            const fmi3UInt64 r[]) {
    (void)vr, (void)nvr, (void)x, (void)r;
    return refused(c, "fmi3SetShiftFraction", NO_CLOCKS);
}

FMI3_Export fmi3Status fmi3ActivateModelPartition(fmi3Instance c, fmi3ValueReference clock,
                                                  fmi3Float64 t) {
    (void)clock, (void)t;
    return refused(c, "fmi3ActivateModelPartition", "no Scheduled Execution");
}

FMI3_Export fmi3Status fmi3CompletedIntegratorStep(fmi3Instance c, fmi3Boolean no_set_prior,
                                                   fmi3Boolean *enter_event,
                                                   fmi3Boolean *terminate) {
    (void)no_set_prior, (void)enter_event, (void)terminate;
    return refused(c, "fmi3CompletedIntegratorStep", NO_ME);
}

FMI3_Export fmi3Status fmi3SetTime(fmi3Instance c, fmi3Float64 t) {
    (void)t;
    return refused(c, "fmi3SetTime", NO_ME);
}

#define NO_ME_ARRAY(NAME, CT)                                                                \
    FMI3_Export fmi3Status NAME(fmi3Instance c, CT x[], size_t n) {                          \
        (void)x, (void)n;                                                                    \
        return refused(c, #NAME, NO_ME);                                                     \
    }
NO_ME_ARRAY(fmi3SetContinuousStates, const fmi3Float64)
NO_ME_ARRAY(fmi3GetContinuousStateDerivatives, fmi3Float64)
NO_ME_ARRAY(fmi3GetEventIndicators, fmi3Float64)
NO_ME_ARRAY(fmi3GetContinuousStates, fmi3Float64)
NO_ME_ARRAY(fmi3GetNominalsOfContinuousStates, fmi3Float64)

FMI3_Export fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance c, size_t *n) {
    (void)n;
    return refused(c, "fmi3GetNumberOfEventIndicators", NO_ME);
}

FMI3_Export fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance c, size_t *n) {
    (void)n;
    return refused(c, "fmi3GetNumberOfContinuousStates", NO_ME);
}
