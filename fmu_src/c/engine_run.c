/* Runs the fast engine from its object file alone (gearpair_engine.o, gearpair.aot): no
 * Python, no numba. Reads from stdin the gear data (GP_N_GEAR numbers), the choices
 * (GP_N_CHOICE numbers, nan for "not given") and a run: t0 dt steps torque speed; prints
 * the step record (GP_RECORD_NAMES) after the initialization and after every step, each
 * number as %a (exact bits). Exit 0; 2 on bad input or a refused set-up (the reason on
 * stderr); 3 when a step fails.
 *
 * Build: cc -O2 -o engine_run engine_run.c gearpair_engine.o -lm
 * (the header gearpair_engine.h beside the object, written with it). */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearpair_engine.h"

typedef struct {
    double *setup[GP_SETUP_WORDS / 2];   /* the set-up arrays (flag as double words) */
    int64_t setup_table[GP_SETUP_WORDS];
    int64_t table[GP_HANDOFF_WORDS];     /* the hand-off table of the records */
    double *state, *saved, block[GP_N_X];
    void *work[18];
    int64_t n;
    int lti;
} Engine;

static int put(int64_t *table, int k, void *data, const int64_t *dims, int ndim) {
    table[4 * k] = (int64_t)(intptr_t)data;
    for (int d = 0; d < 3; d++) table[4 * k + 1 + d] = d < ndim ? dims[d] : 0;
    return 0;
}

/* The set-up: arrays by GP_SETUP_LEN (the table law's two arrays unused: length 2). */
static int64_t engine_setup(Engine *e, const double *gear, const double *choice) {
    for (int k = 0; k < GP_SETUP_WORDS / 2; k++) {
        int64_t len = GP_SETUP_LEN[k] ? GP_SETUP_LEN[k] : 2;
        e->setup[k] = calloc((size_t)len, sizeof(double));
        if (!e->setup[k]) return -1;
        e->setup_table[2 * k] = (int64_t)(intptr_t)e->setup[k];
        e->setup_table[2 * k + 1] = len;
    }
    memcpy(e->setup[GPS_GP], gear, GP_N_GEAR * sizeof(double));
    memcpy(e->setup[GPS_CHOICE], choice, GP_N_CHOICE * sizeof(double));
    return gearpair_setup((int64_t)(intptr_t)e->setup_table);
}

/* The records of the hand-off table for the set-up's model. */
static int engine_records(Engine *e) {
    const int64_t *flag = (const int64_t *)e->setup[GPS_FLAG];
    int64_t n = flag[GP_I_NP], ntab = flag[GP_I_NTAB];
    if (n < 1 || n > GP_N_PAIRS_MAX) return -1;
    e->n = n;
    e->lti = flag[GP_I_LTI] != 0;
    int64_t nk = flag[GP_I_KIND] == GP_KIND_CUBIC ? 4 * (ntab - 1) : ntab;
    int64_t md_len[6] = {GP_N_MP, GP_N_MI, GP_N_Y, ntab, nk, ntab - 1};
    int md_src[6] = {GPS_PAR, GPS_FLAG, GPS_ATOL, GPS_XI_KNOTS, GPS_K_COEF, GPS_K_SLOPE};
    int k = 0;
    for (int i = 0; i < 6; i++, k++) put(e->table, k, e->setup[md_src[i]], &md_len[i], 1);
    for (int i = 0; i < 18; i++, k++) {
        const int64_t *dims = GP_WORK_SHAPE[n - 1][i];
        int ndim = GP_HANDOFF_KIND[k][1] - '0';
        size_t words = 1;
        for (int d = 0; d < ndim; d++) words *= (size_t)dims[d];
        e->work[i] = calloc(words, 8);
        if (!e->work[i]) return -1;
        put(e->table, k, e->work[i], dims, ndim);
    }
    int64_t words = GP_STATE_WORDS(n);
    e->state = calloc((size_t)words, 8);
    e->saved = calloc((size_t)words, 8);
    if (!e->state || !e->saved) return -1;
    for (int i = 0; i < 6; i++, k++) {
        int64_t len = GP_STATE_LEN_A[i] + GP_STATE_LEN_B[i] * n;
        put(e->table, k, e->state + GP_STATE_OFF_A[i] + GP_STATE_OFF_B[i] * n, &len, 1);
    }
    int64_t nx = GP_N_X;
    put(e->table, k++, e->block, &nx, 1);
    put(e->table, k++, e->state, &words, 1);
    put(e->table, k++, e->saved, &words, 1);
    return k == GP_HANDOFF_ARRAYS ? 0 : -1;
}

static void print_record(const double *x) {
    for (int m = 0; m < GP_N_RECORD; m++) printf(m ? " %a" : "%a", x[GP_X_REC + m]);
    printf("\n");
}

int main(void) {
    double gear[GP_N_GEAR], choice[GP_N_CHOICE], t0, dt, torque, speed;
    long steps;
    for (int i = 0; i < GP_N_GEAR; i++)
        if (scanf("%lf", &gear[i]) != 1) return fprintf(stderr, "gear datum %d?\n", i), 2;
    for (int i = 0; i < GP_N_CHOICE; i++)
        if (scanf("%lf", &choice[i]) != 1) return fprintf(stderr, "choice %d?\n", i), 2;
    if (scanf("%lf %lf %ld %lf %lf", &t0, &dt, &steps, &torque, &speed) != 5)
        return fprintf(stderr, "run: t0 dt steps torque speed?\n"), 2;
    Engine e;
    memset(&e, 0, sizeof e);
    int64_t st = engine_setup(&e, gear, choice);
    if (st != 0) {
        fprintf(stderr, "set-up refused: %s\n",
                st > 0 && st < 7 ? GP_SETUP_STATUS[st] : "internal error");
        return 2;
    }
    if (engine_records(&e) != 0) return fprintf(stderr, "no memory or too many pairs\n"), 2;
    double *x = e.block;
    x[GP_X_TCHK] = t0;
    x[GP_X_TORQUE] = torque;
    x[GP_X_SPEED] = speed;
    if (gearpair_init((int64_t)(intptr_t)e.table) != GP_STEP_DONE)
        return fprintf(stderr, "initialization refused\n"), 2;
    print_record(x);
    double t = t0;
    for (long i = 0; i < steps; i++) {
        x[GP_X_TCHK] = t;
        x[GP_X_H] = dt;
        x[GP_X_TEND] = t0 + (double)(i + 1) * dt;
        x[GP_X_FMU] = 1.0;
        int64_t code = e.lti ? gearpair_step_lti((int64_t)(intptr_t)e.table)
                             : gearpair_step((int64_t)(intptr_t)e.table);
        if (code != GP_STEP_DONE) return fprintf(stderr, "step %ld: code %lld\n", i,
                                                 (long long)code), 3;
        t = x[GP_X_TEND];
        print_record(x);
    }
    return 0;
}
