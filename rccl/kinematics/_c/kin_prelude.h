/* The shared prelude of the generated kinematics extensions (rccl/kinematics/_c/<robot>.c):
 * headers, the vector sine/cosine of the batched rows, and the kernel table's types. Hand-written;
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

/* No fused multiply-adds but those written as intrinsics, whatever the flags (e.g. a
 * build with -march=native): a row must round alike on every path (one configuration,
 * a block of a batch, no AVX2), so that one configuration and the same one in a batch
 * give the same bits. */
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#elif defined(__GNUC__)
#pragma GCC optimize("fp-contract=off")
#endif

#if defined(__x86_64__) && defined(__GNUC__)
/* Sine and cosine of 4 doubles at once with AVX2 and FMA, for the batched rows (and a
 * single row's angles side by side), when the CPU has both (checked at import); else
 * plain libm. Both come from one reduction x = k pi/2 + r, |r| <= pi/4: k by the
 * 1.5 * 2^52 shift (which leaves k mod 4 in the low mantissa bits), r with pi/2 split into
 * three doubles (FMA keeps each product k * part exact). On |r| <= pi/4 the degree-13
 * sine and degree-14 cosine minimax polynomials of fdlibm's __kernel_sin/__kernel_cos
 * (their published coefficients); the quadrant k mod 4 then swaps and signs the pair.
 * Error against the exact value: at most 0.74 ulp for |x| <= pi/4, 1.38 ulp for joint
 * angles (|x| <= 2 pi), 1.5 ulp up to |x| = 2^20 (the rounding of r; measured by
 * tests/test_backends_kinematics.py against long double; glibc's libmvec, used before,
 * states 4 ulp). Lanes beyond 2^20 go through libm. */
#define RCCL_VECTOR_TRIG 1
#include <immintrin.h>
static int have_vector_trig = 0;
#define VTRIG_BIG 1048576.0

__attribute__((target("avx2,fma"))) static inline void sincos4(__m256d x, __m256d *sn, __m256d *cs)
{
    const __m256d shift = _mm256_set1_pd(6755399441055744.0);        /* 1.5 * 2^52 */
    const __m256d kd = _mm256_fmadd_pd(x, _mm256_set1_pd(0.63661977236758134308), shift);
    const __m256d k = _mm256_sub_pd(kd, shift);
    __m256d r = _mm256_fnmadd_pd(k, _mm256_set1_pd(1.5707963267948966), x);   /* exact */
    r = _mm256_fnmadd_pd(k, _mm256_set1_pd(6.123233995736766e-17), r);
    r = _mm256_fnmadd_pd(k, _mm256_set1_pd(-1.4973849048591698e-33), r);
    const __m256d z = _mm256_mul_pd(r, r);
    __m256d ps = _mm256_set1_pd(1.58969099521155010221e-10);         /* sin r = r + r^3 P(z) */
    ps = _mm256_fmadd_pd(ps, z, _mm256_set1_pd(-2.50507602534068634195e-08));
    ps = _mm256_fmadd_pd(ps, z, _mm256_set1_pd(2.75573137070700676789e-06));
    ps = _mm256_fmadd_pd(ps, z, _mm256_set1_pd(-1.98412698298579493134e-04));
    ps = _mm256_fmadd_pd(ps, z, _mm256_set1_pd(8.33333333332248946124e-03));
    ps = _mm256_fmadd_pd(ps, z, _mm256_set1_pd(-1.66666666666666324348e-01));
    __m256d pc = _mm256_set1_pd(-1.13596475577881948265e-11);        /* cos r = 1 - z/2 + z^2 Q(z) */
    pc = _mm256_fmadd_pd(pc, z, _mm256_set1_pd(2.08757232129817482790e-09));
    pc = _mm256_fmadd_pd(pc, z, _mm256_set1_pd(-2.75573143513906633035e-07));
    pc = _mm256_fmadd_pd(pc, z, _mm256_set1_pd(2.48015872894767294178e-05));
    pc = _mm256_fmadd_pd(pc, z, _mm256_set1_pd(-1.38888888888741095749e-03));
    pc = _mm256_fmadd_pd(pc, z, _mm256_set1_pd(4.16666666666666019037e-02));
    /* 1 - z/2 rounded as w, its rounding error carried into the small terms */
    const __m256d one = _mm256_set1_pd(1.0), hz = _mm256_mul_pd(_mm256_set1_pd(0.5), z);
    const __m256d w = _mm256_sub_pd(one, hz);
    const __m256d s = _mm256_fmadd_pd(_mm256_mul_pd(z, r), ps, r);
    const __m256d c = _mm256_add_pd(w, _mm256_fmadd_pd(_mm256_mul_pd(z, z), pc, _mm256_sub_pd(_mm256_sub_pd(one, w), hz)));
    /* quadrant q = k mod 4: sin x = s, c, -s, -c and cos x = c, -s, -c, s */
    const __m256i q = _mm256_castpd_si256(kd);
    const __m256d odd = _mm256_castsi256_pd(_mm256_slli_epi64(q, 63));
    const __m256d sign_s = _mm256_castsi256_pd(_mm256_slli_epi64(_mm256_srli_epi64(q, 1), 63));
    const __m256d sign_c = _mm256_castsi256_pd(_mm256_slli_epi64(_mm256_srli_epi64(_mm256_add_epi64(q, _mm256_set1_epi64x(1)), 1), 63));
    *sn = _mm256_xor_pd(_mm256_blendv_pd(s, c, odd), sign_s);
    *cs = _mm256_xor_pd(_mm256_blendv_pd(c, s, odd), sign_c);
}

/* lanes of v beyond VTRIG_BIG (not joint angles, but accepted): recomputed with libm */
static void vtrig_big_lanes(const double *x, double *st, double *ct, int n)
{
    for (int j = 0; j < n; ++j)
        if (fabs(x[j]) > VTRIG_BIG) { st[j] = sin(x[j]); ct[j] = cos(x[j]); }
}

/* One row's sines and cosines: its nv vectors of arguments x (unused lanes 0) into
 * s[0, 4 nv) and c[0, 4 nv), all vectors in one stretch of straight code (inlined into the
 * generated kv1_<kernel>, whose arguments go from the inputs straight into the lanes, with
 * no trip through memory), so that the CPU overlaps their dependency chains. 0 when a lane
 * is beyond VTRIG_BIG: then the caller takes the block path (vtrig_sincos), which sends
 * such lanes to libm. */
#define VTRIG_TARGET __attribute__((target("avx2,fma")))
VTRIG_TARGET __attribute__((always_inline)) static inline int vtrig_row(const __m256d *x, double *s, double *c, int nv)
{
    const __m256d big = _mm256_set1_pd(VTRIG_BIG);
    const __m256d abs_mask = _mm256_castsi256_pd(_mm256_set1_epi64x(0x7fffffffffffffffLL));
    __m256d far = _mm256_setzero_pd();
    for (int v = 0; v < nv; ++v) {
        __m256d sv, cv;
        sincos4(x[v], &sv, &cv);
        _mm256_storeu_pd(s + 4 * v, sv);
        _mm256_storeu_pd(c + 4 * v, cv);
        far = _mm256_or_pd(far, _mm256_cmp_pd(_mm256_and_pd(x[v], abs_mask), big, _CMP_GT_OQ));
    }
    return !_mm256_movemask_pd(far);
}

/* sincos4's operations on 8 lanes with AVX-512F, where the CPU has it (have_vector_trig512,
 * checked at import): the same additions, multiplications and fused multiply-adds lane by
 * lane, each correctly rounded, so the same bits as sincos4 (and a single row's vtrig_row)
 * at twice the lanes per instruction. The quadrant's swap is a mask blend, its signs an
 * integer xor. */
static int have_vector_trig512 = 0;
__attribute__((target("avx512f"))) static inline void sincos8(__m512d x, __m512d *sn, __m512d *cs)
{
    const __m512d shift = _mm512_set1_pd(6755399441055744.0);        /* 1.5 * 2^52 */
    const __m512d kd = _mm512_fmadd_pd(x, _mm512_set1_pd(0.63661977236758134308), shift);
    const __m512d k = _mm512_sub_pd(kd, shift);
    __m512d r = _mm512_fnmadd_pd(k, _mm512_set1_pd(1.5707963267948966), x);
    r = _mm512_fnmadd_pd(k, _mm512_set1_pd(6.123233995736766e-17), r);
    r = _mm512_fnmadd_pd(k, _mm512_set1_pd(-1.4973849048591698e-33), r);
    const __m512d z = _mm512_mul_pd(r, r);
    __m512d ps = _mm512_set1_pd(1.58969099521155010221e-10);
    ps = _mm512_fmadd_pd(ps, z, _mm512_set1_pd(-2.50507602534068634195e-08));
    ps = _mm512_fmadd_pd(ps, z, _mm512_set1_pd(2.75573137070700676789e-06));
    ps = _mm512_fmadd_pd(ps, z, _mm512_set1_pd(-1.98412698298579493134e-04));
    ps = _mm512_fmadd_pd(ps, z, _mm512_set1_pd(8.33333333332248946124e-03));
    ps = _mm512_fmadd_pd(ps, z, _mm512_set1_pd(-1.66666666666666324348e-01));
    __m512d pc = _mm512_set1_pd(-1.13596475577881948265e-11);
    pc = _mm512_fmadd_pd(pc, z, _mm512_set1_pd(2.08757232129817482790e-09));
    pc = _mm512_fmadd_pd(pc, z, _mm512_set1_pd(-2.75573143513906633035e-07));
    pc = _mm512_fmadd_pd(pc, z, _mm512_set1_pd(2.48015872894767294178e-05));
    pc = _mm512_fmadd_pd(pc, z, _mm512_set1_pd(-1.38888888888741095749e-03));
    pc = _mm512_fmadd_pd(pc, z, _mm512_set1_pd(4.16666666666666019037e-02));
    const __m512d one = _mm512_set1_pd(1.0), hz = _mm512_mul_pd(_mm512_set1_pd(0.5), z);
    const __m512d w = _mm512_sub_pd(one, hz);
    const __m512d s = _mm512_fmadd_pd(_mm512_mul_pd(z, r), ps, r);
    const __m512d c = _mm512_add_pd(w, _mm512_fmadd_pd(_mm512_mul_pd(z, z), pc, _mm512_sub_pd(_mm512_sub_pd(one, w), hz)));
    const __m512i q = _mm512_castpd_si512(kd);
    const __mmask8 odd = _mm512_test_epi64_mask(q, _mm512_set1_epi64(1));
    const __m512i sign_s = _mm512_slli_epi64(_mm512_srli_epi64(q, 1), 63);
    const __m512i sign_c = _mm512_slli_epi64(_mm512_srli_epi64(_mm512_add_epi64(q, _mm512_set1_epi64(1)), 1), 63);
    *sn = _mm512_castsi512_pd(_mm512_xor_si512(_mm512_castpd_si512(_mm512_mask_blend_pd(odd, s, c)), sign_s));
    *cs = _mm512_castsi512_pd(_mm512_xor_si512(_mm512_castpd_si512(_mm512_mask_blend_pd(odd, c, s)), sign_c));
}

/* the whole groups of 8 of vtrig_sincos's m values with sincos8; the number done (a group
 * with a lane beyond VTRIG_BIG stops it: the rest go through vtrig_sincos's own loop) */
__attribute__((target("avx512f"))) static int vtrig_sincos8(const double *x, double *s, double *c, int m)
{
    const __m512d big = _mm512_set1_pd(VTRIG_BIG);
    int i = 0;
    for (; i + 8 <= m; i += 8) {
        const __m512d v = _mm512_loadu_pd(x + i);
        if (_mm512_cmp_pd_mask(_mm512_abs_pd(v), big, _CMP_GT_OQ)) break;
        __m512d vs, vc;
        sincos8(v, &vs, &vc);
        if (s) _mm512_storeu_pd(s + i, vs);
        if (c) _mm512_storeu_pd(c + i, vc);
    }
    return i;
}

/* which vector sine/cosine this CPU takes (at import; on = 0: none, libm): AVX2+FMA, and
 * AVX-512F for the whole groups of 8 of a block unless RCCL_KINEMATICS_AVX512=0 */
static void vtrig_init(int on)
{
    __builtin_cpu_init();
    have_vector_trig = on && __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
    const char *env = getenv("RCCL_KINEMATICS_AVX512");
    have_vector_trig512 = have_vector_trig && __builtin_cpu_supports("avx512f") && !(env && env[0] == '0');
}

/* m sines and cosines of x (s or c may be NULL: not wanted) */
__attribute__((target("avx2,fma"))) static void vtrig_sincos(const double *x, double *s, double *c, int m)
{
    const __m256d big = _mm256_set1_pd(VTRIG_BIG);
    const __m256d abs_mask = _mm256_castsi256_pd(_mm256_set1_epi64x(0x7fffffffffffffffLL));
    double st[4], ct[4];
    for (int i = have_vector_trig512 ? vtrig_sincos8(x, s, c, m) : 0; i < m; i += 4) {
        const int n = m - i < 4 ? m - i : 4;
        double xt[4] = {0, 0, 0, 0};
        for (int j = 0; j < n; ++j) xt[j] = x[i + j];
        const __m256d v = n == 4 ? _mm256_loadu_pd(x + i) : _mm256_loadu_pd(xt);
        __m256d vs, vc;
        sincos4(v, &vs, &vc);
        const int far = _mm256_movemask_pd(_mm256_cmp_pd(_mm256_and_pd(v, abs_mask), big, _CMP_GT_OQ));
        if (n == 4 && !far) {
            if (s) _mm256_storeu_pd(s + i, vs);
            if (c) _mm256_storeu_pd(c + i, vc);
            continue;
        }
        _mm256_storeu_pd(st, vs);
        _mm256_storeu_pd(ct, vc);
        if (far) vtrig_big_lanes(x + i, st, ct, n);
        for (int j = 0; j < n; ++j) {
            if (s) s[i + j] = st[j];
            if (c) c[i + j] = ct[j];
        }
    }
}
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
    int finite_out;             /* outputs are polynomials in sines and cosines of the inputs
                                 * (derive/emit_c.py finite_by_construction): finite inputs
                                 * give finite outputs, so they are not scanned */
} kernel_entry;

#endif
