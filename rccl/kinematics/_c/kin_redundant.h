/* The fast public entries of a redundant 7-joint arm's inverse kinematics (q7 free),
 * hand-written: ik(T, config, q_ref=None, q7=...) and ik_all(T, q7, q_ref=None) as
 * rccl.kinematics.redundant_ik defines them, with its checks done here: the pose (rigid),
 * q7 (finite, inside joint 7's range), q_ref, the guards, each joint's 2 pi branch into its
 * range (or nearest q_ref), the fk check (every returned q reproduces T within the runtime's
 * REPRODUCE_TOL, by the module's own fk kernel) and, for ik_all, duplicates dropped (first
 * kept). Whenever anything is off (an error to name, a singular branch, other argument
 * forms) the entry calls the Python runtime, which decides and builds the message: the
 * compiled and the Python paths give the same results. Included by kin_runtime.h inside its
 * numpy part; active after redundant_setup (rccl.kinematics.backend.public_redundant_ik). */
#ifndef RCCL_KIN_REDUNDANT_H
#define RCCL_KIN_REDUNDANT_H

#define RN 7          /* joints */
#define RMAXCONF 16   /* configurations */
#define RMAXGUARD 16  /* guards per configuration */

static struct {
    int ready, ik, ik_all, fk;                    /* kernel indices */
    PyObject *config_type, *fields, *configs;     /* Config class, its field names, Config.all() */
    int nfield, nconf, nguard;
    double lower[RN], upper[RN];                  /* joint ranges (rad) */
    int singular[RMAXGUARD];                      /* 1: the guard's failure is Singular, else Unreachable */
    double rigid_tol, same_tol, range_tol, reproduce_tol;
} RIK = {0, -1, -1, -1, NULL, NULL, NULL, 0, 0, 0, {0}, {0}, {0}, 0, 0, 0, 0};

static int n_floats(PyObject *seq, double *v, int n, const char *what)
{
    PyObject *f = PySequence_Fast(seq, what);
    if (!f) return -1;
    if (PySequence_Fast_GET_SIZE(f) != n) { Py_DECREF(f); PyErr_Format(PyExc_ValueError, "%s: need %d values", what, n); return -1; }
    for (int j = 0; j < n; ++j) {
        v[j] = PyFloat_AsDouble(PySequence_Fast_GET_ITEM(f, j));
        if (v[j] == -1.0 && PyErr_Occurred()) { Py_DECREF(f); return -1; }
    }
    Py_DECREF(f);
    return 0;
}

/* redundant_setup(Config, fields, configs, lower (7), upper (7), singular guard flags,
 * rigid tol, same-solution tol, range tol (rad), reproduce tol); False when the module's
 * kernels lack the layout the entries need (then they are not used) */
static PyObject *redundant_setup(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *ct, *fields, *configs, *lo, *hi, *sing;
    double rigid, same, range, repro;
    if (!PyArg_ParseTuple(args, "OO!O!OOO!dddd:redundant_setup", &ct, &PyTuple_Type, &fields, &PyTuple_Type,
                          &configs, &lo, &hi, &PyTuple_Type, &sing, &rigid, &same, &range, &repro)) return NULL;
    const int nfield = (int)PyTuple_GET_SIZE(fields), nconf = (int)PyTuple_GET_SIZE(configs);
    const int nguard = (int)PyTuple_GET_SIZE(sing);
    if (nfield < 1 || nconf != (1 << nfield) || nconf > RMAXCONF || nguard > RMAXGUARD) {
        PyErr_SetString(PyExc_ValueError, "redundant_setup: need 1..4 fields, 2**fields configurations, <= 16 guards");
        return NULL;
    }
    if (n_floats(lo, RIK.lower, RN, "redundant_setup lower") < 0 || n_floats(hi, RIK.upper, RN, "redundant_setup upper") < 0)
        return NULL;
    for (int g = 0; g < nguard; ++g) RIK.singular[g] = PyObject_IsTrue(PyTuple_GET_ITEM(sing, g)) == 1;
    const int ik = kernel_index("ik"), all = kernel_index("ik_all"), fk = kernel_index("fk");
    const int ok = ik >= 0 && all >= 0 && fk >= 0
        && KERNELS[ik].nin == 3 && KERNELS[ik].in[0].size == 16 && KERNELS[ik].in[1].size == 1
        && KERNELS[ik].in[2].size == nfield && KERNELS[ik].out[0].size == RN && KERNELS[ik].nguard == nguard
        && KERNELS[ik].nout == 1 + nguard
        && KERNELS[all].nin == 2 && KERNELS[all].in[0].size == 16 && KERNELS[all].in[1].size == 1
        && KERNELS[all].nout == 2 && KERNELS[all].out[0].size == RN * nconf && KERNELS[all].out[1].size == nguard * nconf
        && KERNELS[fk].nin == 1 && KERNELS[fk].in[0].size == RN && KERNELS[fk].out[0].size == 16;
    if (!ok) Py_RETURN_FALSE;
    RIK.ik = ik; RIK.ik_all = all; RIK.fk = fk;
    RIK.nfield = nfield; RIK.nconf = nconf; RIK.nguard = nguard;
    Py_XSETREF(RIK.config_type, Py_NewRef(ct));
    Py_XSETREF(RIK.fields, Py_NewRef(fields));
    Py_XSETREF(RIK.configs, Py_NewRef(configs));
    RIK.rigid_tol = rigid; RIK.same_tol = same; RIK.range_tol = range; RIK.reproduce_tol = repro;
    RIK.ready = 1;
    Py_RETURN_TRUE;
}

/* the arguments of a call by name: positional ones in `names` order, then keywords;
 * 0 for any other form (an unknown or repeated keyword, too many arguments) */
static int bind_args(PyObject *const *args, Py_ssize_t nargs, PyObject *kwnames, const char *const *names,
                     int n, PyObject **slot)
{
    for (int i = 0; i < n; ++i) slot[i] = NULL;
    if (nargs > n) return 0;
    for (Py_ssize_t i = 0; i < nargs; ++i) slot[i] = args[i];
    const Py_ssize_t nkw = kwnames ? PyTuple_GET_SIZE(kwnames) : 0;
    for (Py_ssize_t k = 0; k < nkw; ++k) {
        int i = 0;
        while (i < n && PyUnicode_CompareWithASCIIString(PyTuple_GET_ITEM(kwnames, k), names[i]) != 0) ++i;
        if (i == n || slot[i]) return 0;
        slot[i] = args[nargs + k];
    }
    return 1;
}

/* q7 (rad) from a Python float or int, finite and inside joint 7's range; 0 otherwise */
static int free_value(PyObject *x, double *v)
{
    if (!x || !(PyFloat_Check(x) || PyLong_CheckExact(x))) return 0;
    *v = PyFloat_AsDouble(x);
    if (*v == -1.0 && PyErr_Occurred()) { PyErr_Clear(); return 0; }
    return isfinite(*v) && *v >= RIK.lower[RN - 1] - RIK.range_tol && *v <= RIK.upper[RN - 1] + RIK.range_tol;
}

/* the pose when x is a plain (4, 4) float64 array, finite, last row 0 0 0 1, rotation
 * orthonormal within half the rigid tolerance, det > 0; NULL otherwise */
static const double *redundant_pose(const double *t)
{
    return pose_within(t, RIK.rigid_tol) ? t : NULL;
}

/* q_ref as NULL (None) or a plain finite (7,) array; *ok = 0 otherwise */
static const double *redundant_ref(PyObject *x, int *ok)
{
    *ok = 1;
    if (!x || x == Py_None) return NULL;
    PyArrayObject *a = plain_array(x);
    if (!a || PyArray_NDIM(a) != 1 || PyArray_DIM(a, 0) != RN || !all_finite((const double *)PyArray_DATA(a), RN)) {
        *ok = 0;
        return NULL;
    }
    return (const double *)PyArray_DATA(a);
}

/* redundant_ik.RedundantRobot._in_range for one q: q_ref's 2 pi branch, then one turn up
 * or down into the range; 1 when every joint is in its range */
static int into_range(double *q, const double *ref)
{
    int ok = 1;
    for (int j = 0; j < RN; ++j) {
        double x = ref ? ref[j] + wrap_angle(q[j] - ref[j]) : q[j];
        if (x < RIK.lower[j] - RIK.range_tol) x += 2 * M_PI;
        if (x > RIK.upper[j] + RIK.range_tol) x -= 2 * M_PI;
        q[j] = x;
        ok &= x >= RIK.lower[j] - RIK.range_tol && x <= RIK.upper[j] + RIK.range_tol;
    }
    return ok;
}

/* 1 when fk(q) equals the pose t within the reproduce tolerance (rows 1-3: m and 1) */
static int reproduces(const double *q, const double *t)
{
    double tq[16];
    const double *ip[1] = {q};
    double *op[1] = {tq};
    static const Py_ssize_t zero[1] = {0};
    KERNELS[RIK.fk].fn(1, ip, zero, op, zero);
    for (int e = 0; e < 12; ++e)
        if (!(fabs(tq[e] - t[e]) <= RIK.reproduce_tol)) return 0;
    return 1;
}

/* ik(T, config, q_ref=None, q7=...) for one pose */
static PyObject *rfast_ik(PyObject *fallback, PyObject *const *args, Py_ssize_t nargs, PyObject *kwnames)
{
    static const char *const names[4] = {"T", "config", "q_ref", "q7"};
    PyObject *a[4];
    int ok;
    double q7, signs[8], q[RN], guard[RMAXGUARD];
    if (!RIK.ready || !bind_args(args, nargs, kwnames, names, 4, a) || !a[0] || !a[1] || !free_value(a[3], &q7))
        goto slow;
    PyArrayObject *pa = plain_array(a[0]);
    if (!pa || PyArray_NDIM(pa) != 2 || PyArray_DIM(pa, 0) != 4 || PyArray_DIM(pa, 1) != 4) goto slow;
    const double *t = redundant_pose((const double *)PyArray_DATA(pa)), *ref = redundant_ref(a[2], &ok);
    if (!t || !ok || signs_of(a[1], RIK.config_type, RIK.fields, RIK.nfield, signs) < 0) goto slow;
    const kernel_entry *k = &KERNELS[RIK.ik];
    const double *ip[3] = {t, &q7, signs};
    double *op[1 + RMAXGUARD];
    static const Py_ssize_t zero[1 + RMAXGUARD] = {0};
    op[0] = q;
    for (int g = 0; g < k->nguard; ++g) op[1 + g] = &guard[g];
    k->fn(1, ip, zero, op, zero);
    for (int g = 0; g < k->nguard; ++g) if (!(guard[g] >= 0)) goto slow;   /* Unreachable / Singular: messages */
    if (!all_finite(q, RN) || !into_range(q, ref) || !reproduces(q, t)) goto slow;
    return new_vector(q, RN);
slow:
    return PyObject_Vectorcall(fallback, args, (size_t)nargs, kwnames);
}

/* every distinct solution of one pose and q7: a new list of (Config, q), or NULL with
 * *slow = 1 when the Python path must decide (a reachable branch failing a singularity
 * guard or giving no finite q, a solution missing the pose) */
static PyObject *rik_all_one(const double *t, double q7, const double *ref, int *slow)
{
    const int nc = RIK.nconf, ng = RIK.nguard;
    double q[RMAXCONF * RN], g[RMAXCONF * RMAXGUARD];
    int kept[RMAXCONF], nkept = 0;
    *slow = 1;
    if (!redundant_pose(t)) return NULL;
    const double *ip[2] = {t, &q7};
    double *op[2] = {q, g};
    static const Py_ssize_t zero[2] = {0, 0};
    KERNELS[RIK.ik_all].fn(1, ip, zero, op, zero);
    for (int j = 0; j < nc; ++j) {
        double *qj = q + RN * j;
        int reach = 1, guards = 1;
        for (int c = 0; c < ng; ++c) {
            const int pass = g[j * ng + c] >= 0;
            guards &= pass;
            if (!RIK.singular[c]) reach &= pass;
        }
        if (!(guards && all_finite(qj, RN))) {
            if (reach) return NULL;          /* reachable but singular: the runtime raises Singular */
            continue;                        /* unreachable branch: left out */
        }
        if (!into_range(qj, ref)) continue;  /* outside a joint range: left out */
        if (!reproduces(qj, t)) return NULL; /* the runtime raises KinematicsError */
        int dup = 0;
        for (int m = 0; m < nkept && !dup; ++m) {
            int same = 1;
            for (int c = 0; c < RN && same; ++c) same = fabs(wrap_angle(qj[c] - q[RN * kept[m] + c])) < RIK.same_tol;
            dup = same;
        }
        if (!dup) kept[nkept++] = j;
    }
    *slow = 0;
    PyObject *list = PyList_New(nkept);
    if (!list) return NULL;
    for (int m = 0; m < nkept; ++m) {
        PyObject *v = new_vector(q + RN * kept[m], RN);
        PyObject *pair = v ? PyTuple_Pack(2, PyTuple_GET_ITEM(RIK.configs, kept[m]), v) : NULL;
        Py_XDECREF(v);
        if (!pair) { Py_DECREF(list); return NULL; }
        PyList_SET_ITEM(list, m, pair);
    }
    return list;
}

/* ik_all(T, q7, q_ref=None) for one pose (4, 4), or a batch (N, 4, 4) with q7 a float or a
 * plain (N,) array and q_ref None or (N, 7); a batch goes to the Python path as a whole
 * when any of its rows must */
static PyObject *rfast_ik_all(PyObject *fallback, PyObject *const *args, Py_ssize_t nargs, PyObject *kwnames)
{
    static const char *const names[3] = {"T", "q7", "q_ref"};
    PyObject *a[3];
    int ok, slow;
    double q7 = 0;
    if (!RIK.ready || !bind_args(args, nargs, kwnames, names, 3, a) || !a[0] || !a[1]) goto slow;
    PyArrayObject *pa = plain_array(a[0]);
    if (!pa) goto slow;
    if (PyArray_NDIM(pa) == 2) {
        if (PyArray_DIM(pa, 0) != 4 || PyArray_DIM(pa, 1) != 4 || !free_value(a[1], &q7)) goto slow;
        const double *ref = redundant_ref(a[2], &ok);
        if (!ok) goto slow;
        PyObject *res = rik_all_one((const double *)PyArray_DATA(pa), q7, ref, &slow);
        if (slow) goto slow;
        return res;
    }
    if (PyArray_NDIM(pa) != 3 || PyArray_DIM(pa, 1) != 4 || PyArray_DIM(pa, 2) != 4 || PyArray_DIM(pa, 0) == 0) goto slow;
    const Py_ssize_t n = PyArray_DIM(pa, 0);
    const double *q7s = NULL, *refs = NULL;
    if (!free_value(a[1], &q7)) {
        PyArrayObject *v = plain_array(a[1]);
        if (!v || PyArray_NDIM(v) != 1 || PyArray_DIM(v, 0) != n) goto slow;
        q7s = (const double *)PyArray_DATA(v);
        for (Py_ssize_t i = 0; i < n; ++i)
            if (!(q7s[i] >= RIK.lower[RN - 1] - RIK.range_tol && q7s[i] <= RIK.upper[RN - 1] + RIK.range_tol)) goto slow;
    }
    if (a[2] && a[2] != Py_None) {
        PyArrayObject *r = plain_array(a[2]);
        if (!r || PyArray_NDIM(r) != 2 || PyArray_DIM(r, 0) != n || PyArray_DIM(r, 1) != RN) goto slow;
        refs = (const double *)PyArray_DATA(r);
        if (!all_finite(refs, RN * n)) goto slow;
    }
    const double *ts = (const double *)PyArray_DATA(pa);
    PyObject *out = PyList_New(n);
    if (!out) return NULL;
    for (Py_ssize_t i = 0; i < n; ++i) {
        PyObject *res = rik_all_one(ts + 16 * i, q7s ? q7s[i] : q7, refs ? refs + RN * i : NULL, &slow);
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

static PyMethodDef RIK_DEFS[] = {
    {"redundant_ik", (PyCFunction)(void (*)(void))rfast_ik, METH_FASTCALL | METH_KEYWORDS,
     "ik(T, config, q_ref=None, q7=...): fast entry for one float64 pose; anything else, and every error, via the runtime"},
    {"redundant_ik_all", (PyCFunction)(void (*)(void))rfast_ik_all, METH_FASTCALL | METH_KEYWORDS,
     "ik_all(T, q7, q_ref=None): fast entry for float64 poses (one or a batch); anything else, and every error, via the runtime"},
};

/* redundant_public(name, fallback): the fast entry "redundant_ik" or "redundant_ik_all"
 * over `fallback` (after redundant_setup returned True) */
static PyObject *redundant_public(PyObject *self, PyObject *args)
{
    (void)self;
    const char *name;
    PyObject *fallback;
    if (!PyArg_ParseTuple(args, "sO:redundant_public", &name, &fallback)) return NULL;
    if (!PyCallable_Check(fallback)) { PyErr_SetString(PyExc_TypeError, "redundant_public: fallback must be callable"); return NULL; }
    if (!RIK.ready) { PyErr_SetString(PyExc_RuntimeError, "redundant_public: redundant_setup has not succeeded"); return NULL; }
    for (int i = 0; i < (int)(sizeof RIK_DEFS / sizeof RIK_DEFS[0]); ++i)
        if (strcmp(RIK_DEFS[i].ml_name, name) == 0) return PyCFunction_NewEx(&RIK_DEFS[i], fallback, NULL);
    PyErr_Format(PyExc_KeyError, "redundant_public: no entry %s", name);
    return NULL;
}
#endif
