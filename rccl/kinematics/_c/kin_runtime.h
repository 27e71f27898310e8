/* The shared runtime of the generated kinematics extensions (rccl/kinematics/_c/<robot>.c),
 * hand-written: the Python-callable entry of every kernel (shape and NaN checks, results
 * allocated through numpy, batches in chunks and over threads), the public fast entries
 * behind rccl.kinematics.backend.public (single configurations and batches, out=, gravity
 * coefficient mappings, ik / ik_all / config_of with the pose checks; a redundant arm's in
 * kin_redundant.h), and the module's
 * init, which adds one function per entry of KERNELS. A generated file includes it after
 * its kernels and their table KERNELS, and ends with RCCL_MODULE_INIT(<robot>). setup.py
 * defines RCCL_SOURCE_HASH (rccl.kinematics.backend.source_hash of the .c and both
 * headers) for the staleness check. */
#ifndef RCCL_KIN_RUNTIME_H
#define RCCL_KIN_RUNTIME_H

#ifndef RCCL_SOURCE_HASH
#define RCCL_SOURCE_HASH ""   /* built outside setup.py: the loader treats it as stale */
#endif
#define NKERNELS ((int)(sizeof KERNELS / sizeof KERNELS[0]))

static PyObject *call_kernel(const kernel_entry *k, PyObject *const *args, Py_ssize_t nargs);

/* One Python function per kernel, made at import from KERNELS: the entry's self is a
 * capsule holding the kernel's table row. */
static PyObject *kernel_capsule[NKERNELS];
static PyMethodDef kernel_def[NKERNELS];

static const kernel_entry *entry_of(PyObject *capsule)
{
    return (const kernel_entry *)PyCapsule_GetPointer(capsule, NULL);
}

static PyObject *py_kernel(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    return call_kernel(entry_of(self), args, nargs);
}

static PyObject *np_empty = NULL;         /* numpy.empty, to allocate results */
static PyObject *np_array = NULL;         /* numpy.array, to convert lists and other dtypes */
static PyObject *np_array_kw = NULL;      /* {"dtype": "float64", "order": "C"} */
/* ---------------------------------------------------------------- batched rows
 * Every batched call runs its rows in chunks of CHUNK: inputs of the chunk scanned for
 * NaN/inf, the kernel's batched loop, then (public entries) its guards and first output
 * checked while they are still in cache (the output only when it is not finite by
 * construction: kernel_entry.finite_out). Large batches are split over threads (pthreads;
 * RCCL_KINEMATICS_THREADS, default the online CPUs, at most MAX_THREADS). */
#define CHUNK 32
#define MAX_THREADS 8
#define ROWS_PER_THREAD 16384
#if defined(__unix__) || defined(__APPLE__)
#define RCCL_THREADS 1
#include <pthread.h>
#include <unistd.h>
#endif
static int n_threads = 1;

typedef struct {
    const kernel_entry *k;
    Py_ssize_t r0, r1;
    const double *ip[MAXIO];
    Py_ssize_t is[MAXIO];
    double *op[MAXIO];          /* NULL: a guard, written to per-chunk scratch */
    Py_ssize_t os[MAXIO];
    int check;                  /* scan inputs, guards (>= 0) and the first output (finite) */
    int bad;                    /* a check failed */
} row_job;

/* 1 when no element is NaN or inf: x - x is 0 for every finite x and NaN otherwise;
 * two lanes at a time with SSE2 (every x86-64), so the check costs little beside a row */
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
/* four lanes with AVX where the CPU has it (checked at import) */
__attribute__((target("avx"))) static int all_finite_avx(const double *v, Py_ssize_t len)
{
    __m256d bad = _mm256_setzero_pd();
    Py_ssize_t j = 0;
    for (; j + 8 <= len; j += 8) {
        const __m256d a = _mm256_loadu_pd(v + j), b = _mm256_loadu_pd(v + j + 4);
        const __m256d da = _mm256_sub_pd(a, a), db = _mm256_sub_pd(b, b);
        bad = _mm256_or_pd(bad, _mm256_or_pd(_mm256_cmp_pd(da, da, _CMP_UNORD_Q), _mm256_cmp_pd(db, db, _CMP_UNORD_Q)));
    }
    int ok = _mm256_movemask_pd(bad) == 0;
    for (const double *e = v + len, *x = v + j; x < e; ++x) ok &= isfinite(*x) != 0;
    return ok;
}
static int have_avx = 0;
#define FINITE_AVX(v, len) if (have_avx && (len) >= 16) return all_finite_avx(v, len)
#else
#define FINITE_AVX(v, len)
#endif
#if defined(__SSE2__)
#include <emmintrin.h>
static int all_finite(const double *v, Py_ssize_t len)
{
    FINITE_AVX(v, len);
    __m128d bad = _mm_setzero_pd();
    Py_ssize_t j = 0;
    for (; j + 4 <= len; j += 4) {
        const __m128d a = _mm_loadu_pd(v + j), b = _mm_loadu_pd(v + j + 2);
        const __m128d da = _mm_sub_pd(a, a), db = _mm_sub_pd(b, b);
        bad = _mm_or_pd(bad, _mm_or_pd(_mm_cmpunord_pd(da, da), _mm_cmpunord_pd(db, db)));
    }
    int ok = _mm_movemask_pd(bad) == 0;
    for (const double *e = v + len, *x = v + j; x < e; ++x) ok &= isfinite(*x) != 0;
    return ok;
}
#else
static int all_finite(const double *v, Py_ssize_t len)
{
    int ok = 1;
    for (Py_ssize_t j = 0; j < len; ++j) ok &= isfinite(v[j]) != 0;
    return ok;
}
#endif

static void run_job(row_job *j)
{
    const kernel_entry *k = j->k;
    double scratch[MAXIO][CHUNK];
    const double *ic[MAXIO];
    double *oc[MAXIO];
    Py_ssize_t osc[MAXIO];
    for (Py_ssize_t r = j->r0; r < j->r1; r += CHUNK) {
        const Py_ssize_t m = j->r1 - r < CHUNK ? j->r1 - r : CHUNK;
        for (int i = 0; i < k->nin; ++i) {
            ic[i] = j->ip[i] + r * j->is[i];
            if (j->check && j->is[i] && !all_finite(ic[i], m * j->is[i])) { j->bad = 1; return; }
        }
        for (int o = 0; o < k->nout; ++o) {
            if (j->op[o]) { oc[o] = j->op[o] + r * j->os[o]; osc[o] = j->os[o]; }
            else { oc[o] = scratch[o]; osc[o] = 1; }
        }
        /* the next chunk's inputs fetched while this one is computed: at 1e6 rows the input
         * scan above otherwise waits on memory (puma260 force_from_torque6: 11.7 -> 9.0 ns a
         * row, two threads) */
        if (r + CHUNK < j->r1)
            for (int i = 0; i < k->nin; ++i) {
                const char *a = (const char *)(ic[i] + CHUNK * j->is[i]);
                const Py_ssize_t len = (j->r1 - r - CHUNK < CHUNK ? j->r1 - r - CHUNK : CHUNK) * j->is[i] * 8;
                for (Py_ssize_t b = 0; b < len; b += 64) __builtin_prefetch(a + b, 0);
            }
        k->fn(m, ic, j->is, oc, osc);
        if (j->check) {
            for (int g = k->nout - k->nguard; g < k->nout; ++g)
                for (Py_ssize_t t = 0; t < m; ++t)
                    if (!(oc[g][t * osc[g]] >= 0)) { j->bad = 1; return; }
            if (!k->finite_out && !all_finite(oc[0], m * osc[0])) { j->bad = 1; return; }
        }
    }
}

#ifdef RCCL_THREADS
static void *job_thread(void *arg) { run_job((row_job *)arg); return NULL; }
#endif

/* n rows of kernel k, split over up to n_threads threads; returns nonzero when a check
 * failed (check = 1 only). Safe without the GIL: touches no Python object. */
static int run_rows(const kernel_entry *k, Py_ssize_t n, const double *const *ip, const Py_ssize_t *is,
                    double *const *op, const Py_ssize_t *os, int check)
{
    row_job jobs[MAX_THREADS];
    int t = 1;
#ifdef RCCL_THREADS
    t = n_threads;
    if (n / ROWS_PER_THREAD < t) t = (int)(n / ROWS_PER_THREAD);
    if (t < 1) t = 1;
#endif
    for (int w = 0; w < t; ++w) {
        row_job *j = &jobs[w];
        j->k = k; j->check = check; j->bad = 0;
        j->r0 = n * w / t; j->r1 = n * (w + 1) / t;
        for (int i = 0; i < k->nin; ++i) { j->ip[i] = ip[i]; j->is[i] = is[i]; }
        for (int o = 0; o < k->nout; ++o) { j->op[o] = op[o]; j->os[o] = os[o]; }
    }
    if (t == 1) { run_job(&jobs[0]); return jobs[0].bad; }
    int bad = 0;
#ifdef RCCL_THREADS
    pthread_t th[MAX_THREADS];
    int started[MAX_THREADS] = {0};
    for (int w = 1; w < t; ++w) started[w] = pthread_create(&th[w], NULL, job_thread, &jobs[w]) == 0;
    run_job(&jobs[0]);
    bad = jobs[0].bad;
    for (int w = 1; w < t; ++w) {
        if (started[w]) pthread_join(th[w], NULL);
        else run_job(&jobs[w]);       /* no thread to be had: run it here */
        bad |= jobs[w].bad;
    }
#endif
    return bad;
}

static void init_threads(void)
{
    long c = 1;
#ifdef RCCL_THREADS
    const char *env = getenv("RCCL_KINEMATICS_THREADS");
    c = (env && *env) ? strtol(env, NULL, 10) : sysconf(_SC_NPROCESSORS_ONLN);
#endif
    n_threads = c < 1 ? 1 : c > MAX_THREADS ? MAX_THREADS : (int)c;
#if defined(__x86_64__) && defined(__GNUC__)
    __builtin_cpu_init();
    have_avx = __builtin_cpu_supports("avx");
#endif
}

#ifdef RCCL_NUMPY_API
/* ---------------------------------------------------------------- public fast entries
 * The public functions of the generated module (rccl.kinematics.backend.public) are these
 * entries: when every argument is already in the form the C can take directly (float64
 * C-contiguous numpy arrays of the kernel's shape, one configuration or a batch along a
 * leading axis; gravity coefficients also as a mapping of floats; a valid pose; a Config)
 * and every check passes (finite inputs, guards >= 0, finite results), they return the
 * result. Anything else goes to `fallback`, the Python runtime, which gives the contract's
 * conversions, messages and exceptions: no error behaviour is lost. With out= the result
 * is written there; a call that then falls back may have written part of it. */

static PyObject *str_value = NULL, *str_gravity_coeffs = NULL;   /* interned attribute names */

/* a numpy array the entries can read in place: exact ndarray, float64, C-contiguous, aligned */
static PyArrayObject *plain_array(PyObject *x)
{
    if (!PyArray_CheckExact(x)) return NULL;
    PyArrayObject *a = (PyArrayObject *)x;
    if (PyArray_TYPE(a) != NPY_DOUBLE || !PyArray_CHKFLAGS(a, NPY_ARRAY_C_CONTIGUOUS | NPY_ARRAY_ALIGNED)) return NULL;
    return a;
}

/* coefficient values by name from a dict, a mappingproxy or a record with gravity_coeffs;
 * each a float or int, or a record with a float `.value` (rci.robot_model.Value).
 * 0 on success; -1 (no exception set) when the Python path must decide. */
static int mapping_values(PyObject *x, PyObject *keys, double *v)
{
    PyObject *m = x, *owned = NULL;
    if (!PyDict_Check(m) && !PyObject_TypeCheck(m, &PyDictProxy_Type)) {
        owned = PyObject_GetAttr(m, str_gravity_coeffs);
        if (!owned) { PyErr_Clear(); return -1; }
        m = owned;
        if (!PyDict_Check(m) && !PyObject_TypeCheck(m, &PyDictProxy_Type)) { Py_DECREF(owned); return -1; }
    }
    int rc = 0;
    for (Py_ssize_t i = 0; rc == 0 && i < PyTuple_GET_SIZE(keys); ++i) {
        PyObject *key = PyTuple_GET_ITEM(keys, i), *item;
        if (PyDict_Check(m)) { item = PyDict_GetItemWithError(m, key); Py_XINCREF(item); }
        else item = PyObject_GetItem(m, key);
        if (!item) { PyErr_Clear(); rc = -1; break; }
        double d = NAN;
        if (PyFloat_Check(item)) d = PyFloat_AS_DOUBLE(item);
        else if (PyLong_CheckExact(item)) { d = PyLong_AsDouble(item); if (PyErr_Occurred()) { PyErr_Clear(); d = NAN; } }
        else {
            PyObject *val = PyObject_GetAttr(item, str_value);
            if (!val) PyErr_Clear();
            else if (PyFloat_Check(val)) d = PyFloat_AS_DOUBLE(val);
            Py_XDECREF(val);
        }
        Py_DECREF(item);
        if (!isfinite(d)) rc = -1;
        else v[i] = d;
    }
    Py_XDECREF(owned);
    return rc;
}

/* the keyword `out` (or none); -1 for any other keyword */
static int out_keyword(PyObject *kwnames, PyObject *const *args, Py_ssize_t nargs, PyObject **out)
{
    *out = NULL;
    if (!kwnames) return 0;
    if (PyTuple_GET_SIZE(kwnames) != 1 || PyUnicode_CompareWithASCIIString(PyTuple_GET_ITEM(kwnames, 0), "out") != 0)
        return -1;
    if (args[nargs] != Py_None) *out = args[nargs];
    return 0;
}

static int overlaps(const void *a, Py_ssize_t na, const void *b, Py_ssize_t nb)
{
    const char *pa = (const char *)a, *pb = (const char *)b;
    return pa < pb + nb && pb < pa + na;
}

/* the public entry of a kernel: self = (fallback, coefficient names or None, kernel capsule) */
static PyObject *public_call(PyObject *self, PyObject *const *args, Py_ssize_t nargs, PyObject *kwnames)
{
    PyObject *fallback = PyTuple_GET_ITEM(self, 0), *keys = PyTuple_GET_ITEM(self, 1);
    const kernel_entry *k = entry_of(PyTuple_GET_ITEM(self, 2));
    const double *ip[MAXIO];
    double *op[MAXIO];
    Py_ssize_t is[MAXIO], os[MAXIO], ilen[MAXIO];
    double guard[MAXIO], coeffs[64];
    PyObject *out, *res;
    Py_ssize_t n = -1;
    if (nargs != k->nin || k->nout - k->nguard != 1 || out_keyword(kwnames, args, nargs, &out) < 0) goto slow;
    for (int i = 0; i < k->nin; ++i) {
        const arg_shape *s = &k->in[i];
        PyArrayObject *a = plain_array(args[i]);
        if (!a) {  /* the last input of gravity may be a mapping of coefficient values */
            if (keys == Py_None || i != k->nin - 1 || PyArray_Check(args[i]) || s->ndim != 1
                || s->dim[0] != PyTuple_GET_SIZE(keys) || s->dim[0] > 64 || mapping_values(args[i], keys, coeffs) < 0)
                goto slow;
            ip[i] = coeffs; is[i] = 0; ilen[i] = 0;
            continue;
        }
        const int nd = PyArray_NDIM(a), b = nd == s->ndim + 1;
        if (!(nd == s->ndim || b)) goto slow;
        for (int d = 0; d < s->ndim; ++d) if (PyArray_DIM(a, d + b) != s->dim[d]) goto slow;
        ip[i] = (const double *)PyArray_DATA(a);
        ilen[i] = PyArray_NBYTES(a);
        if (b) {
            const Py_ssize_t rows = PyArray_DIM(a, 0);
            if (rows == 0 || (n >= 0 && rows != n)) goto slow;
            n = rows;
            is[i] = s->size;          /* scanned chunk by chunk in run_rows */
        } else {
            if (!all_finite(ip[i], s->size)) goto slow;
            is[i] = 0;
        }
    }
    const arg_shape *s = &k->out[0];
    npy_intp dims[3];
    int nd = 0;
    if (n >= 0) dims[nd++] = n;
    for (int d = 0; d < s->ndim; ++d) dims[nd++] = s->dim[d];
    if (out) {  /* numpy's convention: exactly the result's shape and dtype, writable */
        PyArrayObject *o = plain_array(out);
        if (!o || PyArray_NDIM(o) != nd || !PyArray_ISWRITEABLE(o)) goto slow;
        for (int d = 0; d < nd; ++d) if (PyArray_DIM(o, d) != dims[d]) goto slow;
        for (int i = 0; i < k->nin; ++i)  /* written while read: the Python path copies */
            if (ilen[i] && overlaps(ip[i], ilen[i], PyArray_DATA(o), PyArray_NBYTES(o))) goto slow;
        Py_INCREF(out);
        res = out;
    } else {
        res = PyArray_SimpleNew(nd, dims, NPY_DOUBLE);
        if (!res) return NULL;
    }
    op[0] = (double *)PyArray_DATA((PyArrayObject *)res);
    os[0] = s->size;
    int bad = 0;
    if (n < 0) {
        for (int g = 0; g < k->nguard; ++g) { op[1 + g] = &guard[g]; os[1 + g] = 0; }
        k->fn(1, ip, is, op, os);
        for (int g = 0; g < k->nguard; ++g) bad |= !(guard[g] >= 0);
        bad |= !k->finite_out && !all_finite(op[0], s->size);
    } else {
        for (int g = 0; g < k->nguard; ++g) { op[1 + g] = NULL; os[1 + g] = 1; }
        if (n > 4096) {
            Py_BEGIN_ALLOW_THREADS
            bad = run_rows(k, n, ip, is, op, os, 1);
            Py_END_ALLOW_THREADS
        } else {
            bad = run_rows(k, n, ip, is, op, os, 1);
        }
    }
    if (bad) { Py_DECREF(res); goto slow; }
    return res;
slow:
    return PyObject_Vectorcall(fallback, args, (size_t)nargs, kwnames);
}

/* ---------------------------------------------------------------- ik, ik_all, config_of */

static struct {
    int ready, ik, ik_all, ind;                 /* kernel indices (-1: absent) */
    PyObject *config_type, *fields, *configs;   /* Config class, its field names, Config.all() */
    int nfield, nconf;
    double revolute[6], lower[6], upper[6];
    double rigid_tol, same_tol;
} IK = {0, -1, -1, -1, NULL, NULL, NULL, 0, 0, {0}, {0}, {0}, 0, 0};

static int kernel_index(const char *name)
{
    for (int i = 0; i < (int)(sizeof KERNELS / sizeof KERNELS[0]); ++i)
        if (strcmp(KERNELS[i].name, name) == 0) return i;
    return -1;
}

static int six_floats(PyObject *seq, double *v, const char *what)
{
    PyObject *f = PySequence_Fast(seq, what);
    if (!f) return -1;
    if (PySequence_Fast_GET_SIZE(f) != 6) { Py_DECREF(f); PyErr_Format(PyExc_ValueError, "%s: need 6 values", what); return -1; }
    for (int j = 0; j < 6; ++j) {
        v[j] = PyFloat_AsDouble(PySequence_Fast_GET_ITEM(f, j));
        if (v[j] == -1.0 && PyErr_Occurred()) { Py_DECREF(f); return -1; }
    }
    Py_DECREF(f);
    return 0;
}

/* ik_setup(Config, field names, Config.all(), revolute flags, lower, upper, rigid tol, same-solution tol) */
static PyObject *ik_setup(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *ct, *fields, *configs, *rev, *lo, *hi;
    double rigid, same;
    if (!PyArg_ParseTuple(args, "OO!O!OOOdd:ik_setup", &ct, &PyTuple_Type, &fields, &PyTuple_Type, &configs,
                          &rev, &lo, &hi, &rigid, &same)) return NULL;
    IK.ik = kernel_index("ik");
    IK.ik_all = kernel_index("ik_all");
    IK.ind = kernel_index("config_indicators");
    IK.nfield = (int)PyTuple_GET_SIZE(fields);
    IK.nconf = (int)PyTuple_GET_SIZE(configs);
    if (IK.nfield < 1 || IK.nfield > 8 || IK.nconf != (1 << IK.nfield)) {
        PyErr_SetString(PyExc_ValueError, "ik_setup: need 1..8 fields and 2**fields configurations");
        return NULL;
    }
    if (six_floats(rev, IK.revolute, "ik_setup revolute") < 0 || six_floats(lo, IK.lower, "ik_setup lower") < 0
        || six_floats(hi, IK.upper, "ik_setup upper") < 0) return NULL;
    /* the kernels must have the layout the entries assume; otherwise they stay unused */
    if (IK.ik >= 0 && !(KERNELS[IK.ik].nin == 2 && KERNELS[IK.ik].in[0].size == 16 && KERNELS[IK.ik].in[1].size == IK.nfield
                        && KERNELS[IK.ik].out[0].size == 6 && KERNELS[IK.ik].nout == 1 + KERNELS[IK.ik].nguard)) IK.ik = -1;
    if (IK.ik_all >= 0 && !(KERNELS[IK.ik_all].nout == 2 && KERNELS[IK.ik_all].out[0].size == 6 * IK.nconf
                            && KERNELS[IK.ik_all].out[1].size <= 16 * IK.nconf)) IK.ik_all = -1;
    if (IK.ind >= 0 && !(KERNELS[IK.ind].nin == 1 && KERNELS[IK.ind].in[0].size == 6 && KERNELS[IK.ind].nguard == 0
                         && KERNELS[IK.ind].nout == 1 && KERNELS[IK.ind].out[0].size == IK.nfield)) IK.ind = -1;
    Py_XSETREF(IK.config_type, Py_NewRef(ct));
    Py_XSETREF(IK.fields, Py_NewRef(fields));
    Py_XSETREF(IK.configs, Py_NewRef(configs));
    IK.rigid_tol = rigid;
    IK.same_tol = same;
    IK.ready = 1;
    Py_RETURN_NONE;
}

/* 1 when the 16 doubles are clearly a rigid transform: finite, last row exactly 0 0 0 1,
 * rotation orthonormal within half of rigid_tol (the borderline band is left to the Python
 * check), determinant > 0 */
static int pose_within(const double *t, double rigid_tol)
{
    if (!all_finite(t, 16) || t[12] != 0.0 || t[13] != 0.0 || t[14] != 0.0 || t[15] != 1.0) return 0;
    double dev = 0.0;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            const double d = t[i] * t[j] + t[4 + i] * t[4 + j] + t[8 + i] * t[8 + j] - (i == j);
            dev = fabs(d) > dev ? fabs(d) : dev;
        }
    const double det = t[0] * (t[5] * t[10] - t[6] * t[9]) - t[1] * (t[4] * t[10] - t[6] * t[8])
                     + t[2] * (t[4] * t[9] - t[5] * t[8]);
    return dev <= 0.5 * rigid_tol && det > 0;
}

static int pose_ok(const double *t) { return pose_within(t, IK.rigid_tol); }

/* the pose as 16 doubles when it is a plain (4, 4) array and pose_ok */
static const double *pose_arg(PyObject *x)
{
    PyArrayObject *a = plain_array(x);
    if (!a || PyArray_NDIM(a) != 2 || PyArray_DIM(a, 0) != 4 || PyArray_DIM(a, 1) != 4) return NULL;
    const double *t = (const double *)PyArray_DATA(a);
    return pose_ok(t) ? t : NULL;
}

/* q_ref when None (NULL), or a plain finite (6,) array; *ok = 0 when the Python path must decide */
static const double *ref_arg(PyObject *x, int *ok)
{
    *ok = 1;
    if (!x || x == Py_None) return NULL;
    PyArrayObject *a = plain_array(x);
    if (!a || PyArray_NDIM(a) != 1 || PyArray_DIM(a, 0) != 6 || !all_finite((const double *)PyArray_DATA(a), 6)) {
        *ok = 0;
        return NULL;
    }
    return (const double *)PyArray_DATA(a);
}

/* the +-1 signs of a Config instance (exactly the class `type`, fields named by `fields`) */
static int signs_of(PyObject *c, PyObject *type, PyObject *fields, int nfield, double *signs)
{
    if (!type || (PyObject *)Py_TYPE(c) != type) return -1;
    for (int i = 0; i < nfield; ++i) {
        PyObject *v = PyObject_GetAttr(c, PyTuple_GET_ITEM(fields, i));
        if (!v) { PyErr_Clear(); return -1; }
        const long s = PyLong_CheckExact(v) ? PyLong_AsLong(v) : 0;
        Py_DECREF(v);
        if (s != 1 && s != -1) { PyErr_Clear(); return -1; }
        signs[i] = (double)s;
    }
    return 0;
}

static int config_signs(PyObject *c, double *signs)
{
    return signs_of(c, IK.config_type, IK.fields, IK.nfield, signs);
}

/* (x + pi) mod 2 pi - pi with numpy's floor modulo: runtime._wrap, to the bit */
static double wrap_angle(double x)
{
    double y = fmod(x + M_PI, 2 * M_PI);
    if (y != 0.0) { if (y < 0) y += 2 * M_PI; }
    else y = 0.0;
    return y - M_PI;
}

/* q_ref's 2 pi branch on revolute joints, then finite and prismatic joints in range;
 * 0 when all is well */
static int finish_q(double *q, const double *ref)
{
    if (!all_finite(q, 6)) return -1;
    if (ref)
        for (int j = 0; j < 6; ++j)
            if (IK.revolute[j] != 0) q[j] = ref[j] + wrap_angle(q[j] - ref[j]);
    for (int j = 0; j < 6; ++j)
        if (IK.revolute[j] == 0 && (q[j] < IK.lower[j] - 1e-12 || q[j] > IK.upper[j] + 1e-12)) return -1;
    return all_finite(q, 6) ? 0 : -1;
}

static PyObject *new_vector(const double *v, npy_intp len)
{
    PyObject *a = PyArray_SimpleNew(1, &len, NPY_DOUBLE);
    if (a) memcpy(PyArray_DATA((PyArrayObject *)a), v, (size_t)len * sizeof(double));
    return a;
}

/* the q_ref argument of ik(T, config, q_ref=None) / ik_all(T, q_ref=None): position `pos`
 * or the keyword; *ok = 0 for any other call form */
static PyObject *q_ref_object(PyObject *const *args, Py_ssize_t nargs, PyObject *kwnames, Py_ssize_t pos, int *ok)
{
    const Py_ssize_t nkw = kwnames ? PyTuple_GET_SIZE(kwnames) : 0;
    *ok = 1;
    if (nkw == 0 && nargs == pos) return NULL;
    if (nkw == 0 && nargs == pos + 1) return args[pos];
    if (nkw == 1 && nargs == pos && PyUnicode_CompareWithASCIIString(PyTuple_GET_ITEM(kwnames, 0), "q_ref") == 0)
        return args[pos];
    *ok = 0;
    return NULL;
}

/* ik(T, config, q_ref=None) for one pose */
static PyObject *pubfast_ik(PyObject *fallback, PyObject *const *args, Py_ssize_t nargs, PyObject *kwnames)
{
    int ok;
    if (!IK.ready || IK.ik < 0 || nargs < 2) goto slow;
    PyObject *ref_obj = q_ref_object(args, nargs, kwnames, 2, &ok);
    if (!ok) goto slow;
    const double *ref = ref_arg(ref_obj, &ok), *t = pose_arg(args[0]);
    double signs[8], q[6], guard[MAXIO];
    if (!ok || !t || config_signs(args[1], signs) < 0) goto slow;
    const kernel_entry *k = &KERNELS[IK.ik];
    const double *ip[2] = {t, signs};
    double *op[MAXIO];
    static const Py_ssize_t zero[MAXIO] = {0};
    op[0] = q;
    for (int g = 0; g < k->nguard; ++g) op[1 + g] = &guard[g];
    k->fn(1, ip, zero, op, zero);
    for (int g = 0; g < k->nguard; ++g) if (!(guard[g] >= 0)) goto slow;  /* unreachable, singular: messages */
    if (finish_q(q, ref) < 0) goto slow;
    return new_vector(q, 6);
slow:
    return PyObject_Vectorcall(fallback, args, (size_t)nargs, kwnames);
}

/* every configuration of one pose from the ik_all kernel, duplicates (2 pi apart) dropped
 * with the first kept: a new list of (Config, q), NULL with *slow = 1 when the Python path
 * must decide (a configuration failing a guard: left out, wrist fallback or an error) */
static PyObject *ik_all_one(const double *t, const double *ref, int *slow)
{
    const kernel_entry *k = &KERNELS[IK.ik_all];
    const int nc = IK.nconf, ng = (int)(k->out[1].size / nc);
    double q[256 * 6], g[256 * 16];
    int found[256], kept[256], nkept = 0;
    *slow = 1;
    if (nc > 256 || !pose_ok(t)) return NULL;
    const double *ip[1] = {t};
    double *op[2] = {q, g};
    static const Py_ssize_t zero[2] = {0, 0};
    k->fn(1, ip, zero, op, zero);
    for (int j = 0; j < nc; ++j) {
        for (int c = 0; c < ng; ++c) if (!(g[j * ng + c] >= 0)) return NULL;
        if (!all_finite(q + 6 * j, 6)) return NULL;
        found[j] = finish_q(q + 6 * j, ref) == 0;   /* a prismatic joint out of range: left out */
    }
    for (int j = 0; j < nc; ++j) {
        if (!found[j]) continue;
        int dup = 0;
        for (int m = 0; m < nkept && !dup; ++m) {
            int same = 1;
            for (int c = 0; c < 6 && same; ++c) {
                double d = q[6 * j + c] - q[6 * kept[m] + c];
                if (IK.revolute[c] != 0) d = wrap_angle(d);
                same = fabs(d) < IK.same_tol;
            }
            dup = same;
        }
        if (!dup) kept[nkept++] = j;
    }
    *slow = 0;
    PyObject *list = PyList_New(nkept);
    if (!list) return NULL;
    for (int m = 0; m < nkept; ++m) {
        PyObject *v = new_vector(q + 6 * kept[m], 6);
        PyObject *pair = v ? PyTuple_Pack(2, PyTuple_GET_ITEM(IK.configs, kept[m]), v) : NULL;
        Py_XDECREF(v);
        if (!pair) { Py_DECREF(list); return NULL; }
        PyList_SET_ITEM(list, m, pair);
    }
    return list;
}

/* ik_all(T, q_ref=None) for one pose (4, 4) or a batch (N, 4, 4) (q_ref then (N, 6)); a
 * batch goes to the Python path as a whole when any of its poses must */
static PyObject *pubfast_ik_all(PyObject *fallback, PyObject *const *args, Py_ssize_t nargs, PyObject *kwnames)
{
    int ok, slow;
    if (!IK.ready || IK.ik_all < 0 || nargs < 1) goto slow;
    PyObject *ref_obj = q_ref_object(args, nargs, kwnames, 1, &ok);
    if (!ok) goto slow;
    PyArrayObject *a = plain_array(args[0]);
    if (!a || PyArray_DIM(a, PyArray_NDIM(a) - 1) != 4) goto slow;
    if (PyArray_NDIM(a) == 2) {
        const double *ref = ref_arg(ref_obj, &ok), *t = pose_arg(args[0]);
        if (!ok || !t) goto slow;
        PyObject *res = ik_all_one(t, ref, &slow);
        if (slow) goto slow;
        return res;
    }
    if (PyArray_NDIM(a) != 3 || PyArray_DIM(a, 1) != 4 || PyArray_DIM(a, 0) == 0) goto slow;
    const Py_ssize_t n = PyArray_DIM(a, 0);
    const double *refs = NULL;
    if (ref_obj && ref_obj != Py_None) {
        PyArrayObject *r = plain_array(ref_obj);
        if (!r || PyArray_NDIM(r) != 2 || PyArray_DIM(r, 0) != n || PyArray_DIM(r, 1) != 6) goto slow;
        refs = (const double *)PyArray_DATA(r);
        if (!all_finite(refs, 6 * n)) goto slow;
    }
    const double *ts = (const double *)PyArray_DATA(a);
    PyObject *out = PyList_New(n);
    if (!out) return NULL;
    for (Py_ssize_t i = 0; i < n; ++i) {
        PyObject *res = ik_all_one(ts + 16 * i, refs ? refs + 6 * i : NULL, &slow);
        if (!res) {
            Py_DECREF(out);
            if (slow) goto slow;
            return NULL;
        }
        PyList_SET_ITEM(out, i, res);
    }
    return out;
slow:
    return PyObject_Vectorcall(fallback, args, (size_t)nargs, kwnames);
}

/* config_of(q) for one configuration: the Config.all() entry of the indicators' signs */
static PyObject *pubfast_config_of(PyObject *fallback, PyObject *const *args, Py_ssize_t nargs, PyObject *kwnames)
{
    if (!IK.ready || IK.ind < 0 || nargs != 1 || kwnames) goto slow;
    PyArrayObject *a = plain_array(args[0]);
    if (!a || PyArray_NDIM(a) != 1 || PyArray_DIM(a, 0) != 6) goto slow;
    const double *q = (const double *)PyArray_DATA(a);
    if (!all_finite(q, 6)) goto slow;
    double ind[8];
    const double *ip[1] = {q};
    double *op[1] = {ind};
    static const Py_ssize_t zero[1] = {0};
    KERNELS[IK.ind].fn(1, ip, zero, op, zero);
    if (!all_finite(ind, IK.nfield)) goto slow;
    int idx = 0;
    for (int i = 0; i < IK.nfield; ++i) idx = 2 * idx + (ind[i] >= 0 ? 0 : 1);  /* product((1, -1)) order */
    return Py_NewRef(PyTuple_GET_ITEM(IK.configs, idx));
slow:
    return PyObject_Vectorcall(fallback, args, (size_t)nargs, kwnames);
}

static PyMethodDef IK_DEFS[] = {
    {"ik", (PyCFunction)(void (*)(void))pubfast_ik, METH_FASTCALL | METH_KEYWORDS,
     "ik(T, config, q_ref=None): fast entry for one float64 pose; anything else, and every error, via the runtime"},
    {"ik_all", (PyCFunction)(void (*)(void))pubfast_ik_all, METH_FASTCALL | METH_KEYWORDS,
     "ik_all(T, q_ref=None): fast entry for float64 poses (one or a batch); anything else, and every error, via the runtime"},
    {"config_of", (PyCFunction)(void (*)(void))pubfast_config_of, METH_FASTCALL | METH_KEYWORDS,
     "config_of(q): fast entry for one float64 configuration; anything else via the runtime"},
};

#include "kin_redundant.h"   /* a redundant arm's ik / ik_all (q7 free) */
#endif


/* Shape tuple of one unbatched output (new reference); small shapes are cached so the
 * common single call builds no tuple. */
static PyObject *single_shape(const arg_shape *s)
{
    static PyObject *cache0 = NULL, *cache1[64] = {NULL}, *cache2[16][16] = {{NULL}};
    PyObject **slot = NULL;
    if (s->ndim == 0) slot = &cache0;
    else if (s->ndim == 1 && s->dim[0] < 64) slot = &cache1[s->dim[0]];
    else if (s->ndim == 2 && s->dim[0] < 16 && s->dim[1] < 16) slot = &cache2[s->dim[0]][s->dim[1]];
    if (slot && *slot) { Py_INCREF(*slot); return *slot; }
    PyObject *t = s->ndim == 0 ? PyTuple_New(0) : s->ndim == 1 ? Py_BuildValue("(n)", s->dim[0])
                : Py_BuildValue("(nn)", s->dim[0], s->dim[1]);
    if (slot && t) { Py_INCREF(t); *slot = t; }  /* the cache keeps one reference for the process */
    return t;
}

static PyObject *shape_text(const arg_shape *s)
{
    if (s->ndim == 0) return PyUnicode_FromString("() or (N,)");
    if (s->ndim == 1) return PyUnicode_FromFormat("(%zd,) or (N, %zd)", s->dim[0], s->dim[0]);
    return PyUnicode_FromFormat("(%zd, %zd) or (N, %zd, %zd)", s->dim[0], s->dim[1], s->dim[0], s->dim[1]);
}

/* Get a float64 C-contiguous view of x; convert through numpy when x is not one already. */
static int get_input(PyObject *x, Py_buffer *view, PyObject **owner)
{
    *owner = NULL;
    if (PyObject_GetBuffer(x, view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) == 0) {
        if (view->itemsize == 8 && view->format && strcmp(view->format, "d") == 0) return 0;
        PyBuffer_Release(view);
    } else {
        PyErr_Clear();
    }
    PyObject *conv_args = PyTuple_Pack(1, x);
    if (!conv_args) return -1;
    PyObject *conv = PyObject_Call(np_array, conv_args, np_array_kw);
    Py_DECREF(conv_args);
    if (!conv) return -1;
    if (PyObject_GetBuffer(conv, view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0) { Py_DECREF(conv); return -1; }
    *owner = conv;
    return 0;
}

static PyObject *call_kernel(const kernel_entry *k, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != k->nin) {
        PyErr_Format(PyExc_TypeError, RCCL_ROBOT ".%s takes %d inputs, got %zd", k->name, k->nin, nargs);
        return NULL;
    }
    Py_buffer iv[MAXIO];
    PyObject *owners[MAXIO];
    const double *ip[MAXIO];
    double *op[MAXIO];
    Py_ssize_t is[MAXIO], os[MAXIO];
    PyObject *outs[MAXIO] = {NULL};
    PyObject *result = NULL;
    Py_ssize_t n = -1;
    int ni = 0;
    for (; ni < k->nin; ++ni) {
        if (get_input(args[ni], &iv[ni], &owners[ni]) < 0) goto done;
        const arg_shape *s = &k->in[ni];
        int nd = iv[ni].ndim;
        int batched = (nd == s->ndim + 1);
        int ok = (nd == s->ndim || batched);
        for (int d = 0; ok && d < s->ndim; ++d) ok = iv[ni].shape[d + batched] == s->dim[d];
        if (ok && batched) {
            if (n >= 0 && iv[ni].shape[0] != n) {
                PyErr_Format(PyExc_ValueError, RCCL_ROBOT ".%s: input '%s' has %zd rows, an earlier input has %zd",
                             k->name, k->in_name[ni], iv[ni].shape[0], n);
                ++ni; goto done;
            }
            n = iv[ni].shape[0];
        }
        if (!ok) {
            PyObject *need = shape_text(s);
            PyObject *got = PyTuple_New(nd);
            for (int d = 0; got && d < nd; ++d) PyTuple_SET_ITEM(got, d, PyLong_FromSsize_t(iv[ni].shape[d]));
            PyErr_Format(PyExc_ValueError, RCCL_ROBOT ".%s: input '%s' has shape %R, need %U",
                         k->name, k->in_name[ni], got, need);
            Py_XDECREF(need); Py_XDECREF(got);
            ++ni; goto done;
        }
        ip[ni] = (const double *)iv[ni].buf;
        is[ni] = batched ? s->size : 0;
        Py_ssize_t len = iv[ni].len / 8;
        for (Py_ssize_t j = 0; j < len; ++j) {
            if (!isfinite(ip[ni][j])) {
                if (batched)
                    PyErr_Format(PyExc_ValueError, RCCL_ROBOT ".%s: input '%s' row %zd element %zd is %s",
                                 k->name, k->in_name[ni], j / s->size, j % s->size,
                                 isnan(ip[ni][j]) ? "NaN" : "infinite");
                else
                    PyErr_Format(PyExc_ValueError, RCCL_ROBOT ".%s: input '%s' element %zd is %s",
                                 k->name, k->in_name[ni], j, isnan(ip[ni][j]) ? "NaN" : "infinite");
                ++ni; goto done;
            }
        }
    }
    Py_ssize_t rows = n < 0 ? 1 : n;
    for (int o = 0; o < k->nout; ++o) {
        const arg_shape *s = &k->out[o];
        PyObject *shape;
        if (n < 0) {
            shape = single_shape(s);
            if (!shape) goto done;
            outs[o] = PyObject_Vectorcall(np_empty, &shape, 1, NULL);
            Py_DECREF(shape);
        } else {
            shape = PyTuple_New(1 + s->ndim);
            if (!shape) goto done;
            PyTuple_SET_ITEM(shape, 0, PyLong_FromSsize_t(n));
            for (int d = 0; d < s->ndim; ++d) PyTuple_SET_ITEM(shape, d + 1, PyLong_FromSsize_t(s->dim[d]));
            outs[o] = PyObject_Vectorcall(np_empty, &shape, 1, NULL);
            Py_DECREF(shape);
        }
        if (!outs[o]) goto done;
        Py_buffer ov;
        if (PyObject_GetBuffer(outs[o], &ov, PyBUF_C_CONTIGUOUS | PyBUF_WRITABLE) < 0) goto done;
        op[o] = (double *)ov.buf;   /* the array keeps the memory alive */
        PyBuffer_Release(&ov);
        os[o] = s->size;
    }
    if (rows > 4096) {
        Py_BEGIN_ALLOW_THREADS
        run_rows(k, rows, ip, is, op, os, 0);
        Py_END_ALLOW_THREADS
    } else {
        k->fn(rows, ip, is, op, os);
    }
    result = PyTuple_New(k->nout);
    if (!result) goto done;
    for (int o = 0; o < k->nout; ++o) {
        if (n < 0 && k->out[o].ndim == 0) {
            PyTuple_SET_ITEM(result, o, PyFloat_FromDouble(op[o][0]));
            Py_CLEAR(outs[o]);
        } else {
            PyTuple_SET_ITEM(result, o, outs[o]);
            outs[o] = NULL;
        }
    }
done:
    for (int i = 0; i < ni; ++i) { PyBuffer_Release(&iv[i]); Py_XDECREF(owners[i]); }
    for (int o = 0; o < k->nout; ++o) Py_XDECREF(outs[o]);
    return result;
}


#ifdef RCCL_NUMPY_API
static PyMethodDef public_def[NKERNELS];   /* the public entries, made at import like kernel_def */

/* public(name, fallback, keys=None): the fast public entry of a single-output kernel
 * (keys: names of the coefficients its last input may also be given by, as a mapping), or
 * of "ik", "ik_all", "config_of" (after ik_setup), falling back to `fallback`. */
static PyObject *public(PyObject *self, PyObject *args)
{
    const char *name;
    PyObject *fallback, *keys = Py_None;
    if (!PyArg_ParseTuple(args, "sO|O:public", &name, &fallback, &keys)) return NULL;
    if (!PyCallable_Check(fallback)) { PyErr_SetString(PyExc_TypeError, "public: fallback must be callable"); return NULL; }
    if (keys != Py_None && !PyTuple_Check(keys)) { PyErr_SetString(PyExc_TypeError, "public: keys must be a tuple"); return NULL; }
    for (int i = 0; i < (int)(sizeof IK_DEFS / sizeof IK_DEFS[0]); ++i)
        if (strcmp(IK_DEFS[i].ml_name, name) == 0) {
            if (!IK.ready) { PyErr_SetString(PyExc_RuntimeError, "public: call ik_setup first"); return NULL; }
            return PyCFunction_NewEx(&IK_DEFS[i], fallback, NULL);
        }
    for (int i = 0; i < NKERNELS; ++i)
        if (strcmp(KERNELS[i].name, name) == 0) {
            if (KERNELS[i].nout - KERNELS[i].nguard != 1) break;
            if (keys != Py_None) {
                for (Py_ssize_t j = 0; j < PyTuple_GET_SIZE(keys); ++j) PyUnicode_InternInPlace(&PyTuple_GET_ITEM(keys, j));
            }
            PyObject *data = PyTuple_Pack(3, fallback, keys, kernel_capsule[i]);
            if (!data) return NULL;
            PyObject *fn = PyCFunction_NewEx(&public_def[i], data, NULL);
            Py_DECREF(data);
            return fn;
        }
    PyErr_Format(PyExc_KeyError, RCCL_ROBOT ": no single-output kernel %s", name);
    return NULL;
}
#endif

static PyObject *arg_shape_tuple(const arg_shape *s)
{
    return s->ndim == 0 ? PyTuple_New(0) : s->ndim == 1 ? Py_BuildValue("(n)", s->dim[0])
                        : Py_BuildValue("(nn)", s->dim[0], s->dim[1]);
}

/* kernels(): {name: (input shapes, output shapes)}, for the loader to check it matches. */
static PyObject *kernels(PyObject *self, PyObject *noargs)
{
    (void)self; (void)noargs;
    PyObject *d = PyDict_New();
    if (!d) return NULL;
    for (int i = 0; i < NKERNELS; ++i) {
        const kernel_entry *k = &KERNELS[i];
        PyObject *ins = PyTuple_New(k->nin), *outs = PyTuple_New(k->nout);
        if (!ins || !outs) { Py_XDECREF(ins); Py_XDECREF(outs); Py_DECREF(d); return NULL; }
        for (int j = 0; j < k->nin; ++j) PyTuple_SET_ITEM(ins, j, arg_shape_tuple(&k->in[j]));
        for (int j = 0; j < k->nout; ++j) PyTuple_SET_ITEM(outs, j, arg_shape_tuple(&k->out[j]));
        PyObject *v = Py_BuildValue("(NN)", ins, outs);
        if (!v || PyDict_SetItemString(d, k->name, v) < 0) { Py_XDECREF(v); Py_DECREF(d); return NULL; }
        Py_DECREF(v);
    }
    return d;
}

static PyObject *threads(PyObject *self, PyObject *noargs)
{
    (void)self; (void)noargs;
    return PyLong_FromLong(n_threads);
}

static PyObject *source_hash(PyObject *self, PyObject *noargs)
{
    (void)self; (void)noargs;
    return PyUnicode_FromString(RCCL_SOURCE_HASH);
}

/* vector_sincos([x, ...]) -> ([sin], [cos]) through the batched rows' vector sine/cosine,
 * or None when this build or CPU has none: lets the tests measure its accuracy */
static PyObject *vector_sincos(PyObject *self, PyObject *arg)
{
    (void)self;
#ifdef RCCL_VECTOR_TRIG
    if (!have_vector_trig) Py_RETURN_NONE;
    PyObject *seq = PySequence_Fast(arg, "vector_sincos takes a sequence of floats");
    if (!seq) return NULL;
    const Py_ssize_t n = PySequence_Fast_GET_SIZE(seq);
    double *buf = PyMem_Malloc(3 * (size_t)(n ? n : 1) * sizeof(double));
    PyObject *ls = PyList_New(n), *lc = PyList_New(n);
    if (!buf || !ls || !lc) goto fail;
    for (Py_ssize_t i = 0; i < n; ++i) {
        buf[i] = PyFloat_AsDouble(PySequence_Fast_GET_ITEM(seq, i));
        if (buf[i] == -1.0 && PyErr_Occurred()) goto fail;
    }
    for (Py_ssize_t i = 0; i < n; i += 1 << 20) {
        const int m = n - i < (1 << 20) ? (int)(n - i) : 1 << 20;
        vtrig_sincos(buf + i, buf + n + i, buf + 2 * n + i, m);
    }
    for (Py_ssize_t i = 0; i < n; ++i) {
        PyList_SET_ITEM(ls, i, PyFloat_FromDouble(buf[n + i]));
        PyList_SET_ITEM(lc, i, PyFloat_FromDouble(buf[2 * n + i]));
    }
    PyMem_Free(buf);
    Py_DECREF(seq);
    return Py_BuildValue("(NN)", ls, lc);
fail:
    PyMem_Free(buf); Py_XDECREF(ls); Py_XDECREF(lc); Py_DECREF(seq);
    return NULL;
#else
    (void)arg;
    Py_RETURN_NONE;
#endif
}

static PyMethodDef methods[] = {
    {"vector_sincos", vector_sincos, METH_O, "vector_sincos([x, ...]) -> ([sin x], [cos x]) by the batched rows' vector sine/cosine; None without one"},
    {"kernels", kernels, METH_NOARGS, "kernels() -> {name: (input shapes, output shapes)}"},
    {"source_hash", source_hash, METH_NOARGS, "sha256 of the generated C and the runtime headers this module was built from"},
    {"threads", threads, METH_NOARGS, "threads() -> the most threads a large batch is split over (RCCL_KINEMATICS_THREADS)"},
#ifdef RCCL_NUMPY_API
    {"public", public, METH_VARARGS, "public(name, fallback, keys=None) -> fast public entry of a kernel (see public_call)"},
    {"redundant_setup", redundant_setup, METH_VARARGS, "redundant_setup(Config, fields, configs, lower, upper, singular, rigid_tol, same_tol, range_tol, reproduce_tol) -> True when the redundant ik entries can run"},
    {"redundant_public", redundant_public, METH_VARARGS, "redundant_public(name, fallback) -> fast entry redundant_ik / redundant_ik_all"},
    {"ik_setup", ik_setup, METH_VARARGS, "ik_setup(Config, fields, configs, revolute, lower, upper, rigid_tol, same_tol): data of the ik/ik_all/config_of entries"},
#endif
    {NULL, NULL, 0, NULL}
};

static struct PyModuleDef moduledef = {
    PyModuleDef_HEAD_INIT, RCCL_ROBOT, "Generated C kinematics kernels of the " RCCL_ROBOT
    " (derive/emit_c.py; shared runtime rccl/kinematics/_c/kin_runtime.h).", -1, methods
};

/* the module: the runtime's functions above plus one function per kernel */
static PyObject *module_init(void)
{
#ifdef RCCL_NUMPY_API
    import_array();
    str_value = PyUnicode_InternFromString("value");
    str_gravity_coeffs = PyUnicode_InternFromString("gravity_coeffs");
    if (!str_value || !str_gravity_coeffs) return NULL;
#endif
    init_threads();
#ifdef RCCL_VECTOR_TRIG
    vtrig_init(1);
#endif
    PyObject *np = PyImport_ImportModule("numpy");
    if (!np) return NULL;
    np_empty = PyObject_GetAttrString(np, "empty");
    np_array = PyObject_GetAttrString(np, "array");
    Py_DECREF(np);
    np_array_kw = Py_BuildValue("{ssss}", "dtype", "float64", "order", "C");
    if (!np_empty || !np_array || !np_array_kw) return NULL;
    PyObject *m = PyModule_Create(&moduledef);
    for (int i = 0; m && i < NKERNELS; ++i) {
        const kernel_entry *k = &KERNELS[i];
        kernel_def[i] = (PyMethodDef){k->name, (PyCFunction)(void (*)(void))py_kernel, METH_FASTCALL, k->doc};
#ifdef RCCL_NUMPY_API
        public_def[i] = (PyMethodDef){k->name, (PyCFunction)(void (*)(void))public_call,
                                      METH_FASTCALL | METH_KEYWORDS, k->doc};
#endif
        kernel_capsule[i] = PyCapsule_New((void *)k, NULL, NULL);   /* kept for the process */
        PyObject *fn = kernel_capsule[i] ? PyCFunction_NewEx(&kernel_def[i], kernel_capsule[i], NULL) : NULL;
        if (!fn || PyModule_AddObject(m, k->name, fn) < 0) { Py_XDECREF(fn); Py_CLEAR(m); }
    }
    return m;
}

#define RCCL_MODULE_INIT(name) PyMODINIT_FUNC PyInit_##name(void) { return module_init(); }

#endif
