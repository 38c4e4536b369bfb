/* Runs the fast engine from its object file alone (gearpair_engine.o, gearpair.aot) through
 * the C model part (gearpair_model.c): no Python, no numba. Reads from stdin the gear data
 * (GP_N_GEAR numbers), the choices (GP_N_CHOICE numbers, nan for "not given") and a run:
 * t0 dt steps torque speed. Prints the step record (GP_RECORD_NAMES) after the
 * initialization and after every step, each number as %a (exact bits), as a master would
 * step it (from the engine's time t to t + dt). Then restores the state it copied halfway
 * and steps the second half again, which must repeat the same bits.
 * With the argument --threads it also runs two more instances at once, each in a thread
 * of its own, which must give the serial run's bits.
 * Exit 0; 2 on bad input or a refused set-up (the reason on stderr); 3 when a step fails;
 * 4 when the restored state does not repeat the run; 5 when a thread's run differs.
 *
 * Build: cc -O2 -pthread -o engine_run engine_run.c gearpair_model.c gearpair_engine.o -lm
 * (the header gearpair_engine.h beside the object, written with it). */
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearpair_model.h"

static void print_record(const double *r) {
    for (int m = 0; m < GP_N_RECORD; m++) printf(m ? " %a" : "%a", r[m]);
    printf("\n");
}

/* Steps i0 .. steps-1 from time t; the records into rec (steps x GP_N_RECORD) when given. */
static int run(GpModel *m, double t, double dt, long i0, long steps, double *rec) {
    double *x = gp_model_block(m);
    for (long i = i0; i < steps; i++) {
        int64_t code = gp_model_step(m, t, dt);
        if (code != GP_STEP_DONE) {
            fprintf(stderr, "step %ld: code %lld\n", i, (long long)code);
            return 3;
        }
        t = x[GP_X_TEND];
        memcpy(rec + i * GP_N_RECORD, x + GP_X_REC, GP_N_RECORD * sizeof(double));
    }
    return 0;
}

typedef struct {
    const double *gear, *choice;
    double t0, dt, torque, speed;
    long steps;
    double *rec;
    int rc;
} Job;

/* A whole run of a new instance (a thread's work). */
static void *job(void *arg) {
    Job *j = arg;
    int64_t st;
    GpModel *m = gp_model_new(j->gear, j->choice, &st, NULL);
    j->rc = 2;
    if (m) {
        double *x = gp_model_block(m);
        x[GP_X_TORQUE] = j->torque;
        x[GP_X_SPEED] = j->speed;
        if (gp_model_init(m, j->t0) == GP_STEP_DONE)
            j->rc = run(m, j->t0, j->dt, 0, j->steps, j->rec);
        gp_model_free(m);
    }
    return NULL;
}

/* Two instances in two threads at once against the serial records ``rec``. */
static int threads(Job proto, const double *rec) {
    Job jobs[2] = {proto, proto};
    pthread_t th[2];
    size_t n = (size_t)proto.steps * GP_N_RECORD;
    for (int i = 0; i < 2; i++) {
        jobs[i].rec = calloc(n, sizeof(double));
        if (!jobs[i].rec || pthread_create(&th[i], NULL, job, &jobs[i]) != 0) return 2;
    }
    int rc = 0;
    for (int i = 0; i < 2; i++) {
        pthread_join(th[i], NULL);
        if (jobs[i].rc) rc = jobs[i].rc;
        else if (memcmp(jobs[i].rec, rec, n * sizeof(double)) != 0) rc = 5;
        free(jobs[i].rec);
    }
    if (rc == 5) fprintf(stderr, "a thread's run differs from the serial one\n");
    return rc;
}

int main(int argc, char **argv) {
    double gear[GP_N_GEAR], choice[GP_N_CHOICE], t0, dt, torque, speed;
    long steps;
    for (int i = 0; i < GP_N_GEAR; i++)
        if (scanf("%lf", &gear[i]) != 1) return fprintf(stderr, "gear datum %d?\n", i), 2;
    for (int i = 0; i < GP_N_CHOICE; i++)
        if (scanf("%lf", &choice[i]) != 1) return fprintf(stderr, "choice %d?\n", i), 2;
    if (scanf("%lf %lf %ld %lf %lf", &t0, &dt, &steps, &torque, &speed) != 5 || steps < 2)
        return fprintf(stderr, "run: t0 dt steps (>= 2) torque speed?\n"), 2;
    int64_t st;
    GpModel *m = gp_model_new(gear, choice, &st, NULL);
    if (!m) {
        fprintf(stderr, "set-up refused: %s\n",
                st > 0 && st < 7 ? GP_SETUP_STATUS[st] : "internal error");
        return 2;
    }
    double *x = gp_model_block(m);
    x[GP_X_TORQUE] = torque;
    x[GP_X_SPEED] = speed;
    if (gp_model_init(m, t0) != GP_STEP_DONE) return fprintf(stderr, "init refused\n"), 2;
    print_record(x + GP_X_REC);
    double *rec = calloc((size_t)steps * GP_N_RECORD, sizeof(double));
    double *again = calloc((size_t)steps * GP_N_RECORD, sizeof(double));
    double *half = calloc(gp_model_state_words(m), sizeof(double));
    if (!rec || !again || !half) return fprintf(stderr, "no memory\n"), 2;
    long mid = steps / 2;
    int rc = run(m, t0, dt, 0, mid, rec);
    double t_mid = x[GP_X_TEND]; /* the engine's time after the first half */
    gp_model_get_state(m, half);
    if (!rc) rc = run(m, t_mid, dt, mid, steps, rec);
    if (rc) return rc;
    for (long i = 0; i < steps; i++) print_record(rec + i * GP_N_RECORD);
    gp_model_set_state(m, half);
    rc = run(m, t_mid, dt, mid, steps, again);
    if (rc) return rc;
    if (memcmp(rec + mid * GP_N_RECORD, again + mid * GP_N_RECORD,
               (size_t)(steps - mid) * GP_N_RECORD * sizeof(double)) != 0)
        return fprintf(stderr, "the restored state did not repeat the run\n"), 4;
    gp_model_free(m);
    if (argc > 1 && strcmp(argv[1], "--threads") == 0) {
        Job proto = {gear, choice, t0, dt, torque, speed, steps, NULL, 0};
        rc = threads(proto, rec);
        if (rc) return rc;
    }
    free(rec);
    free(again);
    free(half);
    return 0;
}
