/* The model part of GearPair in C (gearpair_model.h): the records of one engine instance,
 * laid out as the generated header says, and the engine's compiled entry points. */
#include "gearpair_model.h"

#include <stdlib.h>
#include <string.h>

#define N_WORK 18 /* Work's arrays in the hand-off table */

struct GpModel {
    double *setup[GP_SETUP_WORDS / 2]; /* the set-up's arrays (ModelData lives in them) */
    int64_t setup_table[GP_SETUP_WORDS];
    int64_t table[GP_HANDOFF_WORDS]; /* the hand-off table of the records */
    double *work[N_WORK];
    double *state, *saved;
    size_t state_words;
    double block[GP_N_X];
    int early; /* steps may return early at a contact event (FMI 3) */
    int64_t n; /* tracked tooth pairs */
};

static void put(int64_t *table, int k, void *data, const int64_t *dims, int ndim) {
    table[4 * k] = (int64_t)(intptr_t)data;
    for (int d = 0; d < 3; d++) table[4 * k + 1 + d] = d < ndim ? dims[d] : 0;
}

/* The set-up arrays by GP_SETUP_LEN (a table law's two arrays: 2 unused words). */
static int64_t run_setup(GpModel *m, const double *gear, const double *choice) {
    for (int k = 0; k < GP_SETUP_WORDS / 2; k++) {
        int64_t len = GP_SETUP_LEN[k] ? GP_SETUP_LEN[k] : 2;
        m->setup[k] = calloc((size_t)len, sizeof(double));
        if (!m->setup[k]) return -1;
        m->setup_table[2 * k] = (int64_t)(intptr_t)m->setup[k];
        m->setup_table[2 * k + 1] = len;
    }
    memcpy(m->setup[GPS_GP], gear, GP_N_GEAR * sizeof(double));
    memcpy(m->setup[GPS_CHOICE], choice, GP_N_CHOICE * sizeof(double));
    return gearpair_setup((int64_t)(intptr_t)m->setup_table);
}

/* ModelData from the set-up's arrays, Work allocated, HybridState as views of the state. */
static int64_t make_records(GpModel *m) {
    const int64_t *flag = (const int64_t *)m->setup[GPS_FLAG];
    int64_t n = flag[GP_I_NP], ntab = flag[GP_I_NTAB];
    if (n < 1 || n > GP_N_PAIRS_MAX) return -1;
    m->n = n;
    int64_t nk = flag[GP_I_KIND] == GP_KIND_CUBIC ? 4 * (ntab - 1) : ntab;
    const int64_t md_len[6] = {GP_N_MP, GP_N_MI, GP_N_Y, ntab, nk, ntab - 1};
    const int md_src[6] = {GPS_PAR, GPS_FLAG, GPS_ATOL, GPS_XI_KNOTS, GPS_K_COEF,
                           GPS_K_SLOPE};
    int k = 0;
    for (int i = 0; i < 6; i++, k++) put(m->table, k, m->setup[md_src[i]], &md_len[i], 1);
    for (int i = 0; i < N_WORK; i++, k++) {
        const int64_t *dims = GP_WORK_SHAPE[n - 1][i];
        int ndim = GP_HANDOFF_KIND[k][1] - '0';
        size_t words = 1;
        for (int d = 0; d < ndim; d++) words *= (size_t)dims[d];
        m->work[i] = calloc(words, sizeof(double));
        if (!m->work[i]) return -1;
        put(m->table, k, m->work[i], dims, ndim);
    }
    int64_t words = GP_STATE_WORDS(n);
    m->state_words = (size_t)words;
    m->state = calloc((size_t)words, sizeof(double));
    m->saved = calloc((size_t)words, sizeof(double));
    if (!m->state || !m->saved) return -1;
    for (int i = 0; i < 6; i++, k++) {
        int64_t len = GP_STATE_LEN_A[i] + GP_STATE_LEN_B[i] * n;
        put(m->table, k, m->state + GP_STATE_OFF_A[i] + GP_STATE_OFF_B[i] * n, &len, 1);
    }
    const int64_t nx = GP_N_X;
    put(m->table, k++, m->block, &nx, 1);
    put(m->table, k++, m->state, &words, 1);
    put(m->table, k++, m->saved, &words, 1);
    return k == GP_HANDOFF_RUN ? 0 : -1; /* a recorded run's arrays stay empty (zero) */
}

GpModel *gp_model_new(const double *gear, const double *choice, int64_t *status,
                      double *eps) {
    GpModel *m = calloc(1, sizeof *m);
    int64_t st = m ? run_setup(m, gear, choice) : -1;
    if (eps) *eps = m && m->setup[GPS_GEO] ? m->setup[GPS_GEO][GP_GEO_EPS] : 0.0;
    if (st == 0) st = make_records(m);
    if (status) *status = st;
    if (st != 0) {
        gp_model_free(m);
        return NULL;
    }
    return m;
}

void gp_model_free(GpModel *m) {
    if (!m) return;
    for (int k = 0; k < GP_SETUP_WORDS / 2; k++) free(m->setup[k]);
    for (int i = 0; i < N_WORK; i++) free(m->work[i]);
    free(m->state);
    free(m->saved);
    free(m);
}

double *gp_model_block(GpModel *m) { return m->block; }

int64_t gp_model_init(GpModel *m, double t0) {
    m->block[GP_X_TCHK] = t0;
    return gearpair_init((int64_t)(intptr_t)m->table);
}

int64_t gp_model_step(GpModel *m, double t, double h) {
    double *x = m->block;
    x[GP_X_TCHK] = t;
    x[GP_X_H] = h;
    x[GP_X_TEND] = t + h;
    x[GP_X_FMU] = m->early ? 2.0 : 1.0;
    int64_t table = (int64_t)(intptr_t)m->table;
    return m->early ? gearpair_step_early(table) : gearpair_step(table);
}

void gp_model_early_return(GpModel *m, int on) { m->early = on != 0; }

double gp_model_time(const GpModel *m) {
    return m->state[GP_STATE_OFF_A[GP_CLOCK] + GP_STATE_OFF_B[GP_CLOCK] * m->n + GP_T_T];
}

const double *gp_model_summary(const GpModel *m) { return m->work[GP_WORK_SUMMARY]; }

int64_t gp_model_max_events(const GpModel *m) {
    return ((const int64_t *)m->setup[GPS_FLAG])[GP_I_MAXEV];
}

size_t gp_model_state_words(const GpModel *m) { return m->state_words; }

void gp_model_get_state(const GpModel *m, double *out) {
    memcpy(out, m->state, m->state_words * sizeof(double));
}

void gp_model_set_state(GpModel *m, const double *in) {
    memcpy(m->state, in, m->state_words * sizeof(double));
}
