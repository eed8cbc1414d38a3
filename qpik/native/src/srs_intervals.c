/* The feasible psi sets of one S-R-S pose in one call (qpik.analytic.srs_intervals).
 *
 * Compiled with intervals.c into one library. The breakpoint function (CasADi-generated, of the pose, and of
 * q_min and q_max for shrunk limits) gives every breakpoint, the singular psi (NONE where one does not exist) and
 * whether the pose is reachable; the singular psi that exist are breakpoints too, and circle_sets classifies the
 * gaps with the IK. The same steps as PsiIntervals.__call__ and Assembler in numpy.
 */
#include "intervals.h"

typedef struct {
    Kernel breakpoints; /* pose (arg[0]) -> breakpoints (n_breaks), singular psi (n_sing), valid (1); the shrunk
                           limits' function reads q_min, q_max too (arg[1], arg[2]: the IK's arg[2], arg[3]) */
    int n_breaks, n_sing;
    double none; /* a singular psi that does not exist */
    Kernel ik;   /* the checked IK of the rows: (pose, param, q_min, q_max) -> flags in res[1] */
    double *param; /* ik's arg[1] */
    int rows;
    double *breaks; /* room for n_breaks + n_sing */
    int room;       /* output room of circle_sets (pairs) */
    double *iv, *sv;
    int *count, *scount; /* sv and scount: circle_sets' singular values, none asked for (scount all 0) */
    const double *region; /* the classification's region (Call in intervals.c): n_region[0] pairs, none when < 0 */
    const int *n_region;
} PsiSets;

/* Returns circle_sets' number of pieces (0 for every row of an unreachable pose) or status (-1 no room, -2 a
 * compiled function failed, -3 no memory). */
int qpik_psi_sets(const PsiSets *p) {
    const Kernel *b = &p->breakpoints;
    if (((casadi_fn)b->fn)(b->arg, b->res, b->iw, b->w, 0)) return -2;
    if (b->res[2][0] < 0.5) {
        for (int r = 0; r < p->rows; ++r) p->count[r] = 0, p->scount[r] = 0;
        return 0;
    }
    const double *breaks = b->res[0], *sing = b->res[1];
    int nb = 0;
    for (int i = 0; i < p->n_breaks; ++i) p->breaks[nb++] = breaks[i];
    for (int i = 0; i < p->n_sing; ++i)
        if (sing[i] != p->none) p->breaks[nb++] = sing[i];
    Call call = {(casadi_fn)p->ik.fn, p->ik.arg, p->ik.res, p->ik.iw, p->ik.w, p->param, p->region, p->n_region};
    return circle_sets(&call, p->rows, 0, nb, p->breaks, 0, sing, p->room, p->iv, p->count, p->sv, p->scount);
}
