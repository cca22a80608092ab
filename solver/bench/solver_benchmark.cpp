// Time of one adaptive solve with 12 corners from the coarse prior (1 px
// noise, play as in the reference experiment), over a fixed set of problems
// cycled in turn; with Ceres, the identical problem (same residuals, same
// analytic Jacobian, same start) solved by ceres::Solve (dense LM) and by
// ceres::TinySolver. At the end: median times, the ratios, and the largest
// difference between the final costs reached.
//
// Heap use here is deliberate and outside every product binary: this is a
// benchmark program (its own executable, not linked into tcpest or the
// loop). The problem set (std::vector) and the Ceres problems (ceres::Problem
// takes ownership of a new'd cost function; std::unique_ptr holds each
// problem) are built once, before the first timed iteration; the timed
// loops only solve them. Our solver's path allocates nothing
// (solver/test/no_malloc_test.cpp).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "pose_problem.hpp"
#include "tcpest/solver/pose_solver.hpp"

#ifdef TCPEST_HAVE_CERES
#include <ceres/ceres.h>
#include <ceres/tiny_solver.h>
#endif

namespace {

using namespace tcpest::solver;  // NOLINT(google-build-using-namespace): a benchmark program, names stay short

constexpr int kProblems = 64;

struct Fixture {
  CameraModel camera = test_support::pal_camera();
  InstrumentModel model = test_support::default_model();
  std::vector<test_support::Problem> problems;
  std::array<bool, kNumCorners> all{};

  Fixture() {
    all.fill(true);
    std::mt19937 rng(2024);  // NOLINT(cert-msc32-c,cert-msc51-cpp): the same problems in every run, by design
    while (static_cast<int>(problems.size()) < kProblems) {
      test_support::Problem p;
      CornerSet at_prior;
      if (test_support::draw_problem(rng, camera, model, true, 1.0, kNumCorners, p)) {
        model.corners(camera, p.prior, at_prior);
        if (at_prior.count_present() == kNumCorners) {  // every solver then uses all 12
          problems.push_back(p);
        }
      }
    }
  }
};

Fixture& fixture() {
  static Fixture f;
  return f;
}

void BM_Ours_AdaptiveSolve12Corners(benchmark::State& state) {
  Fixture& f = fixture();
  PoseSolver solver(f.camera, f.model);
  std::size_t i = 0;
  long iterations = 0;
  for (auto _ : state) {
    const auto& p = f.problems[i++ % f.problems.size()];
    PoseVector r = p.prior;
    const SolveSummary s = solver.solve(p.observed, SolveMode::Adaptive, r);
    iterations += s.iterations;
    benchmark::DoNotOptimize(r);
  }
  state.counters["lm_iterations"] = benchmark::Counter(static_cast<double>(iterations), benchmark::Counter::kAvgIterations);
}
BENCHMARK(BM_Ours_AdaptiveSolve12Corners)->Repetitions(9)->ReportAggregatesOnly(true)->Unit(benchmark::kMicrosecond);

// The model evaluation every LM iteration pays for (12 corners).
void BM_ModelCornersWithJacobians(benchmark::State& state) {
  Fixture& f = fixture();
  CornerSet corners;
  CornerJacobians jacobians;
  std::size_t i = 0;
  for (auto _ : state) {
    f.model.corners(f.camera, f.problems[i++ % f.problems.size()].truth, corners, &jacobians);
    benchmark::DoNotOptimize(jacobians);
  }
}
BENCHMARK(BM_ModelCornersWithJacobians)->Unit(benchmark::kMicrosecond);

void BM_ModelCornersOnly(benchmark::State& state) {
  Fixture& f = fixture();
  CornerSet corners;
  std::size_t i = 0;
  for (auto _ : state) {
    f.model.corners(f.camera, f.problems[i++ % f.problems.size()].truth, corners, nullptr);
    benchmark::DoNotOptimize(corners);
  }
}
BENCHMARK(BM_ModelCornersOnly)->Unit(benchmark::kMicrosecond);

#ifdef TCPEST_HAVE_CERES

// eq. 8 as a Ceres cost function: the same PoseResidual (residuals and
// analytic Jacobian) the solver uses.
class PoseCost : public ceres::SizedCostFunction<kNumResiduals, kNumParams> {
 public:
  PoseCost(const CameraModel& camera, const InstrumentModel& model, const CornerObservation& observed,
           std::array<bool, kNumCorners>& used)
      : residual_(camera, model, observed, used, nullptr) {}
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    const Eigen::Map<const PoseVector> x(parameters[0]);
    Eigen::Matrix<double, kNumResiduals, 1> values;
    Eigen::Matrix<double, kNumResiduals, kNumParams> jacobian;
    const bool want = jacobians != nullptr && jacobians[0] != nullptr;
    if (!residual_(x, values, want ? &jacobian : nullptr)) {
      return false;
    }
    Eigen::Map<Eigen::Matrix<double, kNumResiduals, 1>> residual_out(residuals);
    residual_out = values;
    if (want) {
      Eigen::Map<Eigen::Matrix<double, kNumResiduals, kNumParams, Eigen::RowMajor>> jacobian_out(jacobians[0]);
      jacobian_out = jacobian;
    }
    return true;
  }

 private:
  mutable PoseResidual<kNumParams> residual_;
};

ceres::Solver::Options ceres_options() {
  ceres::Solver::Options o;
  o.minimizer_type = ceres::TRUST_REGION;
  o.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  o.linear_solver_type = ceres::DENSE_NORMAL_CHOLESKY;
  o.max_num_iterations = SolverOptions{}.max_iterations;
  o.function_tolerance = SolverOptions{}.cost_change_tolerance;
  o.gradient_tolerance = SolverOptions{}.gradient_tolerance;
  o.parameter_tolerance = SolverOptions{}.step_tolerance;
  o.num_threads = 1;
  o.logging_type = ceres::SILENT;
  o.minimizer_progress_to_stdout = false;
  return o;
}

struct CeresProblem {
  PoseVector x;
  ceres::Problem problem;
  explicit CeresProblem(Fixture& f, const test_support::Problem& p) : x(p.prior) {
    problem.AddResidualBlock(new PoseCost(f.camera, f.model, p.observed, f.all), nullptr, x.data());
  }
};

// All 12 corners are visible and given by the model at every start here, so
// "used" = all for every solver.
std::vector<std::unique_ptr<CeresProblem>>& ceres_problems() {
  static std::vector<std::unique_ptr<CeresProblem>> problems;
  if (problems.empty()) {
    for (const auto& p : fixture().problems) {
      problems.push_back(std::make_unique<CeresProblem>(fixture(), p));
    }
  }
  return problems;
}

double ceres_solve(std::size_t index, ceres::Solver::Summary& summary) {
  static const ceres::Solver::Options options = ceres_options();
  CeresProblem& cp = *ceres_problems()[index];
  cp.x = fixture().problems[index].prior;
  ceres::Solve(options, &cp.problem, &summary);
  return summary.final_cost;
}

void BM_Ceres_AdaptiveSolve12Corners(benchmark::State& state) {
  static_cast<void>(ceres_problems());  // built here, before the timed loop (the reference is not needed)
  std::size_t i = 0;
  ceres::Solver::Summary summary;
  long iterations = 0;
  for (auto _ : state) {
    ceres_solve(i++ % kProblems, summary);
    iterations += static_cast<long>(summary.iterations.size());
  }
  state.counters["lm_iterations"] = benchmark::Counter(static_cast<double>(iterations), benchmark::Counter::kAvgIterations);
}
BENCHMARK(BM_Ceres_AdaptiveSolve12Corners)->Repetitions(9)->ReportAggregatesOnly(true)->Unit(benchmark::kMicrosecond);

// TinySolver's function interface around the same residual.
struct TinyPose {
  using Scalar = double;
  enum { NUM_RESIDUALS = kNumResiduals, NUM_PARAMETERS = kNumParams };
  mutable PoseResidual<kNumParams> residual;
  bool operator()(const double* parameters, double* residuals, double* jacobian) const {
    const Eigen::Map<const PoseVector> x(parameters);
    Eigen::Matrix<double, kNumResiduals, 1> values;
    Eigen::Matrix<double, kNumResiduals, kNumParams> j;
    if (!residual(x, values, jacobian != nullptr ? &j : nullptr)) {
      return false;
    }
    Eigen::Map<Eigen::Matrix<double, kNumResiduals, 1>> residual_out(residuals);
    residual_out = values;
    if (jacobian != nullptr) {
      Eigen::Map<Eigen::Matrix<double, kNumResiduals, kNumParams>> jacobian_out(jacobian);  // column-major
      jacobian_out = j;
    }
    return true;
  }
};

double tiny_solve(const test_support::Problem& p, int& iterations) {
  Fixture& f = fixture();
  TinyPose function{PoseResidual<kNumParams>(f.camera, f.model, p.observed, f.all, nullptr)};
  ceres::TinySolver<TinyPose> solver;
  solver.options.max_num_iterations = SolverOptions{}.max_iterations;
  solver.options.gradient_tolerance = SolverOptions{}.gradient_tolerance;
  solver.options.parameter_tolerance = SolverOptions{}.step_tolerance;
  solver.options.function_tolerance = SolverOptions{}.cost_change_tolerance;
  PoseVector x = p.prior;
  const auto& summary = solver.Solve(function, &x);
  iterations = summary.iterations;
  return summary.final_cost;
}

void BM_CeresTinySolver_AdaptiveSolve12Corners(benchmark::State& state) {
  std::size_t i = 0;
  long iterations = 0;
  for (auto _ : state) {
    int n = 0;
    benchmark::DoNotOptimize(tiny_solve(fixture().problems[i++ % kProblems], n));
    iterations += n;
  }
  state.counters["lm_iterations"] = benchmark::Counter(static_cast<double>(iterations), benchmark::Counter::kAvgIterations);
}
BENCHMARK(BM_CeresTinySolver_AdaptiveSolve12Corners)
    ->Repetitions(9)
    ->ReportAggregatesOnly(true)
    ->Unit(benchmark::kMicrosecond);

#endif  // TCPEST_HAVE_CERES

// Collects the medians for the closing summary.
class MedianReporter : public benchmark::ConsoleReporter {
 public:
  void ReportRuns(const std::vector<Run>& runs) override {
    for (const Run& run : runs) {
      if (run.aggregate_name == "median") {
        medians_us[run.run_name.function_name] = run.GetAdjustedRealTime();
        medians_cpu_us[run.run_name.function_name] = run.GetAdjustedCPUTime();
      }
    }
    ConsoleReporter::ReportRuns(runs);
  }
  std::map<std::string, double> medians_us;
  std::map<std::string, double> medians_cpu_us;
};

void print_cost_agreement() {
  Fixture& f = fixture();
  PoseSolver solver(f.camera, f.model);
  double worst_relative = 0.0;
  int ours_converged = 0;
  for (std::size_t i = 0; i < f.problems.size(); ++i) {
    PoseVector r;
    r = f.problems[i].prior;
    const SolveSummary s = solver.solve(f.problems[i].observed, SolveMode::Adaptive, r);
    ours_converged += is_converged(s.status) ? 1 : 0;
#ifdef TCPEST_HAVE_CERES
    ceres::Solver::Summary summary;
    const double ceres_cost = ceres_solve(i, summary);
    int tiny_iterations = 0;
    const double tiny_cost = tiny_solve(f.problems[i], tiny_iterations);
    const double scale = std::max(1e-12, s.final_cost);
    worst_relative = std::max(worst_relative, std::fabs(ceres_cost - s.final_cost) / scale);
    worst_relative = std::max(worst_relative, std::fabs(tiny_cost - s.final_cost) / scale);
#endif
  }
  std::printf("\n%zu problems (12 corners, 1 px noise, play, coarse prior): ours converged on %d\n", f.problems.size(),
              ours_converged);
#ifdef TCPEST_HAVE_CERES
  std::printf("largest relative difference of the final cost, ours vs ceres::Solve / TinySolver: %.3g\n",
              worst_relative);
#else
  static_cast<void>(worst_relative);
  std::printf("built without Ceres: no comparison\n");
#endif
}

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) {
    return 1;
  }
  MedianReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  benchmark::Shutdown();
  print_cost_agreement();
  // Wall and CPU time: on a shared machine the wall time carries other
  // jobs' load, the CPU time is this thread's work.
  const auto ours = reporter.medians_us.find("BM_Ours_AdaptiveSolve12Corners");
  if (ours != reporter.medians_us.end()) {
    const double ours_cpu = reporter.medians_cpu_us[ours->first];
    std::printf("median time of one adaptive solve (ours): %.2f us wall, %.2f us CPU (target <= 30 us)\n",
                ours->second, ours_cpu);
    for (const auto& entry : reporter.medians_us) {
      if (entry.first != ours->first) {
        std::printf("%s / ours: %.2f wall, %.2f CPU (target >= 3 for ceres::Solve)\n", entry.first.c_str(),
                    entry.second / ours->second, reporter.medians_cpu_us[entry.first] / ours_cpu);
      }
    }
  }
  return 0;
}
