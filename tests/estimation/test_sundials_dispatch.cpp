// estimation/SundialsDispatch.cpp: the program's optimised copies of SUNDIALS' dispatch
// wrappers replace the library's (what CVODE calls) and give bit-identical results, including
// the fallbacks for vectors without fused operations (SUNRpowerR's square and fourth roots:
// within one ulp).
#include <dlfcn.h>

#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sundials/sundials_math.h>
#include <sundials/sundials_nonlinearsolver.h>
#include <sunnonlinsol/sunnonlinsol_fixedpoint.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

namespace {

// The library's own definition of `name` (the next one after this program's).
template <typename F>
F libraryVersion(const char* name) {
  void* next = dlsym(RTLD_NEXT, name);
  EXPECT_NE(next, nullptr) << name;
  return reinterpret_cast<F>(next);
}

bool sameBits(double a, double b) {
  return std::memcmp(&a, &b, sizeof a) == 0;
}

struct Vectors {
  SUNContext ctx = nullptr;
  std::vector<N_Vector> v;
  Vectors(int count, sunindextype n, bool fused, unsigned seed) {
    EXPECT_EQ(SUNContext_Create(nullptr, &ctx), 0);
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-3, 3);
    for (int i = 0; i < count; ++i) {
      v.push_back(N_VNew_Serial(n, ctx));
      N_VEnableFusedOps_Serial(v.back(), fused ? SUNTRUE : SUNFALSE);
      for (sunindextype k = 0; k < n; ++k) NV_Ith_S(v.back(), k) = u(rng) * std::exp(u(rng) * 5);
    }
  }
  ~Vectors() {
    for (auto x : v) N_VDestroy(x);
    SUNContext_Free(&ctx);
  }
  std::vector<double> data(int i) const {
    const double* d = NV_DATA_S(v[i]);
    return {d, d + NV_LENGTH_S(v[i])};
  }
};

void expectSameData(const std::vector<double>& a, const std::vector<double>& b, const char* what) {
  ASSERT_EQ(a.size(), b.size()) << what;
  for (size_t i = 0; i < a.size(); ++i)
    EXPECT_TRUE(sameBits(a[i], b[i])) << what << " [" << i << "]";
}

}  // namespace

TEST(SundialsDispatch, TheProgramsDefinitionsAreTheOnesCvodeCalls) {
  // The first definition in lookup order is the one the library's PLT binds to.
  for (const char* name :
       {"N_VLinearSum", "N_VConst", "N_VProd", "N_VScale", "N_VDotProd", "N_VWrmsNorm",
        "N_VGetArrayPointer", "N_VGetArrayPointer_Serial", "N_VLinearCombination",
        "N_VScaleAddMulti", "N_VScaleVectorArray", "SUNRpowerI", "SUNRpowerR", "SUNNonlinSolSolve",
        "SUNNonlinSolGetNumIters", "SUNNonlinSolGetCurIter", "SUNNonlinSolGetNumConvFails"}) {
    void* first = dlsym(RTLD_DEFAULT, name);
    void* library = dlsym(RTLD_NEXT, name);
    ASSERT_NE(first, nullptr) << name;
    ASSERT_NE(library, nullptr) << name;
    EXPECT_NE(first, library) << name << ": the library's unoptimised wrapper is still used";
  }
}

TEST(SundialsDispatch, VectorOperationsGiveTheLibrarysBits) {
  for (bool fused : {true, false}) {
    for (sunindextype n : {1, 7, 54, 90}) {
      Vectors mine(6, n, fused, 11 + n), lib(6, n, fused, 11 + n);
      auto& a = mine.v;
      auto& b = lib.v;
      N_VLinearSum(0.3, a[0], -1.7, a[1], a[2]);
      libraryVersion<void (*)(double, N_Vector, double, N_Vector, N_Vector)>("N_VLinearSum")(
          0.3, b[0], -1.7, b[1], b[2]);
      N_VLinearSum(1.0, a[2], 1.0, a[3], a[2]);  // aliased output, as CVODE's predictor
      libraryVersion<void (*)(double, N_Vector, double, N_Vector, N_Vector)>("N_VLinearSum")(
          1.0, b[2], 1.0, b[3], b[2]);
      N_VScale(-2.5e-3, a[3], a[4]);
      libraryVersion<void (*)(double, N_Vector, N_Vector)>("N_VScale")(-2.5e-3, b[3], b[4]);
      N_VProd(a[0], a[1], a[5]);
      libraryVersion<void (*)(N_Vector, N_Vector, N_Vector)>("N_VProd")(b[0], b[1], b[5]);
      for (int i = 0; i < 6; ++i) expectSameData(mine.data(i), lib.data(i), "single ops");

      double c[4] = {0.5, -1.25, 3.0e-4, 7.0};
      N_VLinearCombination(4, c, &a[0], a[4]);
      libraryVersion<int (*)(int, double*, N_Vector*, N_Vector)>("N_VLinearCombination")(
          4, c, &b[0], b[4]);
      N_VScaleAddMulti(2, c, a[5], &a[0], &a[2]);
      libraryVersion<int (*)(int, double*, N_Vector, N_Vector*, N_Vector*)>("N_VScaleAddMulti")(
          2, c, b[5], &b[0], &b[2]);
      N_VScaleVectorArray(2, c, &a[2], &a[2]);
      libraryVersion<int (*)(int, double*, N_Vector*, N_Vector*)>("N_VScaleVectorArray")(
          2, c, &b[2], &b[2]);
      for (int i = 0; i < 6; ++i) expectSameData(mine.data(i), lib.data(i), "fused ops");

      EXPECT_TRUE(sameBits(N_VWrmsNorm(a[2], a[3]), libraryVersion<double (*)(N_Vector, N_Vector)>(
                                                        "N_VWrmsNorm")(b[2], b[3])));
      EXPECT_TRUE(sameBits(N_VDotProd(a[4], a[5]), libraryVersion<double (*)(N_Vector, N_Vector)>(
                                                       "N_VDotProd")(b[4], b[5])));
      N_VConst(-0.0, a[1]);
      libraryVersion<void (*)(double, N_Vector)>("N_VConst")(-0.0, b[1]);
      expectSameData(mine.data(1), lib.data(1), "N_VConst");
      EXPECT_EQ(N_VGetArrayPointer(a[0]), NV_DATA_S(a[0]));
      EXPECT_EQ(libraryVersion<double* (*)(N_Vector)>("N_VGetArrayPointer")(a[0]), NV_DATA_S(a[0]));
      EXPECT_EQ(N_VGetArrayPointer_Serial(a[1]), NV_DATA_S(a[1]));
      EXPECT_EQ(libraryVersion<double* (*)(N_Vector)>("N_VGetArrayPointer_Serial")(a[1]),
                NV_DATA_S(a[1]));
    }
  }
}

// SUNRpowerI, and SUNRpowerR but for the square and fourth roots: the library's bits. Those two
// (CVODE's step-size rule after a restart) are sqrt(x) and sqrt(sqrt(x)): within one ulp of
// the library's pow (docs/benchmarks.md, "Tenth round", second part).
TEST(SundialsDispatch, PowersGiveTheLibrarysBits) {
  const auto powI = libraryVersion<double (*)(double, int)>("SUNRpowerI");
  const auto powR = libraryVersion<double (*)(double, double)>("SUNRpowerR");
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<double> bases{0.0,      -0.0,  1.0,  -1.0, 0.5, 2.0, 1e-300,
                            4.9e-324, 1e300, -3.7, nan,  inf, -inf};
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-8, 8);
  for (int i = 0; i < 2000; ++i) bases.push_back(std::exp(u(rng)) * (i % 3 == 0 ? -1 : 1));
  for (double base : bases) {
    for (int e : {-7, -3, -1, 0, 1, 2, 3, 5, 12})
      EXPECT_TRUE(sameBits(SUNRpowerI(base, e), powI(base, e))) << base << "^" << e;
    for (double e : {-1.0 / 6, -0.25, 1.0 / 3, 1.0 / 5, 2.0, -1.5, nan})
      EXPECT_TRUE(sameBits(SUNRpowerR(base, e), powR(base, e))) << base << "^" << e;
    for (double e : {0.5, 0.25}) {
      const double r = SUNRpowerR(base, e), lib = powR(base, e);
      if (!(base > 0.0) || std::isinf(base)) {  // 0, negative, nan, inf: as the library
        EXPECT_TRUE(sameBits(r, lib)) << base << "^" << e;
      } else {
        EXPECT_TRUE(sameBits(r, e == 0.5 ? std::sqrt(base) : std::sqrt(std::sqrt(base)))) << base;
        EXPECT_LE(std::fabs(r - lib), std::fabs(std::nextafter(lib, 0.0) - lib))
            << base << "^" << e;
      }
    }
  }
}

TEST(SundialsDispatch, NonlinearSolverQueriesGiveTheLibrarysAnswers) {
  SUNContext ctx = nullptr;
  ASSERT_EQ(SUNContext_Create(nullptr, &ctx), 0);
  N_Vector y = N_VNew_Serial(4, ctx);
  SUNNonlinearSolver fixed = SUNNonlinSol_FixedPoint(y, 0, ctx);
  SUNNonlinearSolver empty = SUNNonlinSolNewEmpty(ctx);  // no operations: the fallbacks
  using GetLong = int (*)(SUNNonlinearSolver, long int*);
  using GetInt = int (*)(SUNNonlinearSolver, int*);
  for (SUNNonlinearSolver s : {fixed, empty}) {
    long mine = 99, lib = 77;
    EXPECT_EQ(SUNNonlinSolGetNumIters(s, &mine),
              libraryVersion<GetLong>("SUNNonlinSolGetNumIters")(s, &lib));
    EXPECT_EQ(mine, lib);
    mine = 99, lib = 77;
    EXPECT_EQ(SUNNonlinSolGetNumConvFails(s, &mine),
              libraryVersion<GetLong>("SUNNonlinSolGetNumConvFails")(s, &lib));
    EXPECT_EQ(mine, lib);
    int cur = 99, cur_lib = 77;
    EXPECT_EQ(SUNNonlinSolGetCurIter(s, &cur),
              libraryVersion<GetInt>("SUNNonlinSolGetCurIter")(s, &cur_lib));
    EXPECT_EQ(cur, cur_lib);
  }
  SUNNonlinSolFreeEmpty(empty);
  SUNNonlinSolFree(fixed);
  N_VDestroy(y);
  SUNContext_Free(&ctx);
}
