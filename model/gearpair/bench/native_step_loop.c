/* The native step's loop for `gearpair bench` (gearpair/bench/nativestep.py): the loop a
 * co-simulation master runs, with the engine's compiled step called at its C address, as
 * the C layer of the pythonfmu-based FMU that GearPair.fmu replaced called it.
 *
 * Loaded with ctypes into a Python process that holds a FastEngine (its records, hand-off
 * table and step block): per step it writes the inputs and the step's times into the step
 * block, as fmi2SetReal and fmi2DoStep of the FMU write them (X_FMU = 1: the FMU's checks
 * and rollback), calls `int64_t step(int64_t table)` and reads the outputs from the step
 * record, as fmi2GetReal does. The timed loop is C, so that the only difference from the
 * FMU's step in the C host (fmi2_bench_host.c) is the call path, not Python.
 *
 * Build: gcc -O2 -shared -fPIC -o native_step_loop.so native_step_loop.c
 */
#define _GNU_SOURCE
#include <stdint.h>
#include <string.h>
#include <time.h>

typedef int64_t (*step_fn)(int64_t table);

/* The slots of the step block the loop writes (stepblock.X_*), in this order. */
enum { S_TEND, S_TCHK, S_H, S_TORQUE, S_SPEED, S_FMU, N_SLOTS };

static double now(clockid_t id) {
    struct timespec ts;
    clock_gettime(id, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* N steps of h on the master's grid (step k from (first + k + 1) * h, as the C host's block
 * `first / n` steps; first = -1: the first step, from 0), calling the compiled step at
 * `step_address` on the hand-off table `table` with the step block `x`. `slots`: the
 * block's slots (N_SLOTS, then the n_out record slots of the outputs read each step).
 * `digest` (FNV-1a, as the host's) goes on over the bits of every output of every step;
 * times[0], times[1]: the loop's wall time and the thread's CPU time (s). Returns 0 (every
 * step done) or the first step's code that was not (a STEP_* code). */
int64_t native_block(int64_t step_address, int64_t table, double *x, const int64_t *slots,
                     int64_t n_out, double torque, double speed, double h, int64_t first,
                     int64_t n, uint64_t *digest, double *times) {
    step_fn step = (step_fn)(intptr_t)step_address;
    const int64_t *out = slots + N_SLOTS;
    uint64_t d = *digest;
    int64_t code = 0;
    double w0 = now(CLOCK_MONOTONIC), c0 = now(CLOCK_THREAD_CPUTIME_ID);
    for (int64_t k = 0; k < n; k++) {
        double t = (double)(first + k + 1) * h; /* the master's grid, i*h */
        x[slots[S_TORQUE]] = torque;             /* fmi2SetReal of the inputs */
        x[slots[S_SPEED]] = speed;
        x[slots[S_TCHK]] = t; /* fmi2DoStep(t, h), as the FMU's model part sets it */
        x[slots[S_H]] = h;
        x[slots[S_TEND]] = t + h;
        x[slots[S_FMU]] = 1.0;
        code = step(table);
        if (code != 0) break;
        for (int64_t j = 0; j < n_out; j++) { /* fmi2GetReal of the outputs */
            uint64_t bits;
            memcpy(&bits, &x[out[j]], sizeof bits);
            d = (d ^ bits) * 1099511628211ull;
        }
    }
    times[0] = now(CLOCK_MONOTONIC) - w0;
    times[1] = now(CLOCK_THREAD_CPUTIME_ID) - c0;
    *digest = d;
    return code;
}
