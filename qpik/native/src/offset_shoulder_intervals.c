/* The feasible delta sets of one offset-shoulder pose in one call (qpik.analytic.offset_shoulder_intervals).
 *
 * Compiled with polyroots.c and intervals.c into one library. The breakpoint function (CasADi-generated, of
 * the pose) gives the closed-form candidates and singular candidates (NONE where one does not exist) and the
 * wrist equations' coefficients; qpik_trig_roots solves those; a theta5 root within the common-root tolerance of
 * a theta7 root is a wrist singularity (sin theta6 = 0 zeroes both); circle_sets classifies the gaps with the IK.
 * The same steps as DeltaIntervals.breakpoints and Assembler in numpy.
 */
#include <math.h>

#include "circle.h"
#include "intervals.h"
#include "polyroots.h"

typedef struct {
    Kernel breakpoints; /* pose (arg[0]) -> candidates, singular candidates, A (K, size), B (K, size); the shrunk
                           limits' function reads q_min, q_max too (arg[1], arg[2]: the IK's arg[2], arg[3]) */
    int n_cand, n_sing, K, size;
    int a7, b7, a5, b5; /* the theta7 equations are rows [a7, b7), the theta5 ones [a5, b5) */
    double none;        /* a value that stands for "does not exist" */
    double common;      /* cos of the common-root tolerance: cos(r5 - r7) above it is a common root */
    Kernel ik;          /* the checked IK of rows 1-8: (pose, param, q_min, q_max) -> flags in res[1] */
    double *param;      /* ik's arg[1] */
    int rows, shift;
    int room_roots; /* the wrist roots' room, in delta, owner, and after the candidates in breaks and sing */
    double *delta, *breaks, *sing;
    int *owner;
    int room; /* output room of circle_sets (pairs) */
    double *iv, *sv;
    int *count, *scount;
    int *ns; /* out: the singular candidates' number, the row stride of sv */
    const double *region; /* the classification's region (Call in intervals.c): n_region[0] pairs, none when < 0 */
    const int *n_region;
} DeltaSets;

/* Returns circle_sets' number of pieces or status (-1 no room, -2 a compiled function failed, -3 no memory). */
int qpik_delta_sets(const DeltaSets *d) {
    const Kernel *b = &d->breakpoints;
    if (((casadi_fn)b->fn)(b->arg, b->res, b->iw, b->w, 0)) return -2;
    const double *cand = b->res[0], *sing = b->res[1];
    int nb = 0, ns = 0;
    for (int i = 0; i < d->n_cand; ++i)
        if (cand[i] != d->none) d->breaks[nb++] = cand[i];
    for (int i = 0; i < d->n_sing; ++i)
        if (sing[i] != d->none) d->sing[ns++] = sing[i];
    int m = qpik_trig_roots(d->K, d->size - 1, b->res[2], b->res[3], d->room_roots, d->delta, d->owner);
    if (m < 0) return -1;
    for (int i = 0; i < m; ++i) {
        d->breaks[nb++] = d->delta[i];
        if (d->owner[i] < d->a5 || d->owner[i] >= d->b5) continue;
        for (int j = 0; j < m; ++j) { /* a common root with a theta7 equation (cos only for roots within 0.1 rad) */
            double gap = fabs(d->delta[i] - d->delta[j]);
            if (d->owner[j] < d->a7 || d->owner[j] >= d->b7 || (gap > 0.1 && gap < TWO_PI - 0.1)) continue;
            if (cos(d->delta[i] - d->delta[j]) > d->common) {
                d->sing[ns++] = d->delta[i];
                break;
            }
        }
    }
    *d->ns = ns;
    Call call = {(casadi_fn)d->ik.fn, d->ik.arg, d->ik.res, d->ik.iw, d->ik.w, d->param, d->region, d->n_region};
    return circle_sets(&call, d->rows, d->shift, nb, d->breaks, ns, d->sing, d->room, d->iv, d->count, d->sv,
                       d->scount);
}
