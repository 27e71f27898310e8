/* The generated kernels of one robot as plain C functions (kernel_rows.h), for the C++
 * comparison with Pinocchio (bench/cpp/vs_pinocchio.cpp).
 *
 * RCCL_KERNELS names a file that bench/cpp_pinocchio.py cuts from the generated
 * rccl/kinematics/_c/<robot>.c: everything before its `#include "kin_runtime.h"` (the
 * prelude, every kernel's row function and batched loop, the kernel table), so what runs
 * here is the generated code itself, compiled as the extension compiles it. Python.h comes
 * in through kin_prelude.h for its types only: nothing here calls the interpreter. */
#include RCCL_KERNELS
#include "kernel_rows.h"

#ifndef NJ
#error "NJ (the robot's joint count) must be defined: bench/cpp_pinocchio.py passes -DNJ=<n>"
#endif

static const kernel_entry *find(const char *name)
{
    for (size_t i = 0; i < sizeof KERNELS / sizeof KERNELS[0]; ++i)
        if (strcmp(KERNELS[i].name, name) == 0) return &KERNELS[i];
    abort();  /* the generated module lacks a kernel every robot has: a derive/ change */
}

const char *rccl_robot(void) { return RCCL_ROBOT; }

int rccl_gravity_ncoeffs(void) { return (int)find("gravity")->in[1].size; }

int rccl_vector_trig(int on)
{
#ifdef RCCL_VECTOR_TRIG
    /* as the extension's init does (kin_runtime.h) */
    vtrig_init(on);
    return have_vector_trig;
#else
    (void)on;
    return 0;
#endif
}

/* one kernel over n rows through its generated batched loop (one input besides q at most) */
static void rows(const char *name, long n, const double *q, const double *c, double *out)
{
    const kernel_entry *k = find(name);
    const double *in[2] = {q, c};
    const Py_ssize_t is[2] = {k->in[0].size, 0};   /* c: the same for every row */
    double *outs[1] = {out};
    const Py_ssize_t os[1] = {k->out[0].size};
    k->fn((Py_ssize_t)n, in, is, outs, os);
}

void rccl_fk_one(const double *q, double *T) { batch_fk(1, (const double *const[]){q}, (const Py_ssize_t[]){NJ}, (double *const[]){T}, (const Py_ssize_t[]){16}); }
void rccl_jacobian6_one(const double *q, double *J) { batch_jacobian6(1, (const double *const[]){q}, (const Py_ssize_t[]){NJ}, (double *const[]){J}, (const Py_ssize_t[]){6 * NJ}); }
void rccl_jacobian4_one(const double *q, double *J) { batch_jacobian4(1, (const double *const[]){q}, (const Py_ssize_t[]){NJ}, (double *const[]){J}, (const Py_ssize_t[]){6 * NJ}); }
void rccl_gravity_one(const double *q, const double *c, double *tau)
{
    batch_gravity(1, (const double *const[]){q, c}, (const Py_ssize_t[]){NJ, 0}, (double *const[]){tau}, (const Py_ssize_t[]){NJ});
}

void rccl_fk_rows(long n, const double *q, double *T) { rows("fk", n, q, NULL, T); }
void rccl_jacobian6_rows(long n, const double *q, double *J) { rows("jacobian6", n, q, NULL, J); }
void rccl_jacobian4_rows(long n, const double *q, double *J) { rows("jacobian4", n, q, NULL, J); }
void rccl_gravity_rows(long n, const double *q, const double *c, double *tau) { rows("gravity", n, q, c, tau); }

void rccl_inverse_dynamics_one(const double *q, const double *qd, const double *qdd, double *tau)
{
    batch_inverse_dynamics(1, (const double *const[]){q, qd, qdd}, (const Py_ssize_t[]){NJ, NJ, NJ},
                           (double *const[]){tau}, (const Py_ssize_t[]){NJ});
}
void rccl_inertia_matrix_one(const double *q, double *D)
{
    batch_inertia_matrix(1, (const double *const[]){q}, (const Py_ssize_t[]){NJ}, (double *const[]){D}, (const Py_ssize_t[]){NJ * NJ});
}
void rccl_inverse_dynamics_rows(long n, const double *q, const double *qd, const double *qdd, double *tau)
{
    const kernel_entry *k = find("inverse_dynamics");
    const double *in[3] = {q, qd, qdd};
    const Py_ssize_t is[3] = {NJ, NJ, NJ};
    double *outs[1] = {tau};
    const Py_ssize_t os[1] = {NJ};
    k->fn((Py_ssize_t)n, in, is, outs, os);
}
void rccl_inertia_matrix_rows(long n, const double *q, double *D) { rows("inertia_matrix", n, q, NULL, D); }
