/* The planner's grid states (qpik.planning.grid, Grid.layers) in one loop over the CasADi-generated row
 * function (called through its C entry point).
 *
 * The row function maps (pose, parameter) to, per gridded branch b, [q (n), valid and within the limits,
 * f(q), smallest clearance (m)]. For waypoints k = 0..K-1 (poses column-major, 16 entries each) and grid
 * values i = 0..G-1 it is evaluated where some branch's value is inside its exact feasible set
 * (inside[k, b, i]), and the outputs go straight to their places, states (k, b, i) row-major:
 * q[k, b, i, :], ok[k, b, i] = inside and valid and within the limits and clearance >= d_safe and f finite,
 * f[k, b, i] (inf where not ok). Rows with no branch inside are not evaluated: q = 0, ok = 0, f = inf.
 * Returns 0, or -1 when the row function fails.
 */
#include <math.h>
#include <string.h>

typedef long long casadi_int;
typedef int (*casadi_fn)(const double **arg, double **res, casadi_int *iw, double *w, int mem);

int qpik_plan_layers(void *fn, const double **arg, double **res, casadi_int *iw, double *w, double *pose,
                     double *param, const double *row, long long K, long long B, long long G, long long n,
                     const double *cols, const double *values, const unsigned char *inside, double d_safe,
                     double *q, unsigned char *ok, double *f) {
    casadi_fn call = (casadi_fn)fn;
    for (long long k = 0; k < K; ++k) {
        memcpy(pose, cols + 16 * k, 16 * sizeof(double));
        const unsigned char *in = inside + k * B * G;
        for (long long i = 0; i < G; ++i) {
            int any = 0;
            for (long long b = 0; b < B && !any; ++b) any = in[b * G + i];
            if (any) {
                *param = values[i];
                if (call(arg, res, iw, w, 0)) return -1;
            }
            for (long long b = 0; b < B; ++b) {
                long long s = (k * B + b) * G + i;
                const double *r = row + b * (n + 3);
                int good = any && in[b * G + i] && r[n] > 0.5 && r[n + 2] >= d_safe && isfinite(r[n + 1]);
                if (any)
                    memcpy(q + s * n, r, (size_t)n * sizeof(double));
                else
                    memset(q + s * n, 0, (size_t)n * sizeof(double));
                ok[s] = (unsigned char)good;
                f[s] = good ? r[n + 1] : INFINITY;
            }
        }
    }
    return 0;
}
