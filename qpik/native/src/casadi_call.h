/* Calling CasADi-generated C from qpik's C code: its integer and function types, and a generated function with its
 * argument and result pointer arrays and work arrays (qpik.native.compiled.Kernel, the same fields). */
#ifndef QPIK_CASADI_CALL_H
#define QPIK_CASADI_CALL_H

typedef long long casadi_int;
typedef int (*casadi_fn)(const double **arg, double **res, casadi_int *iw, double *w, int mem);

typedef struct {
    void *fn;
    const double **arg;
    double **res;
    casadi_int *iw;
    double *w;
} Kernel;

#endif
