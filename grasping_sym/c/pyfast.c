/*
 * grasping_sym fast path: a minimal CPython extension module (`_gs_fast`)
 * wrapping the gs_ driver functions of driver.c, compiled into the same shared
 * library.  It exists because a ctypes call plus NumPy allocation costs a few
 * microseconds, while a METH_FASTCALL function costs a few hundred nanoseconds.
 *
 * Needs the same -D macros as driver.c (the work sizes), reads the model's sizes and features (gs_nx, gs_np,
 * gs_ny, gs_driver.h) at run time, and needs the include directories of Python.h and numpy/arrayobject.h.  The module
 * uses multi-phase initialisation, so a rebuilt library loaded from the same
 * path is never served from CPython's single-phase extension cache.
 *
 * Module functions (x: shape (nx,), X: shape (n, nx), p: shape (np,) or None
 * when np == 0; anything array-like is converted to contiguous float64):
 *   rhs(x, p=None)            -> ndarray (nx,)
 *   rhs_batch(X, p=None)      -> ndarray (n, nx)
 *   outputs(x, p=None)        -> ndarray (ny,)      (only with outputs)
 *   outputs_batch(X, p=None)  -> ndarray (n, ny)    (only with outputs)
 *   adaptive(method, t_out, x0, p, rtol, atol, h0, max_steps, nstiff, lo, hi, mask,
 *            proj_tol, out, stats) -> (rc, t_fail)
 *       gs_radau5 (method 0), gs_dopri5 (method 1) or gs_dop853 (2) with the GIL released; the
 *       low-level call behind CompiledLibrary.radau5 / dopri5, which validate the
 *       arguments and turn rc into results or errors.  Arrays are not converted:
 *       t_out, x0, p, lo, hi float64 C-contiguous 1-D (p, lo, hi, mask may be None),
 *       mask int32, out a writeable float64 C-contiguous (len(t_out) + 1, nx) array
 *       and stats a writeable float64 array of GS_NSTATS entries; a wrong type or
 *       shape raises TypeError / ValueError.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>

#include "gs_driver.h"

#define GS_FAST_FLAGS (NPY_ARRAY_C_CONTIGUOUS | NPY_ARRAY_ALIGNED)

/* Return a new reference to a C-contiguous float64 ndarray view/copy of obj,
 * or NULL with an exception set. */
static PyArrayObject* as_f64(PyObject* obj) {
  if (PyArray_CheckExact(obj)) {
    PyArrayObject* a = (PyArrayObject*)obj;
    if (PyArray_TYPE(a) == NPY_DOUBLE && PyArray_CHKFLAGS(a, GS_FAST_FLAGS) &&
        PyArray_ISNOTSWAPPED(a)) {
      Py_INCREF(obj);
      return a;
    }
  }
  return (PyArrayObject*)PyArray_FROMANY(obj, NPY_DOUBLE, 0, 0, NPY_ARRAY_IN_ARRAY);
}

static PyObject* shape_str(PyArrayObject* a) {
  PyObject* shape = PyTuple_New(PyArray_NDIM(a));
  if (!shape) return NULL;
  for (int i = 0; i < PyArray_NDIM(a); ++i)
    PyTuple_SET_ITEM(shape, i, PyLong_FromSsize_t(PyArray_DIM(a, i)));
  PyObject* s = PyObject_Repr(shape);
  Py_DECREF(shape);
  return s;
}

/* expected: a shape, with %d for the model's size n (read at run time, gs_driver.h). */
static void shape_error(const char* name, const char* expected_fmt, int n, PyArrayObject* a) {
  char expected[96];
  snprintf(expected, sizeof expected, expected_fmt, n);
  PyObject* got = shape_str(a);
  if (!got) return;
  PyErr_Format(PyExc_ValueError, "%s must have shape %s, got shape %U", name, expected, got);
  Py_DECREF(got);
}

/* Collect (x, p) from vectorcall arguments: x positional or keyword `xname`,
 * p positional or keyword "p" (default None).  Returns 0 or -1 with an exception. */
static int get_args(const char* fname, const char* xname, PyObject* const* args,
                    Py_ssize_t nargs, PyObject* kwnames, PyObject** x, PyObject** p) {
  *x = nargs > 0 ? args[0] : NULL;
  *p = nargs > 1 ? args[1] : NULL;
  if (nargs > 2) goto bad;
  if (kwnames) {
    Py_ssize_t nkw = PyTuple_GET_SIZE(kwnames);
    for (Py_ssize_t i = 0; i < nkw; ++i) {
      PyObject* key = PyTuple_GET_ITEM(kwnames, i);
      PyObject** slot;
      if (PyUnicode_CompareWithASCIIString(key, "p") == 0) slot = p;
      else if (PyUnicode_CompareWithASCIIString(key, xname) == 0) slot = x;
      else {
        PyErr_Format(PyExc_TypeError, "%s() got an unexpected keyword argument %R", fname, key);
        return -1;
      }
      if (*slot) {
        PyErr_Format(PyExc_TypeError, "%s() got multiple values for argument %R", fname, key);
        return -1;
      }
      *slot = args[nargs + i];
    }
  }
  if (!*x) goto bad;
  if (!*p) *p = Py_None;
  return 0;
bad:
  PyErr_Format(PyExc_TypeError, "%s() takes arguments (%s, p=None)", fname, xname);
  return -1;
}

/* Parse p: returns 0 and sets *pa (new ref or NULL) and *pp, or -1 on error. */
static int parse_p(PyObject* obj, PyArrayObject** pa, const double** pp) {
  *pa = NULL;
  *pp = NULL;
  if (obj == Py_None) {
    if (gs_np == 0) return 0;
    PyErr_Format(PyExc_ValueError, "this model has np = %d parameters: pass p of shape (%d,)",
                 gs_np, gs_np);
    return -1;
  }
  PyArrayObject* a = as_f64(obj);
  if (!a) return -1;
  if (PyArray_NDIM(a) != 1 || PyArray_DIM(a, 0) != gs_np) {
    shape_error("p", "(%d,)", gs_np, a);
    Py_DECREF(a);
    return -1;
  }
  *pa = a;
  *pp = gs_np ? (const double*)PyArray_DATA(a) : NULL;
  return 0;
}

typedef int (*single_fn)(const double*, const double*, double*);
typedef int (*batch_fn)(long, const double*, const double*, double*);

static PyObject* call_single(const char* fname, single_fn fn, npy_intp nout,
                             PyObject* const* args, Py_ssize_t nargs, PyObject* kwnames) {
  PyObject *xo, *po;
  if (get_args(fname, "x", args, nargs, kwnames, &xo, &po)) return NULL;
  PyArrayObject* x = as_f64(xo);
  if (!x) return NULL;
  PyArrayObject* p = NULL;
  const double* pp = NULL;
  PyObject* out = NULL;
  if (PyArray_NDIM(x) != 1 || PyArray_DIM(x, 0) != gs_nx) {
    shape_error("x", "(%d,)", gs_nx, x);
    goto done;
  }
  if (parse_p(po, &p, &pp)) goto done;
  out = PyArray_SimpleNew(1, &nout, NPY_DOUBLE);
  if (!out) goto done;
  if (fn((const double*)PyArray_DATA(x), pp, (double*)PyArray_DATA((PyArrayObject*)out))) {
    Py_CLEAR(out);
    PyErr_Format(PyExc_RuntimeError, "%s: the CasADi function reported an evaluation error", fname);
  }
done:
  Py_DECREF(x);
  Py_XDECREF(p);
  return out;
}

static PyObject* call_batch(const char* fname, batch_fn fn, npy_intp nout,
                            PyObject* const* args, Py_ssize_t nargs, PyObject* kwnames) {
  PyObject *xo, *po;
  if (get_args(fname, "X", args, nargs, kwnames, &xo, &po)) return NULL;
  PyArrayObject* X = as_f64(xo);
  if (!X) return NULL;
  PyArrayObject* p = NULL;
  const double* pp = NULL;
  PyObject* out = NULL;
  if (PyArray_NDIM(X) != 2 || PyArray_DIM(X, 1) != gs_nx) {
    shape_error("X", "(n, %d)", gs_nx, X);
    goto done;
  }
  if (parse_p(po, &p, &pp)) goto done;
  npy_intp dims[2] = {PyArray_DIM(X, 0), nout};
  out = PyArray_SimpleNew(2, dims, NPY_DOUBLE);
  if (!out) goto done;
  int rc;
  Py_BEGIN_ALLOW_THREADS
  rc = fn((long)dims[0], (const double*)PyArray_DATA(X), pp,
          (double*)PyArray_DATA((PyArrayObject*)out));
  Py_END_ALLOW_THREADS
  if (rc) {
    Py_CLEAR(out);
    PyErr_Format(PyExc_RuntimeError, "%s: the CasADi function reported an evaluation error", fname);
  }
done:
  Py_DECREF(X);
  Py_XDECREF(p);
  return out;
}

static PyObject* py_rhs(PyObject* self, PyObject* const* args, Py_ssize_t nargs,
                        PyObject* kwnames) {
  (void)self;
  return call_single("rhs", gs_rhs, gs_nx, args, nargs, kwnames);
}

static PyObject* py_rhs_batch(PyObject* self, PyObject* const* args, Py_ssize_t nargs,
                        PyObject* kwnames) {
  (void)self;
  return call_batch("rhs_batch", gs_rhs_batch, gs_nx, args, nargs, kwnames);
}

static PyObject* py_outputs(PyObject* self, PyObject* const* args, Py_ssize_t nargs,
                        PyObject* kwnames) {
  (void)self;
  return call_single("outputs", gs_outputs, gs_ny, args, nargs, kwnames);
}

static PyObject* py_outputs_batch(PyObject* self, PyObject* const* args, Py_ssize_t nargs,
                        PyObject* kwnames) {
  (void)self;
  return call_batch("outputs_batch", gs_outputs_batch, gs_ny, args, nargs, kwnames);
}

/* The array argument `name` of adaptive(): NULL with an exception unless it is an ndarray of
 * `type`, C-contiguous and aligned (writeable if `write`), with ndim 1 and n entries
 * (n < 0: any), or ndim 2 and shape (n, nx) when ndim2 (n < 0: at least -n rows).
 * None gives *ptr = NULL when `optional`. */
static int array_arg(PyObject* obj, const char* name, int type, int ndim2, npy_intp n,
                     int write, int optional, void** ptr) {
  *ptr = NULL;
  if (obj == Py_None && optional) return 0;
  if (!PyArray_Check(obj)) {
    PyErr_Format(PyExc_TypeError, "adaptive(): %s must be a numpy array, got %R", name,
                 (PyObject*)Py_TYPE(obj));
    return -1;
  }
  PyArrayObject* a = (PyArrayObject*)obj;
  const int flags = GS_FAST_FLAGS | (write ? NPY_ARRAY_WRITEABLE : 0);
  if (PyArray_TYPE(a) != type || !PyArray_CHKFLAGS(a, flags) || !PyArray_ISNOTSWAPPED(a)) {
    PyErr_Format(PyExc_TypeError, "adaptive(): %s must be a C-contiguous%s %s array", name,
                 write ? ", writeable" : "", type == NPY_DOUBLE ? "float64" : "int32");
    return -1;
  }
  int ok;
  if (ndim2)
    ok = PyArray_NDIM(a) == 2 && PyArray_DIM(a, 1) == gs_nx &&
         (n >= 0 ? PyArray_DIM(a, 0) == n : PyArray_DIM(a, 0) >= -n);
  else
    ok = PyArray_NDIM(a) == 1 && (n < 0 || PyArray_DIM(a, 0) == n);
  if (!ok) {
    shape_error(name, ndim2 ? "(rows, %d) with enough rows" : "(n,) of the model's size", gs_nx,
                a);
    return -1;
  }
  *ptr = PyArray_DATA(a);
  return 0;
}

static PyObject* py_adaptive(PyObject* self, PyObject* const* args, Py_ssize_t nargs) {
  (void)self;
  if (nargs != 15) {
    PyErr_Format(PyExc_TypeError, "adaptive() takes 15 positional arguments (%zd given)", nargs);
    return NULL;
  }
  const long method = PyLong_AsLong(args[0]);
  const double rtol = PyFloat_AsDouble(args[4]), atol = PyFloat_AsDouble(args[5]);
  const double h0 = PyFloat_AsDouble(args[6]);
  const long max_steps = PyLong_AsLong(args[7]), nstiff = PyLong_AsLong(args[8]);
  const double proj_tol = PyFloat_AsDouble(args[12]);
  if (PyErr_Occurred()) return NULL;
  if (method < 0 || method > 2) {
    PyErr_Format(PyExc_ValueError,
                 "adaptive(): method must be 0 (radau5), 1 (dopri5) or 2 (dop853), got %ld", method);
    return NULL;
  }
  void *t_out, *x0, *p, *lo, *hi, *mask, *out, *stats;
  if (array_arg(args[1], "t_out", NPY_DOUBLE, 0, -1, 0, 0, &t_out)) return NULL;
  const npy_intp m = PyArray_DIM((PyArrayObject*)args[1], 0);
  if (m < 2) {
    PyErr_SetString(PyExc_ValueError, "adaptive(): t_out needs at least two times");
    return NULL;
  }
  if (array_arg(args[2], "x0", NPY_DOUBLE, 0, gs_nx, 0, 0, &x0) ||
      array_arg(args[3], "p", NPY_DOUBLE, 0, gs_np, 0, gs_np == 0, &p) ||
      array_arg(args[9], "lo", NPY_DOUBLE, 0, gs_nx, 0, 1, &lo) ||
      array_arg(args[10], "hi", NPY_DOUBLE, 0, gs_nx, 0, 1, &hi) ||
      array_arg(args[11], "mask", NPY_INT32, 0, gs_nx, 0, 1, &mask) ||
      array_arg(args[13], "out", NPY_DOUBLE, 1, -(m + 1), 1, 0, &out) ||
      array_arg(args[14], "stats", NPY_DOUBLE, 0, GS_NSTATS, 1, 0, &stats))
    return NULL;
  double t_fail = NAN;
  const double* t = (const double*)t_out;
  long rc;
  Py_BEGIN_ALLOW_THREADS
  if (method == 0)
    rc = gs_radau5(t[0], (long)m, t, (const double*)x0, (const double*)p, rtol, atol, h0,
                   max_steps, (const double*)lo, (const double*)hi, (const int*)mask, proj_tol,
                   (double*)out, (double*)stats, &t_fail);
  else if (method == 1)
    rc = gs_dopri5(t[0], (long)m, t, (const double*)x0, (const double*)p, rtol, atol, h0,
                   max_steps, nstiff, (const double*)lo, (const double*)hi, (const int*)mask,
                   proj_tol, (double*)out, (double*)stats, &t_fail);
  else
    rc = gs_dop853(t[0], (long)m, t, (const double*)x0, (const double*)p, rtol, atol, h0,
                   max_steps, nstiff, (const double*)lo, (const double*)hi, (const int*)mask,
                   proj_tol, (double*)out, (double*)stats, &t_fail);
  Py_END_ALLOW_THREADS
  return Py_BuildValue("(ld)", rc, t_fail);
}

static PyMethodDef gs_methods[] = {
    {"adaptive", (PyCFunction)(void (*)(void))py_adaptive, METH_FASTCALL,
     "adaptive(method, t_out, x0, p, rtol, atol, h0, max_steps, nstiff, lo, hi, mask, "
     "proj_tol, out, stats) -> (rc, t_fail): gs_radau5 (0) / gs_dopri5 (1) / gs_dop853 (2), "
     "arrays as-is"},
    {"rhs", (PyCFunction)(void (*)(void))py_rhs, METH_FASTCALL | METH_KEYWORDS,
     "rhs(x, p=None) -> xdot, shape (nx,)"},
    {"rhs_batch", (PyCFunction)(void (*)(void))py_rhs_batch, METH_FASTCALL | METH_KEYWORDS,
     "rhs_batch(X, p=None) -> XDOT, shape (n, nx)"},
    {"outputs", (PyCFunction)(void (*)(void))py_outputs, METH_FASTCALL | METH_KEYWORDS,
     "outputs(x, p=None) -> y, shape (ny,)"},
    {"outputs_batch", (PyCFunction)(void (*)(void))py_outputs_batch, METH_FASTCALL | METH_KEYWORDS,
     "outputs_batch(X, p=None) -> Y, shape (n, ny)"},
    {NULL, NULL, 0, NULL}};

static int gs_exec(PyObject* m) {
  if (_import_array() < 0) return -1;
  if (PyModule_AddIntConstant(m, "nx", gs_nx) < 0) return -1;
  if (PyModule_AddIntConstant(m, "np", gs_np) < 0) return -1;
  if (PyModule_AddIntConstant(m, "ny", gs_has_out ? gs_ny : -1) < 0) return -1;
  /* a model without outputs (the link file's gs_has_out) has no outputs functions */
  if (!gs_has_out && (PyObject_DelAttrString(m, "outputs") < 0 ||
                      PyObject_DelAttrString(m, "outputs_batch") < 0))
    return -1;
  return 0;
}

static PyModuleDef_Slot gs_slots[] = {{Py_mod_exec, (void*)gs_exec}, {0, NULL}};

static struct PyModuleDef gs_module = {
    PyModuleDef_HEAD_INIT, "_gs_fast", "grasping_sym compiled-model fast path", 0,
    gs_methods, gs_slots, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__gs_fast(void) { return PyModuleDef_Init(&gs_module); }
