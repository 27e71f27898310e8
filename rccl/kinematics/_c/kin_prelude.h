/* The shared prelude of the generated kinematics extensions (rccl/kinematics/_c/<robot>.c):
 * headers, the vector sine/cosine of libmvec, and the kernel table's types. Hand-written;
 * a generated file defines RCCL_ROBOT and MAXIO, includes this, then its kernels and
 * their table KERNELS, then kin_runtime.h. */
#ifndef RCCL_KIN_PRELUDE_H
#define RCCL_KIN_PRELUDE_H
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#ifdef RCCL_NUMPY_API
/* numpy's C API, when setup.py found numpy's headers: the public fast path below */
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>
#endif

#if defined(RCCL_LIBMVEC) && defined(__x86_64__) && defined(__GNUC__)
/* glibc's vector math library (libmvec): sin/cos of 4 doubles at once with AVX2, within
 * 4 ulp; used for batches when the CPU has AVX2 (checked at import), else plain libm. */
#define RCCL_VECTOR_TRIG 1
#include <immintrin.h>
__m256d _ZGVdN4v_sin(__m256d);
__m256d _ZGVdN4v_cos(__m256d);
static int have_vector_trig = 0;

#define VTRIG(fn) \
__attribute__((target("avx2,fma"))) static void vtrig_##fn(const double *x, double *y, int m) \
{ \
    int i = 0; \
    for (; i + 4 <= m; i += 4) _mm256_storeu_pd(y + i, _ZGVdN4v_##fn(_mm256_loadu_pd(x + i))); \
    if (i < m) { /* the tail, padded into one vector */ \
        double xt[4] = {0, 0, 0, 0}, yt[4]; \
        for (int j = 0; i + j < m; ++j) xt[j] = x[i + j]; \
        _mm256_storeu_pd(yt, _ZGVdN4v_##fn(_mm256_loadu_pd(xt))); \
        for (int j = 0; i + j < m; ++j) y[i + j] = yt[j]; \
    } \
}
VTRIG(sin)
VTRIG(cos)
#endif

typedef void (*batch_fn)(Py_ssize_t, const double *const *, const Py_ssize_t *, double *const *, const Py_ssize_t *);

typedef struct { int ndim; Py_ssize_t dim[2]; Py_ssize_t size; } arg_shape;

typedef struct {
    const char *name;
    batch_fn fn;
    int nin, nout, nguard;      /* nout counts the outputs and then the nguard guards */
    arg_shape in[MAXIO];
    arg_shape out[MAXIO];
    const char *in_name[MAXIO];
    const char *out_name[MAXIO];
    const char *doc;            /* the docstring of the kernel's Python-callable entry */
} kernel_entry;

#endif
