// The generated C kernels of one robot against Pinocchio's C++ on the same configurations,
// in one process, one thread (bench/cpp_pinocchio.py builds and runs it; see there).
//
//   vs_pinocchio MODEL Q.bin C.bin REPEATS [RESULTS.bin]
//
// MODEL    the robot's Pinocchio model as Pinocchio's URDF parser built it from
//          models/urdf/<robot>.urdf (bench/cpp_pinocchio.py model_text): one line per joint
//          `joint NAME TYPE AX AY AZ PARENT R(9, row-major) P(3) MASS LEVER(3) I(xx xy yy xz yz zz)`
//          and per frame `frame NAME PARENT_JOINT R(9) P(3)`, rebuilt here with addJoint,
//          appendBodyToJoint and addFrame (the parser's own header costs most of a compile)
// Q.bin    N configurations, N x NJ doubles (rad, m), row-major, native byte order
//
// Built per robot: -DNJ=<joint count> (6 for the thesis's arms, 7 for the Panda) and
// -DEND_FRAME="link<NJ>" (the last link's frame, where the generated fk and Jacobian end).
// C.bin    the gravity coefficients of the generated gravity kernel (doubles)
// REPEATS  rounds: each timing is the best of its passes over the N configurations, one per
//          round; a round runs every pass once, in turn
// RESULTS  optional: per configuration, Pinocchio's then the kernel's T (16), the Jacobian in
//          END_FRAME (6 NJ), in frame 4's axes (6 NJ), gravity (NJ), inverse dynamics (NJ) and
//          the inertia matrix (NJ NJ), row-major doubles, for the agreement test
//
// Prints one line per timing: `<computation> <implementation> <ns per configuration>`.
// What is compared (Pinocchio side):
//   fk        forwardKinematics(q) + updateFramePlacement(END_FRAME): T6 = data.oMf[link6]
//             for a six-joint arm
//   jacobian6 computeFrameJacobian(q, END_FRAME, LOCAL): Paul's frame-6 Jacobian 6J (six joints)
//   jacobian4 the thesis's link-4 Jacobian 4J: that Jacobian with both 3-row blocks rotated
//             into frame 4 (R46 = oMf[link4].R^T oMf[END_FRAME].R; updateFramePlacement of
//             link4 and END_FRAME after the Jacobian pass)
//   gravity   computeGeneralizedGravity(q)
//   inverse_dynamics  rnea(q, qd, qdd); inertia_matrix  crba(q) (its upper triangle, which
//             is what Pinocchio fills; the generated kernel writes all NJ x NJ entries)
//   (qd, qdd: fixed functions of q, the same for both sides)
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/jacobian.hpp>
#include <pinocchio/algorithm/kinematics.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/multibody.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <iostream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "kernel_rows.h"

#ifndef NJ
#error "NJ (the robot's joint count) must be defined: bench/cpp_pinocchio.py passes -DNJ=<n>"
#endif
#ifndef END_FRAME
#error "END_FRAME (the last link's frame name) must be defined: bench/cpp_pinocchio.py passes it"
#endif

namespace {

using Clock = std::chrono::steady_clock;
using RowMajorJ = Eigen::Matrix<double, 6, NJ, Eigen::RowMajor>;
using ColN = Eigen::Matrix<double, NJ, 1>;
using MatN = Eigen::Matrix<double, NJ, NJ>;
using RowMajorN = Eigen::Matrix<double, NJ, NJ, Eigen::RowMajor>;
// the largest result of one configuration (T 16, a Jacobian 6 NJ, the inertia matrix NJ NJ)
constexpr int ROW = (NJ * NJ > 16 ? NJ * NJ : 16) > 6 * NJ ? (NJ * NJ > 16 ? NJ * NJ : 16) : 6 * NJ;
using RowMajor4 = Eigen::Matrix<double, 4, 4, Eigen::RowMajor>;
#ifdef PINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION
// The agreement-only build (bench/cpp_pinocchio.py CHECK): the algorithms the wheel's
// libraries instantiate take an Eigen::VectorXd; a copy of each configuration into one
// lets this program use them instead of compiling its own (most of the compile time).
using QArg = Eigen::VectorXd;
#else
// The timed build: the configuration read in place, the algorithms compiled here at -O3.
using QArg = Eigen::Map<const ColN>;
#endif

std::vector<double> read_doubles(const std::string &path)
{
    std::ifstream in(path, std::ios::binary | std::ios::ate);
    if (!in) throw std::runtime_error("cannot read " + path);
    const std::streamsize bytes = in.tellg();
    if (bytes % sizeof(double) != 0) throw std::runtime_error(path + ": size is not a whole number of doubles");
    std::vector<double> v(bytes / sizeof(double));
    in.seekg(0);
    in.read(reinterpret_cast<char *>(v.data()), bytes);
    return v;
}

pinocchio::SE3 read_se3(std::istream &in)
{
    Eigen::Matrix<double, 3, 3, Eigen::RowMajor> r;
    Eigen::Vector3d p;
    for (int i = 0; i < 9; ++i) in >> r.data()[i];
    for (int i = 0; i < 3; ++i) in >> p[i];
    return pinocchio::SE3(Eigen::Matrix3d(r), p);
}

// The joint model of a parsed model's joint: its type (Pinocchio's shortname) and axis.
pinocchio::JointModel joint_model(const std::string &type, const Eigen::Vector3d &axis)
{
    if (type == "JointModelRX") return pinocchio::JointModelRX();
    if (type == "JointModelRY") return pinocchio::JointModelRY();
    if (type == "JointModelRZ") return pinocchio::JointModelRZ();
    if (type == "JointModelRevoluteUnaligned") return pinocchio::JointModelRevoluteUnaligned(axis);
    if (type == "JointModelPX") return pinocchio::JointModelPX();
    if (type == "JointModelPY") return pinocchio::JointModelPY();
    if (type == "JointModelPZ") return pinocchio::JointModelPZ();
    if (type == "JointModelPrismaticUnaligned") return pinocchio::JointModelPrismaticUnaligned(axis);
    throw std::runtime_error("joint type " + type + " is not one this program rebuilds");
}

// The model file of bench/cpp_pinocchio.py (see the top of this file) into `model`.
void read_model(const std::string &path, pinocchio::Model &model)
{
    std::ifstream file(path);
    if (!file) throw std::runtime_error("cannot read " + path);
    std::string line;
    int lineno = 0;
    while (std::getline(file, line)) {
        ++lineno;
        std::istringstream in(line);
        std::string kind, name;
        in >> kind >> name;
        if (kind == "joint") {
            std::string type;
            Eigen::Vector3d axis, lever;
            pinocchio::JointIndex parent;
            in >> type >> axis[0] >> axis[1] >> axis[2] >> parent;
            const pinocchio::SE3 placement = read_se3(in);
            double mass, i[6];
            in >> mass >> lever[0] >> lever[1] >> lever[2];
            for (double &x : i) in >> x;
            if (!in) throw std::runtime_error(path + ":" + std::to_string(lineno) + ": not a joint line");
            const pinocchio::JointIndex j = model.addJoint(parent, joint_model(type, axis), placement, name);
            model.appendBodyToJoint(j, pinocchio::Inertia(mass, lever, pinocchio::Symmetric3(i[0], i[1], i[2], i[3], i[4], i[5])),
                                    pinocchio::SE3::Identity());
        } else if (kind == "frame") {
            pinocchio::JointIndex parent;
            in >> parent;
            const pinocchio::SE3 placement = read_se3(in);
            if (!in) throw std::runtime_error(path + ":" + std::to_string(lineno) + ": not a frame line");
            model.addFrame(pinocchio::Frame(name, parent, placement, pinocchio::BODY));
        } else if (!kind.empty()) {
            throw std::runtime_error(path + ":" + std::to_string(lineno) + ": unknown line kind " + kind);
        }
    }
}

// One timed pass over all N configurations: what is computed and by whom.
struct Pass {
    const char *what;
    const char *who;
    std::function<void()> run;
};

// Best seconds per configuration of every pass over `repeats` rounds; a round runs every
// pass once, in turn (after one warm-up round: caches, branch predictors, first touch).
std::vector<double> best_per_config(int repeats, long n, const std::vector<Pass> &passes)
{
    std::vector<double> best(passes.size(), std::numeric_limits<double>::infinity());
    for (const Pass &p : passes) p.run();
    for (int r = 0; r < repeats; ++r)
        for (std::size_t i = 0; i < passes.size(); ++i) {
            const auto t0 = Clock::now();
            passes[i].run();
            const std::chrono::duration<double> dt = Clock::now() - t0;
            best[i] = std::min(best[i], dt.count() / double(n));
        }
    return best;
}

// The link-4 Jacobian from Pinocchio's END_FRAME one (rows v then omega, as Paul's 6J).
RowMajorJ jacobian4_from(const pinocchio::Data &data, pinocchio::FrameIndex f4, pinocchio::FrameIndex f6,
                         const pinocchio::Data::Matrix6x &j6)
{
    const Eigen::Matrix3d r46 = data.oMf[f4].rotation().transpose() * data.oMf[f6].rotation();
    RowMajorJ j4;
    j4.topRows<3>().noalias() = r46 * j6.topRows<3>();
    j4.bottomRows<3>().noalias() = r46 * j6.bottomRows<3>();
    return j4;
}

}  // namespace

int main(int argc, char **argv)
{
    if (argc < 5 || argc > 6) {
        std::fprintf(stderr, "usage: %s MODEL Q.bin C.bin REPEATS [RESULTS.bin]\n", argv[0]);
        return 2;
    }
    try {
        pinocchio::Model model;
        read_model(argv[1], model);
        pinocchio::Data data(model);
        if (model.nq != NJ || model.nv != NJ)
            throw std::runtime_error(std::string(argv[1]) + ": this program is built for " + std::to_string(NJ)
                                     + " joint variables, Pinocchio finds nq = " + std::to_string(model.nq));
        const pinocchio::FrameIndex f6 = model.getFrameId(END_FRAME), f4 = model.getFrameId("link4");
        if (f6 >= model.frames.size() || f4 >= model.frames.size())
            throw std::runtime_error(std::string(argv[1]) + ": no frame link4 or " END_FRAME);
        const std::vector<double> q = read_doubles(argv[2]);
        const std::vector<double> c = read_doubles(argv[3]);
        const int repeats = std::atoi(argv[4]);
        if (q.empty() || q.size() % NJ != 0)
            throw std::runtime_error(std::string(argv[2]) + ": not N x " + std::to_string(NJ) + " doubles");
        if (int(c.size()) != rccl_gravity_ncoeffs())
            throw std::runtime_error(std::string(argv[3]) + ": " + std::to_string(c.size()) + " coefficients, the "
                                     + rccl_robot() + " gravity kernel takes " + std::to_string(rccl_gravity_ncoeffs()));
        if (repeats < 1) throw std::runtime_error("REPEATS must be >= 1");
        const long n = long(q.size() / NJ);
        auto qi = [&](long i) { return QArg(Eigen::Map<const ColN>(q.data() + NJ * i)); };

        const int vector_trig = rccl_vector_trig(1);
        std::printf("vector_trig - %d\n", vector_trig);
        std::printf("configurations - %ld\n", n);

        pinocchio::Data::Matrix6x j6 = pinocchio::Data::Matrix6x::Zero(6, model.nv);
        double sink = 0.0;  // every result feeds it, so no pass is optimised away
        std::vector<double> out(std::size_t(n) * ROW);
        double row[ROW];

        // Every pass of every side, then the best of `repeats` rounds, each round running them
        // all in turn: both sides see the same moments of a loaded machine.
        std::vector<Pass> passes;
        // ---- FK
        passes.push_back({"fk", "pinocchio", [&] {
                   for (long i = 0; i < n; ++i) {
                       pinocchio::forwardKinematics(model, data, qi(i));
                       sink += pinocchio::updateFramePlacement(model, data, f6).translation()[0];
                   }
               }});
        passes.push_back({"fk", "c_one", [&] {
                   for (long i = 0; i < n; ++i) {
                       rccl_fk_one(q.data() + NJ * i, row);
                       sink += row[3];
                   }
               }});
        passes.push_back({"fk", "c_rows", [&] {
                   rccl_fk_rows(n, q.data(), out.data());
                   sink += out[3];
               }});

        // ---- 6J
        passes.push_back({"jacobian6", "pinocchio", [&] {
                   for (long i = 0; i < n; ++i) {
                       pinocchio::computeFrameJacobian(model, data, qi(i), f6, pinocchio::LOCAL, j6);
                       sink += j6(0, 0);
                   }
               }});
        passes.push_back({"jacobian6", "c_one", [&] {
                   for (long i = 0; i < n; ++i) {
                       rccl_jacobian6_one(q.data() + NJ * i, row);
                       sink += row[0];
                   }
               }});
        passes.push_back({"jacobian6", "c_rows", [&] {
                   rccl_jacobian6_rows(n, q.data(), out.data());
                   sink += out[0];
               }});

        // ---- 4J
        passes.push_back({"jacobian4", "pinocchio", [&] {
                   for (long i = 0; i < n; ++i) {
                       pinocchio::computeFrameJacobian(model, data, qi(i), f6, pinocchio::LOCAL, j6);
                       pinocchio::updateFramePlacement(model, data, f4);
                       pinocchio::updateFramePlacement(model, data, f6);
                       sink += jacobian4_from(data, f4, f6, j6)(0, 0);
                   }
               }});
        passes.push_back({"jacobian4", "c_one", [&] {
                   for (long i = 0; i < n; ++i) {
                       rccl_jacobian4_one(q.data() + NJ * i, row);
                       sink += row[0];
                   }
               }});
        passes.push_back({"jacobian4", "c_rows", [&] {
                   rccl_jacobian4_rows(n, q.data(), out.data());
                   sink += out[0];
               }});

        // ---- gravity
        passes.push_back({"gravity", "pinocchio", [&] {
                   for (long i = 0; i < n; ++i)
                       sink += pinocchio::computeGeneralizedGravity(model, data, qi(i))[1];
               }});
        passes.push_back({"gravity", "c_one", [&] {
                   for (long i = 0; i < n; ++i) {
                       rccl_gravity_one(q.data() + NJ * i, c.data(), row);
                       sink += row[1];
                   }
               }});
        passes.push_back({"gravity", "c_rows", [&] {
                   rccl_gravity_rows(n, q.data(), c.data(), out.data());
                   sink += out[1];
               }});

        // ---- dynamics (eq. 4.6): rates and accelerations, fixed functions of q
        std::vector<double> qd(q.size()), qdd(q.size());
        for (std::size_t i = 0; i < q.size(); ++i) {
            qd[i] = std::sin(q[i] + 1.0);
            qdd[i] = 2.0 * std::cos(1.5 * q[i]);
        }
        auto vi = [&](const std::vector<double> &v, long i) {
            return QArg(Eigen::Map<const ColN>(v.data() + NJ * i));
        };
        passes.push_back({"inverse_dynamics", "pinocchio", [&] {
                   for (long i = 0; i < n; ++i)
                       sink += pinocchio::rnea(model, data, qi(i), vi(qd, i), vi(qdd, i))[1];
               }});
        passes.push_back({"inverse_dynamics", "c_one", [&] {
                   for (long i = 0; i < n; ++i) {
                       rccl_inverse_dynamics_one(q.data() + NJ * i, qd.data() + NJ * i, qdd.data() + NJ * i, row);
                       sink += row[1];
                   }
               }});
        passes.push_back({"inverse_dynamics", "c_rows", [&] {
                   rccl_inverse_dynamics_rows(n, q.data(), qd.data(), qdd.data(), out.data());
                   sink += out[1];
               }});
        passes.push_back({"inertia_matrix", "pinocchio", [&] {
                   for (long i = 0; i < n; ++i)
                       sink += pinocchio::crba(model, data, qi(i))(0, 1);
               }});
        passes.push_back({"inertia_matrix", "c_one", [&] {
                   for (long i = 0; i < n; ++i) {
                       rccl_inertia_matrix_one(q.data() + NJ * i, row);
                       sink += row[1];
                   }
               }});
        passes.push_back({"inertia_matrix", "c_rows", [&] {
                   rccl_inertia_matrix_rows(n, q.data(), out.data());
                   sink += out[1];
               }});

        const std::vector<double> best = best_per_config(repeats, n, passes);
        for (std::size_t i = 0; i < passes.size(); ++i)
            std::printf("%s %s %.6g\n", passes[i].what, passes[i].who, best[i] * 1e9);

        if (argc == 6) {  // the results themselves, single-configuration paths
            std::ofstream res(argv[5], std::ios::binary);
            auto put = [&](const double *v, int len) { res.write(reinterpret_cast<const char *>(v), len * sizeof(double)); };
            for (long i = 0; i < n; ++i) {
                pinocchio::forwardKinematics(model, data, qi(i));
                const RowMajor4 t = pinocchio::updateFramePlacement(model, data, f6).toHomogeneousMatrix();
                put(t.data(), 16);
                rccl_fk_one(q.data() + NJ * i, row);
                put(row, 16);
                pinocchio::computeFrameJacobian(model, data, qi(i), f6, pinocchio::LOCAL, j6);
                const RowMajorJ j6r = j6;
                put(j6r.data(), 6 * NJ);
                rccl_jacobian6_one(q.data() + NJ * i, row);
                put(row, 6 * NJ);
                pinocchio::updateFramePlacement(model, data, f4);
                pinocchio::updateFramePlacement(model, data, f6);
                const RowMajorJ j4 = jacobian4_from(data, f4, f6, j6);
                put(j4.data(), 6 * NJ);
                rccl_jacobian4_one(q.data() + NJ * i, row);
                put(row, 6 * NJ);
                const ColN g = pinocchio::computeGeneralizedGravity(model, data, qi(i));
                put(g.data(), NJ);
                rccl_gravity_one(q.data() + NJ * i, c.data(), row);
                put(row, NJ);
                const ColN torques = pinocchio::rnea(model, data, qi(i), vi(qd, i), vi(qdd, i));
                put(torques.data(), NJ);
                rccl_inverse_dynamics_one(q.data() + NJ * i, qd.data() + NJ * i, qdd.data() + NJ * i, row);
                put(row, NJ);
                MatN mm = pinocchio::crba(model, data, qi(i));
                mm.triangularView<Eigen::StrictlyLower>() = mm.transpose();
                const RowMajorN md = mm;
                put(md.data(), NJ * NJ);
                rccl_inertia_matrix_one(q.data() + NJ * i, row);
                put(row, NJ * NJ);
            }
            if (!res) throw std::runtime_error(std::string("cannot write ") + argv[5]);
        }
        std::printf("sink - %.17g\n", sink);
    } catch (const std::exception &e) {
        std::fprintf(stderr, "vs_pinocchio: %s\n", e.what());
        return 1;
    }
    return 0;
}
