/* Feasible parameter sets on the circle from breakpoints (intervals.c), for the C files that classify an arm's gaps
 * (offset_shoulder_intervals.c, srs_intervals.c). */
#ifndef QPIK_INTERVALS_H
#define QPIK_INTERVALS_H

#include "casadi_call.h"
#include "internal.h"

/* The call: fn(arg, res) with the parameter written to *param; flags = res[1] (valid, singular, within
 * per branch). A region (region[0..2 n), n = *n_region >= 0 pairs (lo, hi) in [-pi, pi]), when there is one,
 * holds every feasible gap: a gap whose middle lies outside it is infeasible on every row, with no evaluation (the
 * caller knows the sets are inside an earlier, larger one: qpik.nlp.levelset's rounds). */
typedef struct {
    casadi_fn fn;
    const double **arg;
    double **res;
    casadi_int *iw;
    double *w;
    double *param;
    const double *region;
    const int *n_region;
} Call;

/* Feasible sets of `rows` branches (2 rows with shift) from nb breakpoints, and their singular values, with
 * the IK `call`. Out: count[r] pieces per output row, their (lo, hi) pairs one row after the other in iv (room
 * pairs), and scount[r] singular values of row r in sv[r * ns ...]. Returns the number of pieces, -1 when room is
 * too small, -2 when the IK fails, -3 without memory. */
QPIK_INTERNAL int circle_sets(const Call *call, int rows, int shift, int nb, const double *breaks, int ns,
                              const double *sing, int room, double *iv, int *count, double *sv, int *scount);

#endif
