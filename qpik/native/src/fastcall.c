/* qpik's CPython extension (qpik.fastcall): calls the CasADi-generated C of qpik's kernels from Python.
 *
 * A Kernel holds one generated function (its entry point, taken from the shared library that
 * qpik.compiled built), the pointer and work arrays of CasADi's calling convention, and input and
 * output buffers owned by numpy arrays that the Python side keeps. A call copies its arguments into
 * the input buffers and runs the function: no CasADi dispatch, no ctypes marshalling.
 *
 * - kernel(*args): arguments as qpik.compiled.Compiled takes them (float64 vectors of the input's
 *   size, (rows, cols) float64 matrices copied in column-major order, and for a scalar input any real
 *   number: a Python float or int, a numpy floating or integer scalar, a 0-d array of one; not a bool);
 *   returns the object given at construction (the Compiled's output views). None when an argument is
 *   of another form, for the caller's general path.
 * - kernel.fresh(*args): the same with every argument checked in C (finite; a pose input is a
 *   homogeneous transform with an orthonormal rotation); returns a tuple of new arrays, one per kept
 *   output (a column-major matrix turned row-major, raw entries, or flags > 0.5 as bools). None when
 *   an argument fails a check: the caller's Python path then raises the error that names it.
 * - kernel.into(outs, *args): fresh's checks, the outputs written into the caller's arrays `outs`
 *   (float64, C-contiguous, of the outputs' shapes). Returns outs, or None as fresh does.
 *
 * Arguments left out keep their buffer's content (constant inputs are written once by the caller).
 *
 * The module's scatter(parts, names, views) writes parts by name into numpy views (qpik.control.inputs: a task's or
 * limit's parameters into the controller's buffer), as `view[...] = parts[name]` does.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>
#include <numpy/arrayscalars.h>
#include <math.h>
#include <stddef.h>
#include <string.h>

#include "casadi_call.h"

#define MAX_IO 16
#define ORTHONORMAL_TOL 1e-6 /* qpik.validate.ORTHONORMAL_TOL */
#define MAX_LENGTH 1e6       /* qpik.validate.MAX_LENGTH, m */

enum { IN_PLAIN = 0, IN_POSE = 1, IN_SCALAR = 2 };
enum { OUT_MATRIX = 0, OUT_RAW = 1, OUT_FLAGS = 2, OUT_SKIP = 3 };

static PyObject *input_error; /* qpik.errors.InputError, given by set_input_error */

static PyObject *qpik_input_error(void) { return input_error ? input_error : PyExc_ValueError; }

typedef struct {
    PyObject_HEAD
    vectorcallfunc vectorcall;
    casadi_fn fn;
    int n_in, n_out, n_kept;
    const double **arg;
    double **res;
    casadi_int *iw;
    double *w;
    double *in[MAX_IO];
    Py_ssize_t in_rows[MAX_IO], in_cols[MAX_IO];
    int in_kind[MAX_IO];
    double *out[MAX_IO];
    Py_ssize_t out_rows[MAX_IO], out_cols[MAX_IO];
    int out_kind[MAX_IO], out_nd[MAX_IO];
    npy_intp out_dims[MAX_IO][3];
    PyObject *keep;   /* the arrays whose memory is used and the owner of fn */
    PyObject *result; /* what a call returns */
} KernelObject;

/* Whether the row-major 4x4 T is a pose qpik.validate.single_pose accepts without projection. */
static int pose_ok(const double *T) {
    if (fabs(T[12]) > 1e-12 || fabs(T[13]) > 1e-12 || fabs(T[14]) > 1e-12 || fabs(T[15] - 1.0) > 1e-12) return 0;
    if (fabs(T[3]) > MAX_LENGTH || fabs(T[7]) > MAX_LENGTH || fabs(T[11]) > MAX_LENGTH) return 0;
    double a = T[0], b = T[1], c = T[2], d = T[4], e = T[5], f = T[6], g = T[8], h = T[9], i = T[10];
    double det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g);
    double err[7] = {a * a + d * d + g * g - 1.0, b * b + e * e + h * h - 1.0, c * c + f * f + i * i - 1.0,
                     a * b + d * e + g * h,       a * c + d * f + g * i,       b * c + e * f + h * i,
                     det - 1.0};
    for (int k = 0; k < 7; ++k)
        if (!(fabs(err[k]) <= ORTHONORMAL_TOL)) return 0;
    return 1;
}

/* The value of a real number a in *x: a Python float or int, a numpy floating or integer scalar (float64, float32,
 * int64, uint8, ...), or a 0-d array of one. Returns 1, or 0 for anything else (a bool, a complex number, an int
 * beyond float64's range, a 0-d array of another type) and for a conversion that fails (no exception left set). */
static int scalar_value(PyObject *a, double *x) {
    if (PyFloat_CheckExact(a)) {
        *x = PyFloat_AS_DOUBLE(a);
        return 1;
    }
    if (PyArray_IsScalar(a, Double)) {
        *x = PyArrayScalar_VAL(a, Double);
        return 1;
    }
    if (PyLong_CheckExact(a)) { /* not a bool: its type is a subclass */
        *x = PyLong_AsDouble(a);
        if (*x == -1.0 && PyErr_Occurred()) {
            PyErr_Clear();
            return 0;
        }
        return 1;
    }
    if (PyArray_IsScalar(a, Floating) || PyArray_IsScalar(a, Integer)) {
        PyArray_Descr *to = PyArray_DescrFromType(NPY_DOUBLE);
        int failed = PyArray_CastScalarToCtype(a, x, to) < 0;
        Py_DECREF(to);
        if (failed) PyErr_Clear();
        return !failed;
    }
    if (PyArray_CheckExact(a) && PyArray_NDIM((PyArrayObject *)a) == 0) {
        PyArrayObject *arr = (PyArrayObject *)a;
        if (PyArray_TYPE(arr) == NPY_DOUBLE && PyArray_ISALIGNED(arr) && PyArray_ISNOTSWAPPED(arr)) {
            *x = *(const double *)PyArray_DATA(arr);
            return 1;
        }
        if (!PyTypeNum_ISFLOAT(PyArray_TYPE(arr)) && !PyTypeNum_ISINTEGER(PyArray_TYPE(arr))) return 0;
        PyObject *item = PyArray_ToScalar(PyArray_DATA(arr), arr); /* a numpy scalar of the array's type */
        if (!item) {
            PyErr_Clear();
            return 0;
        }
        int ok = scalar_value(item, x);
        Py_DECREF(item);
        return ok;
    }
    return 0;
}

/* Copy argument a into input k. Returns 1 on success, 0 when a is of another form (or fails the
 * checks, with `checked`). A scalar input (one entry) takes a real number (scalar_value); an input of kind
 * IN_SCALAR takes nothing else. */
static int load_input(KernelObject *self, int k, PyObject *a, int checked) {
    double *dst = self->in[k];
    Py_ssize_t rows = self->in_rows[k], cols = self->in_cols[k], size = rows * cols;
    if (size == 1 && scalar_value(a, dst)) return !checked || isfinite(dst[0]);
    if (self->in_kind[k] == IN_SCALAR || !PyArray_CheckExact(a)) return 0;
    PyArrayObject *arr = (PyArrayObject *)a;
    if (PyArray_TYPE(arr) != NPY_DOUBLE || !PyArray_IS_C_CONTIGUOUS(arr) || !PyArray_ISALIGNED(arr)) return 0;
    const double *src = (const double *)PyArray_DATA(arr);
    int nd = PyArray_NDIM(arr);
    const npy_intp *dims = PyArray_DIMS(arr);
    if (nd == 1 && dims[0] == size && self->in_kind[k] == IN_PLAIN) {
        memcpy(dst, src, sizeof(double) * (size_t)size);
    } else if (nd == 2 && dims[0] == rows && dims[1] == cols) {
        if (checked && self->in_kind[k] == IN_POSE && !pose_ok(src)) return 0;
        for (Py_ssize_t i = 0; i < rows; ++i)
            for (Py_ssize_t j = 0; j < cols; ++j) dst[j * rows + i] = src[i * cols + j];
    } else {
        return 0;
    }
    if (checked)
        for (Py_ssize_t i = 0; i < size; ++i)
            if (!isfinite(dst[i])) return 0;
    return 1;
}

/* Load the arguments and evaluate; 1 on success, 0 when an argument does not fit, -1 with an exception. */
static int run(KernelObject *self, PyObject *const *args, Py_ssize_t nargs, int checked) {
    if (nargs > self->n_in) {
        PyErr_Format(PyExc_TypeError, "kernel takes at most %d arguments, got %zd", self->n_in, nargs);
        return -1;
    }
    for (Py_ssize_t k = 0; k < nargs; ++k)
        if (!load_input(self, (int)k, args[k], checked)) return 0;
    if (self->fn(self->arg, self->res, self->iw, self->w, 0)) {
        PyErr_SetString(PyExc_RuntimeError, "qpik kernel: the generated function failed");
        return -1;
    }
    return 1;
}

/* Output k written into dst (its kept form, see the file's comment). */
static void store(KernelObject *self, int k, void *dst) {
    const double *src = self->out[k];
    Py_ssize_t rows = self->out_rows[k], cols = self->out_cols[k], size = rows * cols;
    if (self->out_kind[k] == OUT_MATRIX) {
        double *d = (double *)dst;
        for (Py_ssize_t i = 0; i < rows; ++i)
            for (Py_ssize_t j = 0; j < cols; ++j) d[i * cols + j] = src[j * rows + i];
    } else if (self->out_kind[k] == OUT_RAW) {
        memcpy(dst, src, sizeof(double) * (size_t)size);
    } else {
        npy_bool *d = (npy_bool *)dst;
        for (Py_ssize_t i = 0; i < size; ++i) d[i] = src[i] > 0.5;
    }
}

static PyObject *kernel_vectorcall(PyObject *obj, PyObject *const *args, size_t nargsf, PyObject *kwnames) {
    KernelObject *self = (KernelObject *)obj;
    if (kwnames && PyTuple_GET_SIZE(kwnames)) {
        PyErr_SetString(PyExc_TypeError, "kernel takes no keyword arguments");
        return NULL;
    }
    int ok = run(self, args, PyVectorcall_NARGS(nargsf), 0);
    if (ok < 0) return NULL;
    if (!ok) Py_RETURN_NONE;
    Py_INCREF(self->result);
    return self->result;
}

static PyObject *kernel_fresh(PyObject *obj, PyObject *const *args, Py_ssize_t nargs) {
    KernelObject *self = (KernelObject *)obj;
    int ok = run(self, args, nargs, 1);
    if (ok < 0) return NULL;
    if (!ok) Py_RETURN_NONE;
    PyObject *out = PyTuple_New(self->n_kept);
    if (!out) return NULL;
    for (int k = 0, t = 0; k < self->n_out; ++k) {
        if (self->out_kind[k] == OUT_SKIP) continue;
        int type = self->out_kind[k] == OUT_FLAGS ? NPY_BOOL : NPY_DOUBLE;
        PyObject *a = PyArray_SimpleNew(self->out_nd[k], self->out_dims[k], type);
        if (!a) {
            Py_DECREF(out);
            return NULL;
        }
        store(self, k, PyArray_DATA((PyArrayObject *)a));
        PyTuple_SET_ITEM(out, t++, a);
    }
    return out;
}

static PyObject *kernel_into(PyObject *obj, PyObject *const *args, Py_ssize_t nargs) {
    KernelObject *self = (KernelObject *)obj;
    if (nargs < 1 || !PyTuple_Check(args[0]) || PyTuple_GET_SIZE(args[0]) != self->n_kept) {
        PyErr_Format(PyExc_TypeError, "out: expected a tuple of %d arrays", self->n_kept);
        return NULL;
    }
    PyObject *outs = args[0];
    for (int k = 0, t = 0; k < self->n_out; ++k) {
        if (self->out_kind[k] == OUT_SKIP) continue;
        PyObject *a = PyTuple_GET_ITEM(outs, t++);
        int type = self->out_kind[k] == OUT_FLAGS ? NPY_BOOL : NPY_DOUBLE;
        PyArrayObject *arr = (PyArrayObject *)a;
        int fits = PyArray_Check(a) && PyArray_TYPE(arr) == type && PyArray_IS_C_CONTIGUOUS(arr) &&
                   PyArray_ISWRITEABLE(arr) && PyArray_ISALIGNED(arr) && PyArray_NDIM(arr) == self->out_nd[k];
        for (int d = 0; fits && d < self->out_nd[k]; ++d) fits = PyArray_DIMS(arr)[d] == self->out_dims[k][d];
        if (!fits) {
            PyErr_Format(qpik_input_error(), "out[%d]: expected a writeable C-contiguous %s array of the output's shape",
                         t - 1, type == NPY_BOOL ? "bool" : "float64");
            return NULL;
        }
    }
    int ok = run(self, args + 1, nargs - 1, 1);
    if (ok < 0) return NULL;
    if (!ok) Py_RETURN_NONE;
    for (int k = 0, t = 0; k < self->n_out; ++k)
        if (self->out_kind[k] != OUT_SKIP) store(self, k, PyArray_DATA((PyArrayObject *)PyTuple_GET_ITEM(outs, t++)));
    Py_INCREF(outs);
    return outs;
}

/* The data pointer of a float64 C-contiguous array of `size` entries (borrowed), or NULL with an exception. */
static double *buffer_of(PyObject *a, Py_ssize_t size, const char *what) {
    PyArrayObject *arr = (PyArrayObject *)a;
    if (!PyArray_Check(a) || PyArray_TYPE(arr) != NPY_DOUBLE || !PyArray_IS_C_CONTIGUOUS(arr) ||
        PyArray_SIZE(arr) != size) {
        PyErr_Format(PyExc_TypeError, "Kernel: %s must be a float64 C-contiguous array of %zd entries", what, size);
        return NULL;
    }
    return (double *)PyArray_DATA(arr);
}

/* Kernel(address, work, inputs, outputs, result, owner)
 *   address: the generated function's entry point; work: (sz_arg, sz_res, sz_iw, sz_w);
 *   inputs: ((array, rows, cols, kind), ...); outputs: ((array, rows, cols, kind, shape), ...);
 *   result: what a call returns; owner: kept alive with the kernel (the loaded library). */
static PyObject *kernel_new(PyTypeObject *type, PyObject *args, PyObject *kwds) {
    unsigned long long address;
    Py_ssize_t sz_arg, sz_res, sz_iw, sz_w;
    PyObject *inputs, *outputs, *result, *owner;
    if (!PyArg_ParseTuple(args, "K(nnnn)O!O!OO", &address, &sz_arg, &sz_res, &sz_iw, &sz_w, &PyTuple_Type, &inputs,
                          &PyTuple_Type, &outputs, &result, &owner))
        return NULL;
    Py_ssize_t n_in = PyTuple_GET_SIZE(inputs), n_out = PyTuple_GET_SIZE(outputs);
    if (n_in > MAX_IO || n_out > MAX_IO || address == 0) {
        PyErr_SetString(PyExc_ValueError, "Kernel: at most 16 inputs and outputs, and an entry point");
        return NULL;
    }
    KernelObject *self = (KernelObject *)type->tp_alloc(type, 0);
    if (!self) return NULL;
    self->vectorcall = kernel_vectorcall;
    self->fn = (casadi_fn)(uintptr_t)address;
    self->n_in = (int)n_in, self->n_out = (int)n_out;
    Py_ssize_t na = sz_arg > n_in ? sz_arg : n_in, nr = sz_res > n_out ? sz_res : n_out;
    self->arg = PyMem_Calloc((size_t)na, sizeof(double *));
    self->res = PyMem_Calloc((size_t)nr, sizeof(double *));
    self->iw = PyMem_Calloc((size_t)(sz_iw > 0 ? sz_iw : 1), sizeof(casadi_int));
    self->w = PyMem_Calloc((size_t)(sz_w > 0 ? sz_w : 1), sizeof(double));
    self->keep = PyTuple_Pack(3, inputs, outputs, owner);
    Py_INCREF(result);
    self->result = result;
    if (!self->arg || !self->res || !self->iw || !self->w || !self->keep) {
        Py_DECREF(self);
        return PyErr_NoMemory();
    }
    for (Py_ssize_t k = 0; k < n_in; ++k) {
        PyObject *a;
        if (!PyArg_ParseTuple(PyTuple_GET_ITEM(inputs, k), "Onni", &a, &self->in_rows[k], &self->in_cols[k],
                              &self->in_kind[k]) ||
            !(self->in[k] = buffer_of(a, self->in_rows[k] * self->in_cols[k], "an input"))) {
            Py_DECREF(self);
            return NULL;
        }
        self->arg[k] = self->in[k];
    }
    for (Py_ssize_t k = 0; k < n_out; ++k) {
        PyObject *a, *shape;
        if (!PyArg_ParseTuple(PyTuple_GET_ITEM(outputs, k), "OnniO!", &a, &self->out_rows[k], &self->out_cols[k],
                              &self->out_kind[k], &PyTuple_Type, &shape) ||
            !(self->out[k] = buffer_of(a, self->out_rows[k] * self->out_cols[k], "an output"))) {
            Py_DECREF(self);
            return NULL;
        }
        self->res[k] = self->out[k];
        self->out_nd[k] = (int)PyTuple_GET_SIZE(shape);
        npy_intp count = 1;
        for (int d = 0; d < self->out_nd[k] && d < 3; ++d) {
            self->out_dims[k][d] = PyLong_AsSsize_t(PyTuple_GET_ITEM(shape, d));
            count *= self->out_dims[k][d];
        }
        if (self->out_nd[k] > 3 || (self->out_kind[k] != OUT_SKIP && count != self->out_rows[k] * self->out_cols[k])) {
            PyErr_SetString(PyExc_ValueError, "Kernel: an output's shape does not hold its entries");
            Py_DECREF(self);
            return NULL;
        }
        self->n_kept += self->out_kind[k] != OUT_SKIP;
    }
    return (PyObject *)self;
}

static void kernel_dealloc(KernelObject *self) {
    PyMem_Free(self->arg);
    PyMem_Free(self->res);
    PyMem_Free(self->iw);
    PyMem_Free(self->w);
    Py_XDECREF(self->keep);
    Py_XDECREF(self->result);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static PyMethodDef kernel_methods[] = {
    {"fresh", (PyCFunction)(void (*)(void))kernel_fresh, METH_FASTCALL,
     "fresh(*args): checked arguments, new output arrays (None when an argument fails a check)"},
    {"into", (PyCFunction)(void (*)(void))kernel_into, METH_FASTCALL,
     "into(outs, *args): checked arguments, outputs written into the arrays outs (None as fresh)"},
    {NULL, NULL, 0, NULL},
};

static PyTypeObject KernelType = {
    PyVarObject_HEAD_INIT(NULL, 0).tp_name = "qpik_fastcall.Kernel",
    .tp_basicsize = sizeof(KernelObject),
    .tp_flags = Py_TPFLAGS_DEFAULT | Py_TPFLAGS_HAVE_VECTORCALL,
    .tp_doc = "A CasADi-generated function called on numpy buffers (see qpik/fastcall.c).",
    .tp_new = kernel_new,
    .tp_dealloc = (destructor)kernel_dealloc,
    .tp_vectorcall_offset = offsetof(KernelObject, vectorcall),
    .tp_call = PyVectorcall_Call,
    .tp_methods = kernel_methods,
};

static PyObject *set_input_error(PyObject *mod, PyObject *cls) {
    Py_XSETREF(input_error, Py_NewRef(cls));
    Py_RETURN_NONE;
}

/* pose_ok(T): whether T is a float64 (4, 4) C-contiguous array holding a finite pose that
 * qpik.validate.single_pose accepts without projection (False for anything else). */
static PyObject *module_pose_ok(PyObject *mod, PyObject *a) {
    PyArrayObject *arr = (PyArrayObject *)a;
    if (!PyArray_CheckExact(a) || PyArray_TYPE(arr) != NPY_DOUBLE || !PyArray_IS_C_CONTIGUOUS(arr) ||
        !PyArray_ISALIGNED(arr) || PyArray_NDIM(arr) != 2 || PyArray_DIMS(arr)[0] != 4 || PyArray_DIMS(arr)[1] != 4)
        Py_RETURN_FALSE;
    const double *T = (const double *)PyArray_DATA(arr);
    for (int i = 0; i < 16; ++i)
        if (!isfinite(T[i])) Py_RETURN_FALSE;
    return PyBool_FromLong(pose_ok(T));
}

/* vector_ok(q, n): whether q is a float64 1-D C-contiguous array of n finite entries (False for anything else). */
static PyObject *module_vector_ok(PyObject *mod, PyObject *const *args, Py_ssize_t nargs) {
    if (nargs != 2) {
        PyErr_SetString(PyExc_TypeError, "vector_ok(q, n)");
        return NULL;
    }
    PyArrayObject *arr = (PyArrayObject *)args[0];
    Py_ssize_t n = PyLong_AsSsize_t(args[1]);
    if (n == -1 && PyErr_Occurred()) return NULL;
    if (!PyArray_CheckExact(args[0]) || PyArray_TYPE(arr) != NPY_DOUBLE || !PyArray_IS_C_CONTIGUOUS(arr) ||
        !PyArray_ISALIGNED(arr) || PyArray_NDIM(arr) != 1 || PyArray_DIMS(arr)[0] != n)
        Py_RETURN_FALSE;
    const double *q = (const double *)PyArray_DATA(arr);
    for (Py_ssize_t i = 0; i < n; ++i)
        if (!isfinite(q[i])) Py_RETURN_FALSE;
    Py_RETURN_TRUE;
}

/* Array a as a C-contiguous aligned 1-D array of type t with at least n entries, or NULL (TypeError set). */
static void *vector_of(PyObject *a, int t, Py_ssize_t n, const char *what) {
    PyArrayObject *arr = (PyArrayObject *)a;
    if (!PyArray_CheckExact(a) || PyArray_TYPE(arr) != t || !PyArray_IS_C_CONTIGUOUS(arr) || !PyArray_ISALIGNED(arr) ||
        PyArray_NDIM(arr) != 1 || PyArray_DIMS(arr)[0] < n) {
        PyErr_Format(PyExc_TypeError, "circle_lists: %s is not a 1-D array of the expected type and size", what);
        return NULL;
    }
    return PyArray_DATA(arr);
}

/* circle_lists(iv, count, sv, scount, ns): the output of qpik_circle_sets (qpik/analytic/intervals.c) as Python
 * lists, per row r: its count[r] pieces (lo, hi) (pairs one row after the other in iv, float64) and its
 * scount[r] singular values (sv[r * ns ...]); count and scount are C ints, one per row. */
static PyObject *module_circle_lists(PyObject *mod, PyObject *const *args, Py_ssize_t nargs) {
    if (nargs != 5) {
        PyErr_SetString(PyExc_TypeError, "circle_lists(iv, count, sv, scount, ns)");
        return NULL;
    }
    Py_ssize_t ns = PyLong_AsSsize_t(args[4]);
    if (ns == -1 && PyErr_Occurred()) return NULL;
    Py_ssize_t rows = PyArray_Check(args[1]) ? PyArray_SIZE((PyArrayObject *)args[1]) : 0;
    const int *count = vector_of(args[1], NPY_INT, rows, "count");
    const int *scount = count ? vector_of(args[3], NPY_INT, rows, "scount") : NULL;
    if (!scount) return NULL;
    Py_ssize_t pieces = 0;
    for (Py_ssize_t r = 0; r < rows; ++r) {
        if (count[r] < 0 || scount[r] < 0 || scount[r] > ns) {
            PyErr_SetString(PyExc_ValueError, "circle_lists: negative count or scount above ns");
            return NULL;
        }
        pieces += count[r];
    }
    const double *iv = vector_of(args[0], NPY_DOUBLE, 2 * pieces, "iv");
    const double *sv = iv ? vector_of(args[2], NPY_DOUBLE, rows * ns, "sv") : NULL;
    if (!sv) return NULL;
    PyObject *sets = PyList_New(rows), *found = PyList_New(rows);
    if (!sets || !found) goto fail;
    for (Py_ssize_t r = 0; r < rows; ++r) {
        PyObject *set = PyList_New(count[r]), *vals = PyList_New(scount[r]);
        if (set) PyList_SET_ITEM(sets, r, set);
        if (vals) PyList_SET_ITEM(found, r, vals);
        if (!set || !vals) goto fail;
        for (int i = 0; i < count[r]; ++i, iv += 2) {
            PyObject *piece = PyTuple_New(2), *a = PyFloat_FromDouble(iv[0]), *b = PyFloat_FromDouble(iv[1]);
            if (piece) PyList_SET_ITEM(set, i, piece);
            if (piece && a) PyTuple_SET_ITEM(piece, 0, a);
            if (piece && b) PyTuple_SET_ITEM(piece, 1, b);
            if (!piece || !a || !b) {
                if (!piece) Py_XDECREF(a), Py_XDECREF(b);
                goto fail;
            }
            PyObject_GC_UnTrack(piece); /* a pair of floats holds no reference cycle: the collector skips it */
        }
        for (int i = 0; i < scount[r]; ++i) {
            PyObject *x = PyFloat_FromDouble(sv[r * ns + i]);
            if (!x) goto fail;
            PyList_SET_ITEM(vals, i, x);
        }
    }
    return Py_BuildValue("(NN)", sets, found);
fail:
    Py_XDECREF(sets), Py_XDECREF(found);
    return NULL;
}

/* Whether a is a float64 array in native byte order, C-contiguous and aligned (and writeable if asked). */
static int plain_doubles(PyObject *a, int writeable) {
    PyArrayObject *arr = (PyArrayObject *)a;
    return PyArray_Check(a) && PyArray_TYPE(arr) == NPY_DOUBLE && PyArray_ISCARRAY_RO(arr) &&
           PyArray_ISNOTSWAPPED(arr) && (!writeable || PyArray_ISWRITEABLE(arr));
}

/* x written into the numpy array view as `view[...] = x`: a float (numpy's float64 too) into a float64 view of one
 * entry, and a float64 array of the view's shape, in C; anything else by the view's own assignment (numpy's
 * conversions, broadcasting and errors). 0, or -1 with the exception set. */
static int write_into(PyObject *view, PyObject *x) {
    if (plain_doubles(view, 1)) {
        PyArrayObject *v = (PyArrayObject *)view;
        if (PyFloat_Check(x) && PyArray_SIZE(v) == 1) {
            *(double *)PyArray_DATA(v) = PyFloat_AS_DOUBLE(x);
            return 0;
        }
        PyArrayObject *a = (PyArrayObject *)x;
        if (plain_doubles(x, 0) && PyArray_NDIM(a) == PyArray_NDIM(v) &&
            PyArray_CompareLists(PyArray_DIMS(a), PyArray_DIMS(v), PyArray_NDIM(v))) {
            memmove(PyArray_DATA(v), PyArray_DATA(a), sizeof(double) * (size_t)PyArray_SIZE(v));
            return 0;
        }
    }
    return PyObject_SetItem(view, Py_Ellipsis, x);
}

/* scatter(parts, names, views): view[...] = parts[name] for each name of the tuple names and view of the tuple
 * views (write_into), parts a dict or another mapping; a name missing from parts is a KeyError. Returns None. */
static PyObject *module_scatter(PyObject *mod, PyObject *const *args, Py_ssize_t nargs) {
    if (nargs != 3 || !PyTuple_Check(args[1]) || !PyTuple_Check(args[2]) ||
        PyTuple_GET_SIZE(args[1]) != PyTuple_GET_SIZE(args[2])) {
        PyErr_SetString(PyExc_TypeError, "scatter(parts, names, views): names and views tuples of one length");
        return NULL;
    }
    PyObject *parts = args[0];
    int dict = PyDict_CheckExact(parts);
    for (Py_ssize_t i = 0; i < PyTuple_GET_SIZE(args[1]); ++i) {
        PyObject *name = PyTuple_GET_ITEM(args[1], i), *x;
        if (dict) {
            x = PyDict_GetItemWithError(parts, name);
            if (!x && !PyErr_Occurred()) PyErr_SetObject(PyExc_KeyError, name);
            Py_XINCREF(x);
        } else {
            x = PyObject_GetItem(parts, name);
        }
        if (!x) return NULL;
        int failed = write_into(PyTuple_GET_ITEM(args[2], i), x);
        Py_DECREF(x);
        if (failed) return NULL;
    }
    Py_RETURN_NONE;
}

static PyMethodDef module_methods[] = {
    {"scatter", (PyCFunction)(void (*)(void))module_scatter, METH_FASTCALL,
     "scatter(parts, names, views): view[...] = parts[name] for each name and view."},
    {"circle_lists", (PyCFunction)(void (*)(void))module_circle_lists, METH_FASTCALL,
     "The feasible sets and singular values of qpik_circle_sets as lists, per row."},
    {"vector_ok", (PyCFunction)(void (*)(void))module_vector_ok, METH_FASTCALL,
     "Whether q is a float64 1-D array of n finite entries."},
    {"pose_ok", module_pose_ok, METH_O, "Whether a float64 (4, 4) array is a finite pose with an orthonormal rotation."},
    {"set_input_error", set_input_error, METH_O, "The exception class of bad arguments (qpik.errors.InputError)."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "qpik_fastcall", NULL, -1, module_methods};

PyMODINIT_FUNC PyInit_qpik_fastcall(void) {
    import_array();
    if (PyType_Ready(&KernelType) < 0) return NULL;
    PyObject *m = PyModule_Create(&module);
    if (!m) return NULL;
    Py_INCREF(&KernelType);
    if (PyModule_AddObject(m, "Kernel", (PyObject *)&KernelType) < 0) {
        Py_DECREF(&KernelType);
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
