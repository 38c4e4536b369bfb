/* The model part of GearPair in C: one engine instance over the engine's object file
 * (gearpair_engine.o and its generated header, gearpair.aot). It names no FMI function: an
 * FMI layer (or any C program) creates an instance from the gear data and choices, sets the
 * inputs in its step block, initializes, steps, and copies its state. Nothing is shared
 * between instances, so instances step in parallel threads. */
#ifndef GEARPAIR_MODEL_H
#define GEARPAIR_MODEL_H

#include <stddef.h>
#include <stdint.h>

#include "gearpair_engine.h"

typedef struct GpModel GpModel;

/* A new instance of gear data gear[GP_N_GEAR] (GearParams' order) and choices
 * choice[GP_N_CHOICE] (the set-up's C_* slots, NaN: not given). Returns it, or NULL with
 * *status the set-up's status (GP_SETUP_TEXT[*status] says why, with the contact ratio
 * *eps; -1: no memory); eps may be NULL. */
GpModel *gp_model_new(const double *gear, const double *choice, int64_t *status,
                      double *eps);
void gp_model_free(GpModel *m);

/* The step block (GP_X_* slots, the step record from GP_X_REC): inputs in, record out. */
double *gp_model_block(GpModel *m);

/* The static equilibrium at t0 under the block's torque and speed, and its outputs in the
 * record (GP_STEP_DONE; GP_STEP_REFUSED: an input out of range, nothing changed). */
int64_t gp_model_init(GpModel *m, double t0);

/* One communication step from t over h with the block's inputs (an FMU's doStep: refused
 * when t is not the engine's time, rolled back when it fails). GP_STEP_* code. With early
 * return on (gp_model_early_return), a step that is done may end at the first change of
 * the contact state inside it, the switch applied: gp_model_time says where. */
int64_t gp_model_step(GpModel *m, double t, double h);
void gp_model_early_return(GpModel *m, int on);

/* The engine's time (s), the summary of its last step (GP_O_* slots: why it failed) and
 * the most contact switches it takes in one step. */
double gp_model_time(const GpModel *m);
const double *gp_model_summary(const GpModel *m);
int64_t gp_model_max_events(const GpModel *m);

/* The engine's state: one buffer of gp_model_state_words doubles (a snapshot is a copy). */
size_t gp_model_state_words(const GpModel *m);
void gp_model_get_state(const GpModel *m, double *out);
void gp_model_set_state(GpModel *m, const double *in);

#endif
