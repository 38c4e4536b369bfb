"""The step block: what a caller of the fast engine's compiled step and the step share.

One float64 array per caller (`gearpair.fast.native`): the end of the step, the inputs held
over it, and the *step record* the step leaves there, the outputs at its end and the figures
over it by name (`STEP_RECORD`). The FMU slave keeps its input and output variables in its
block, so that its C layer sets the inputs, runs the compiled step and reads the outputs
without Python. Plain data: this module imports no numba (the slave reads it with either
engine).

Slots (`X_*`): X_TEND the end of the step (s); X_TCHK, X_H the FMU's communication point and
step size (s); X_TORQUE (N.m), X_SPEED, X_LOAD (rad/s) the inputs, X_LOADON 1 when the load
speed drives the load shaft; X_FMU 1 for an FMU's doStep (the communication point and the
inputs checked, a failed or non-finite step rolled back), 2 for one that may return early at
the first change of the contact state inside it (FMI 3; the engine's time then says where it
stopped); X_BAD the record slot of the first value that is not finite; X_REC the first slot
of the step record.
"""

from __future__ import annotations

(X_TEND, X_TCHK, X_H, X_TORQUE, X_SPEED, X_LOAD, X_LOADON, X_FMU, X_BAD) = range(9)
X_REC = 9
# The step record: the `Outputs` values after time (10), then the `StepSummary` figures
# after t_start and t_end, in their classes' order. Units: m, N, N, code, N.m, N.m, N.m,
# rad/s, rad/s, m/s, 1, 1, N, count, count, 1, N, N.
STEP_RECORD = ("dte", "mesh_force", "friction_force", "contact_state", "output_torque",
               "input_torque_reaction", "input_torque", "gear1_speed", "gear2_speed",
               "sliding_velocity", "stick_fraction", "separation_fraction", "mesh_force_max",
               "n_events", "n_steps", "back_fraction", "mesh_force_mean", "mesh_force_min")
N_X = X_REC + len(STEP_RECORD)
# What a step returns: done; refused before it began (state unchanged: the caller's own
# checks say why); the engine failed (its summary says how); a value is not finite. After
# the last two an FMU's step is rolled back to its start.
STEP_DONE, STEP_REFUSED, STEP_FAILED, STEP_NONFINITE = 0, 1, 2, 3
