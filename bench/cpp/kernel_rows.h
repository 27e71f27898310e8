/* The generated C kernels of one robot as plain C functions, for bench/cpp/vs_pinocchio.cpp.
 * kernel_rows.c defines them around the robot's generated rccl/kinematics/_c/<robot>.c
 * (its kernels only, without the CPython runtime), compiled with -DNJ=<the robot's joint
 * count n> (6 for the thesis's arms, 7 for the Panda). Arrays are row-major doubles:
 * q[n] joint variables (rad, m), T[16] = the last link's frame (link n) in the base frame (m),
 * J[6n] = the Jacobian in frame n or in frame 4's axes (rows dx dy dz dx_rot dy_rot dz_rot,
 * columns joints 1-n), c[] the robot's gravity coefficients, tau[n] gravity torques (N m, N). */
#ifndef RCCL_BENCH_KERNEL_ROWS_H
#define RCCL_BENCH_KERNEL_ROWS_H
#ifdef __cplusplus
extern "C" {
#endif

/* The robot's name and its number of gravity coefficients (the gravity kernel's c). */
const char *rccl_robot(void);
int rccl_gravity_ncoeffs(void);

/* 1 when the sines and cosines run four at a time with AVX2+FMA (as the extension does on
 * this CPU), 0 when they are libm's; `on` = 0 forces libm, 1 asks for AVX2+FMA if the CPU has it. */
int rccl_vector_trig(int on);

/* One configuration: the code path a single call of the extension runs. */
void rccl_fk_one(const double *q, double *T);
void rccl_jacobian6_one(const double *q, double *J);
void rccl_jacobian4_one(const double *q, double *J);
void rccl_gravity_one(const double *q, const double *c, double *tau);

/* n configurations (rows of q), one thread: the batched loop of the extension (blocks of
 * rows with their sines and cosines computed together). The same c for every row. */
void rccl_fk_rows(long n, const double *q, double *T);
void rccl_jacobian6_rows(long n, const double *q, double *J);
void rccl_jacobian4_rows(long n, const double *q, double *J);
void rccl_gravity_rows(long n, const double *q, const double *c, double *tau);

/* The dynamics (thesis eq. 4.6): qd[n], qdd[n] joint rates and accelerations, tau[n] the
 * rigid-body joint torques of the data file's inertials, D[n*n] the inertia matrix. */
void rccl_inverse_dynamics_one(const double *q, const double *qd, const double *qdd, double *tau);
void rccl_inertia_matrix_one(const double *q, double *D);
void rccl_inverse_dynamics_rows(long n, const double *q, const double *qd, const double *qdd, double *tau);
void rccl_inertia_matrix_rows(long n, const double *q, double *D);

#ifdef __cplusplus
}
#endif
#endif
