/* Calling CasADi-generated C from qpik's C code (qpik.build.call_header prepends this to its sources). */

typedef long long casadi_int;
typedef int (*casadi_fn)(const double **arg, double **res, casadi_int *iw, double *w, int mem);

/* A CasADi-generated function and its argument and result pointer arrays and work arrays (qpik.compiled.Kernel). */
typedef struct {
    void *fn;
    const double **arg;
    double **res;
    casadi_int *iw;
    double *w;
} Kernel;
