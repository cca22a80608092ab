// tcpest evaluate: runs the pipeline over one or more dataset directories
// (images and their JSON sidecars, docs/dataset-format.md) and scores them
// against the ground truth: corners found within 1.5 px with the right
// label, median corner error, wrongly labelled and misplaced corners, the
// per-frame success criterion of the hard set, TCP error, and the time of
// each stage. Several directories (e.g. one set rendered with several
// seeds) are pooled into one score, with a frame-success line per
// directory: a change is judged on many frames, not on one set's few that
// sit near the tolerance.

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "cli/args.hpp"
#include "cli/commands.hpp"
#include "cli/joint_errors.hpp"
#include "cli/setup.hpp"
#include "cli/vision_run.hpp"
#include "tcpest/common/dmath.hpp"
#include "tcpest/render/sidecar.hpp"

namespace tcpest {
namespace cli {
namespace {

const OptionSpec kSpecs[] = {
    kCalibOption,
    kInstrumentConfigOption,
    {"colors", "MODEL.json", "colour model; default: the built-in model"},
    {"fixed-model", nullptr, "solve with the channel pose held at its nominal value"},
    kGuidedRoundsOption,
    kDenseOption,
    {"no-prior", nullptr, "ignore the sidecars' encoder priors (generic / temporal priors only)"},
    {"true-prior", nullptr,
     "diagnostic: the sidecars' true joints (lambda, phi, theta of r) as the prior, to tell the seed's "
     "error from the readings'"},
    {"max", "N", "score at most N images"},
    {"tolerance", "PX", "distance under which a corner counts as found (default 1.5)"},
    {"verbose", nullptr, "one line per image"},
    {"corners-csv", "FILE", "one row per image and corner index: truth, detection, model at the estimate"},
};
constexpr std::size_t kSpecCount = sizeof kSpecs / sizeof kSpecs[0];

// The value below which `share` (0..1) of v lies (sorts v; 0 when empty).
double quantile_of(std::vector<double>& v, double share) noexcept {
  if (v.empty()) {
    return 0.0;
  }
  std::sort(v.begin(), v.end());
  const auto last = static_cast<double>(v.size() - 1U);
  return v[static_cast<std::size_t>(std::lround(share * last))];
}

// One frame's corners against its truth: the visible ones, those found
// within the tolerance (their errors appended to `errors_px`), and of all
// the corners reported those beyond it, wrongly labelled (within the
// tolerance of another k's truth, and nearer to it than to its own) or
// misplaced (the rest).
struct CornerScore {
  int visible = 0;
  int found_ok = 0;
  long found = 0;
  long wrong = 0;
  long mislabelled = 0;
};

// Corners found and frames succeeded, over a dataset or all of them. A
// frame succeeds when at least 80 % of its visible corners are found
// (the hard set's criterion); one without visible corners is not counted.
struct SuccessTally {
  int frames_with_visible = 0;
  int successes = 0;
  long visible = 0;
  long found_ok = 0;

  // Adds a frame; true when it has visible corners and succeeded.
  bool add(const CornerScore& score) noexcept {
    visible += score.visible;
    found_ok += score.found_ok;
    if (score.visible == 0) {
      return false;
    }
    ++frames_with_visible;
    const bool success = score.found_ok * 10 >= score.visible * 8;
    successes += success ? 1 : 0;
    return success;
  }
};

// One directory's share of the pooled score (printed when several are).
struct DatasetTally {
  std::string dir;
  SuccessTally corners;
};

// The motion-blur streak the image fit read, against the sidecars' (when
// they carry it): how often it is read on blurred frames, how well, and
// how often on frames rendered without blur (a false reading).
struct StreakTally {
  int blurred_frames = 0;
  int read_blurred = 0;
  int sharp_frames = 0;
  int read_sharp = 0;
  std::vector<double> length_errors_px, direction_errors_deg;

  void add(const render::Sidecar& truth, const solver::Vec2& read_px) {
    const bool read = read_px.norm() > 0.0;
    if (truth.has_motion_blur) {
      ++blurred_frames;
      const solver::Vec2 true_px(truth.motion_blur_px[0], truth.motion_blur_px[1]);
      if (read && true_px.norm() > 0.0) {
        ++read_blurred;
        length_errors_px.push_back(std::fabs(read_px.norm() - true_px.norm()));
        // The sign is arbitrary: the angle between the two lines, 0..90 deg.
        const double cosine = std::fabs(read_px.dot(true_px)) / (read_px.norm() * true_px.norm());
        direction_errors_deg.push_back(dmath::acos(std::min(1.0, cosine)) * 180.0 / solver::kPi);
      }
    } else if (truth.has_render) {
      ++sharp_frames;
      read_sharp += read ? 1 : 0;
    }
  }
};

double median_of(std::vector<double>& v) noexcept {
  if (v.empty()) {
    return 0.0;
  }
  std::sort(v.begin(), v.end());
  return v[v.size() / 2U];
}

// The robot receives a degraded estimate flagged but still uses it (the
// protocol's status 1): how far off those are is part of the result.
constexpr double kDegradedFarMm = 5.0;
// A valid estimate this far off at the TCP is a gross error the robot
// would act on (counted in the report).
constexpr double kValidFarMm = 3.0;

// How many of the errors lie beyond limit_mm.
long count_over(const std::vector<double>& errors_mm, double limit_mm) noexcept {
  long far = 0;
  for (const double e_mm : errors_mm) {
    far += e_mm > limit_mm ? 1 : 0;
  }
  return far;
}

// TCP errors against the sidecars, by the estimate's status: of the valid
// ones the median and the RMS per axis, of the degraded ones the median,
// the 90th percentile and how many lie beyond kDegradedFarMm.
struct TcpTally {
  std::vector<double> valid_mm, degraded_mm;
  double valid_sq_mm2[3] = {0.0, 0.0, 0.0};

  void add(solver::EstimateQuality status, const solver::Vec3& error_mm) {
    if (status == solver::EstimateQuality::Valid) {
      valid_mm.push_back(error_mm.norm());
      for (int c = 0; c < 3; ++c) {
        valid_sq_mm2[c] += error_mm[c] * error_mm[c];
      }
    } else if (status == solver::EstimateQuality::Degraded) {
      degraded_mm.push_back(error_mm.norm());
    }
  }
  double valid_rms_mm(int axis) const noexcept {
    return valid_mm.empty() ? 0.0 : std::sqrt(valid_sq_mm2[axis] / static_cast<double>(valid_mm.size()));
  }
  long valid_far() const noexcept { return count_over(valid_mm, kValidFarMm); }
  long degraded_far() const noexcept { return count_over(degraded_mm, kDegradedFarMm); }
};

// Scores one frame's reported corners (CornerScore above).
CornerScore score_corners(const render::Sidecar& truth, const EstimateResult& result, const vision::Extraction& e,
                          double tolerance_px, std::vector<double>& errors_px) {
  CornerScore score;
  for (std::size_t k = 0U; k < static_cast<std::size_t>(solver::kNumCorners); ++k) {
    const bool is_visible = truth.instrument.corner_visible[k];
    if (is_visible) {
      ++score.visible;
    }
    if (!corner_reported(result, e, k)) {
      continue;
    }
    ++score.found;
    const bool has_truth = truth.instrument.corner_present[k];
    const double err = has_truth ? dmath::hypot(e.corners[k].pixel.x - truth.instrument.corners[k].x(),
                                              e.corners[k].pixel.y - truth.instrument.corners[k].y())
                                 : 1e9;
    if (err <= tolerance_px) {
      if (is_visible) {
        ++score.found_ok;
        errors_px.push_back(err);
      }
      continue;
    }
    ++score.wrong;
    for (std::size_t other = 0U; other < static_cast<std::size_t>(solver::kNumCorners); ++other) {
      if (other == k || !truth.instrument.corner_present[other]) {
        continue;
      }
      const double to_other = dmath::hypot(e.corners[k].pixel.x - truth.instrument.corners[other].x(),
                                         e.corners[k].pixel.y - truth.instrument.corners[other].y());
      if (to_other <= tolerance_px && to_other < err) {
        ++score.mislabelled;
        break;
      }
    }
  }
  return score;
}

// The frame's rows of --corners-csv: truth, detection and the model at the
// estimate, per corner index. Pooled: the image named with its directory
// (the same names recur).
void write_corner_rows(FILE* csv, const char* dir, bool pooled, const render::Sidecar& truth,
                       const EstimateResult& result, const vision::Extraction& e, const ModelSetup& setup) {
  solver::CornerSet model;
  if (result.status != solver::EstimateQuality::None) {
    setup.instrument.corners(setup.camera, result.r, model);
  }
  for (std::size_t k = 0U; k < static_cast<std::size_t>(solver::kNumCorners); ++k) {
    const bool found = corner_reported(result, e, k);
    const bool has_truth = truth.instrument.corner_present[k];
    const double tu = has_truth ? truth.instrument.corners[k].x() : std::nan("");
    const double tv = has_truth ? truth.instrument.corners[k].y() : std::nan("");
    const double u = found ? e.corners[k].pixel.x : std::nan("");
    const double v = found ? e.corners[k].pixel.y : std::nan("");
    std::fprintf(csv, "%s%s%s,%zu,%d,%.3f,%.3f,%d,%.3f,%.3f,%.3f,%.3f,%s,%.3f,%.3f\n", pooled ? dir : "",
                 pooled ? "/" : "", truth.image, k, truth.instrument.corner_visible[k] ? 1 : 0, tu, tv, found ? 1 : 0,
                 u, v, found ? e.corners[k].confidence : 0.0, dmath::hypot(u - tu, v - tv), to_string(result.status),
                 model.present[k] ? model.pixel[k].x() : std::nan(""),
                 model.present[k] ? model.pixel[k].y() : std::nan(""));
  }
}

// Everything scored over all the datasets, and its report.
struct EvaluateTotals {
  int frames = 0;
  int unreadable = 0;
  SuccessTally corners;
  long found_total = 0;
  long wrong = 0;
  long mislabelled = 0;
  HardCaseTally by_case;  // frame success per hard case
  VisibleCornersTally by_visible;  // ... and by the frame's visible corners
  InsertionTally by_insertion;     // ... and by the truth's insertion
  // The frames with visible corners that did not succeed, by the estimate's
  // status; of those without a pose, the ones that reported no corner at
  // all (stage 4 found nothing and no seed's image fit held: the reading
  // failed, not the choice among results).
  int failed_none = 0;
  int failed_none_no_corner = 0;
  int failed_degraded = 0;
  int failed_valid = 0;
  std::vector<double> errors_px, stage_us[4], stages_total_us, solve_us;
  StreakTally streaks;
  // The solve's TCP (what the robot receives), and on the same frames, where
  // a model-guided round was kept, the TCP of the pose the corners were read
  // at (docs/solver.md, "The image fit's pose and the TCP").
  TcpTally solve_tcp, fit_tcp;
  JointErrors valid_joints;  // of the valid estimates
  // The solve's TCP errors of the estimates demoted from valid because that
  // TCP lay too far from the image fit's (EstimateResult::fit_disagrees).
  std::vector<double> fit_disagrees_mm;
  // The dense stage (--dense): frames it ran on, frames its estimate was
  // kept on and those of them that succeed, and its frames' solve times.
  int dense_ran = 0;
  int dense_kept = 0;
  int dense_kept_success = 0;
  std::vector<double> dense_solve_us;
  // Per policy row (vision::kEstimationPolicy): the frames it ran on, and
  // those whose estimate it produced (a check: demoted).
  std::array<long, vision::kNumStepKinds> row_tried{};
  std::array<long, vision::kNumStepKinds> row_produced{};

  // Adds one frame; returns its TCP error (mm; -1 without a pose or a true TCP).
  double add(const render::Sidecar& truth, const EstimateResult& result, const CornerScore& score,
             DatasetTally& dataset) {
    ++frames;
    for (std::size_t i = 0U; i < row_tried.size(); ++i) {
      const auto kind = static_cast<vision::StepKind>(i);
      row_tried[i] += result.rows_tried.has(kind) ? 1 : 0;
      row_produced[i] += result.rows_produced.has(kind) ? 1 : 0;
    }
    found_total += score.found;
    wrong += score.wrong;
    mislabelled += score.mislabelled;
    const bool success = corners.add(score);
    static_cast<void>(dataset.corners.add(score));  // the same verdict as `success`
    if (score.visible > 0) {
      by_case.add(truth.hard_cases, success);
      by_visible.add(score.visible, success);
      if (truth.instrument.has_r) {
        by_insertion.add(truth.instrument.r[solver::kLambda], success);
      }
      if (!success) {
        switch (result.status) {
          case solver::EstimateQuality::None:
            ++failed_none;
            failed_none_no_corner += score.found == 0 ? 1 : 0;
            break;
          case solver::EstimateQuality::Degraded: ++failed_degraded; break;
          case solver::EstimateQuality::Valid: ++failed_valid; break;
        }
      }
    }
    if (result.dense_ran) {
      ++dense_ran;
      dense_solve_us.push_back(result.times.solve_us);
      dense_kept += result.dense_kept ? 1 : 0;
      dense_kept_success += result.dense_kept && success ? 1 : 0;
    }
    streaks.add(truth, result.streak_px);
    for (int s = 0; s < 4; ++s) {
      stage_us[s].push_back(result.times.stage_us[s]);
    }
    stages_total_us.push_back(result.times.stage_us[0] + result.times.stage_us[1] + result.times.stage_us[2] +
                              result.times.stage_us[3]);
    solve_us.push_back(result.times.solve_us);
    if (result.status == solver::EstimateQuality::None || !truth.instrument.has_tcp) {
      return -1.0;
    }
    solve_tcp.add(result.status, result.tcp - truth.instrument.tcp);
    if (result.status == solver::EstimateQuality::Valid && truth.instrument.has_r) {
      valid_joints.add(result.r, truth.instrument.r);
    }
    if (result.guided_rounds > 0) {
      fit_tcp.add(result.status, result.fit_tcp - truth.instrument.tcp);
    }
    if (result.fit_disagrees) {
      fit_disagrees_mm.push_back((result.tcp - truth.instrument.tcp).norm());
    }
    return (result.tcp - truth.instrument.tcp).norm();
  }

  void print(const std::vector<DatasetTally>& datasets, double tolerance_px) {
    const auto percent = [](long part, long whole) noexcept {
      return whole > 0 ? 100.0 * static_cast<double>(part) / static_cast<double>(whole) : 0.0;
    };
    if (datasets.size() > 1U) {
      for (const DatasetTally& t : datasets) {
        std::printf("dataset %s: frame success %.1f %% of %d frames, corners found %.2f %% of %ld visible\n",
                    t.dir.c_str(), percent(t.corners.successes, t.corners.frames_with_visible),
                    t.corners.frames_with_visible, percent(t.corners.found_ok, t.corners.visible), t.corners.visible);
      }
      std::printf("pooled over %zu datasets: %d images scored (%d unreadable), %ld visible corners\n",
                  datasets.size(), frames, unreadable, corners.visible);
    } else {
      std::printf("dataset %s: %d images scored (%d unreadable), %ld visible corners\n", datasets[0].dir.c_str(),
                  frames, unreadable, corners.visible);
    }
    std::printf("corners found within %.1f px and correctly labelled: %.2f %% of visible\n", tolerance_px,
                percent(corners.found_ok, corners.visible));
    std::printf("median corner error (found ones): %.3f px\n", median_of(errors_px));
    std::printf("found corners farther than %.1f px from their truth: %.2f %% of %ld found (wrongly labelled, i.e. "
                "another corner's: %.2f %%; misplaced: %.2f %%)\n",
                tolerance_px, percent(wrong, found_total), found_total, percent(mislabelled, found_total),
                percent(wrong - mislabelled, found_total));
    std::printf("frame success (>= 80 %% of visible corners found and labelled): %.1f %% of %d frames\n",
                percent(corners.successes, corners.frames_with_visible), corners.frames_with_visible);
    std::printf("frames not succeeding: %d (no estimate %d, of which %d report no corner; degraded %d; valid %d)\n",
                corners.frames_with_visible - corners.successes, failed_none, failed_none_no_corner, failed_degraded,
                failed_valid);
    char case_line[512];
    format_hard_case_tally(by_case, case_line, sizeof case_line);
    if (case_line[0] != '\0') {
      std::printf("%s\n", case_line);
    }
    format_visible_corners_tally(by_visible, case_line, sizeof case_line);
    if (case_line[0] != '\0') {
      std::printf("%s\n", case_line);
    }
    format_insertion_tally(by_insertion, case_line, sizeof case_line);
    if (case_line[0] != '\0') {
      std::printf("%s\n", case_line);
    }
    if (dense_ran > 0) {
      std::printf("dense stage: ran on %d frames (not valid, valid from few corners measured, or a streak read), "
                  "its estimate kept on %d, of which %d succeed; median solve time with it %.0f ms\n",
                  dense_ran, dense_kept, dense_kept_success, 1e-3 * median_of(dense_solve_us));
    }
    if (streaks.blurred_frames > 0) {
      std::printf("motion-blur streak read on %d of %d blurred frames (length error median %.2f px, direction error "
                  "median %.1f deg) and on %d of %d others\n",
                  streaks.read_blurred, streaks.blurred_frames, median_of(streaks.length_errors_px),
                  median_of(streaks.direction_errors_deg), streaks.read_sharp, streaks.sharp_frames);
    }
    std::printf("valid estimates: %zu; TCP error median %.2f mm, RMS x/y/z %.2f / %.2f / %.2f mm, over %.0f mm: %ld\n",
                solve_tcp.valid_mm.size(), median_of(solve_tcp.valid_mm), solve_tcp.valid_rms_mm(0),
                solve_tcp.valid_rms_mm(1), solve_tcp.valid_rms_mm(2), kValidFarMm, solve_tcp.valid_far());
    char joints_line[320];
    valid_joints.format("valid estimates' joints: ", joints_line, sizeof joints_line);
    std::printf("%s\n", joints_line);
    std::printf("valid solves degraded, their TCP too far from the image fit's: %zu; TCP error median %.2f mm, "
                "over %.0f mm: %ld\n",
                fit_disagrees_mm.size(), median_of(fit_disagrees_mm), kValidFarMm,
                count_over(fit_disagrees_mm, kValidFarMm));
    std::printf("degraded estimates: %zu; TCP error median %.2f mm, 90th percentile %.2f mm, over %.0f mm: %ld\n",
                solve_tcp.degraded_mm.size(), median_of(solve_tcp.degraded_mm),
                quantile_of(solve_tcp.degraded_mm, 0.9), kDegradedFarMm, solve_tcp.degraded_far());
    std::printf("the image fit's pose instead (%zu of the valid, %zu of the degraded: those with a round kept): valid "
                "TCP error median %.2f mm, RMS x/y/z %.2f / %.2f / %.2f mm, over %.0f mm: %ld; degraded median %.2f mm, "
                "90th percentile %.2f mm, over %.0f mm: %ld\n",
                fit_tcp.valid_mm.size(), fit_tcp.degraded_mm.size(), median_of(fit_tcp.valid_mm),
                fit_tcp.valid_rms_mm(0), fit_tcp.valid_rms_mm(1), fit_tcp.valid_rms_mm(2), kValidFarMm,
                fit_tcp.valid_far(), median_of(fit_tcp.degraded_mm), quantile_of(fit_tcp.degraded_mm, 0.9), kDegradedFarMm,
                fit_tcp.degraded_far());
    std::printf("median time: stage 1 %.0f us, stage 2 %.0f us, stage 3 %.0f us, stage 4 %.0f us, stages 1-4 %.0f "
                "us, solver %.0f us\n",
                median_of(stage_us[0]), median_of(stage_us[1]), median_of(stage_us[2]), median_of(stage_us[3]),
                median_of(stages_total_us), median_of(solve_us));
    for (const vision::PolicyStep& row : vision::kEstimationPolicy) {
      const auto i = static_cast<std::size_t>(row.kind);
      std::printf("policy row %s: ran on %ld frames, produced (or demoted) the estimate of %ld\n", row.name,
                  row_tried[i], row_produced[i]);
    }
  }
};

// The command's options beyond the model setup's.
struct EvaluateOptions {
  double tolerance_px = 1.5;
  unsigned long long max_images = ~0ULL;
  bool true_prior = false;
  bool no_prior = false;
  bool verbose = false;
  const char* corners_csv = nullptr;
};

// The options from the arguments; false (with the reason on stderr) on a bad
// value or a forbidden combination.
bool read_evaluate_options(const Args& args, EvaluateOptions& out) {
  if (args.value("tolerance") != nullptr &&
      (!parse_number(args.value("tolerance"), out.tolerance_px) || out.tolerance_px <= 0.0)) {
    std::fprintf(stderr, "tcpest evaluate: --tolerance needs a positive number\n");
    return false;
  }
  if (args.value("max") != nullptr && !parse_unsigned(args.value("max"), out.max_images)) {
    std::fprintf(stderr, "tcpest evaluate: --max needs a non-negative integer\n");
    return false;
  }
  out.true_prior = args.flag("true-prior");
  out.no_prior = args.flag("no-prior");
  if (out.true_prior && out.no_prior) {
    std::fprintf(stderr, "tcpest evaluate: --true-prior and --no-prior exclude each other\n");
    return false;
  }
  out.verbose = args.flag("verbose");
  out.corners_csv = args.value("corners-csv");
  return true;
}

// What one evaluation run works with, for each frame.
struct EvaluateRun {
  const EvaluateOptions& options;
  const ModelSetup& setup;
  EstimatePipeline& pipeline;
  ImageReader& reader;
  std::vector<std::uint8_t>& pixels;
  EvaluateTotals& totals;
  FILE* csv;    // the corner rows (nullptr: none)
  bool pooled;  // several datasets: images named with their directory
};

// One frame of dataset `tally`: its sidecar `name` read, its image through
// the pipeline and scored against the sidecar. An unreadable sidecar or
// image, or one of another size than the calibration's, is reported and
// counted, and the run goes on.
void evaluate_frame(EvaluateRun& run, DatasetTally& tally, const std::string& name) {
  char error[512];
  const std::string& dir = tally.dir;
  std::string sidecar_path = dir;
  sidecar_path += "/";
  sidecar_path += name;
  const auto parsed = render::read_sidecar_file(sidecar_path.c_str());
  if (!parsed.ok()) {
    parsed.error().format(error, sizeof error);
    std::fprintf(stderr, "tcpest evaluate: %s\n", error);
    ++run.totals.unreadable;
    return;
  }
  const render::Sidecar& truth = parsed.value();
  std::string image_path = dir;
  image_path += "/";
  image_path += truth.image;
  ImageView view;
  if (!run.reader.read(image_path.c_str(), run.pixels, view, error, sizeof error)) {
    std::fprintf(stderr, "tcpest evaluate: %s: %s\n", image_path.c_str(), error);
    ++run.totals.unreadable;
    return;
  }
  if (view.width != run.setup.camera.width() || view.height != run.setup.camera.height()) {
    std::fprintf(stderr, "tcpest evaluate: %s: size differs from the calibration\n", image_path.c_str());
    ++run.totals.unreadable;
    return;
  }
  if (std::strcmp(truth.set, "seq") != 0) {
    run.pipeline.reset_sequence();  // independent images
  }
  // The true joints: r's lambda, phi, theta (the channel's pose is not a
  // prior: the pipeline starts it at the CAD pose either way).
  const double true_joints[3] = {truth.instrument.r[solver::kLambda], truth.instrument.r[solver::kPhi],
                                 truth.instrument.r[solver::kTheta]};
  const double* prior = nullptr;
  if (run.options.true_prior) {
    prior = truth.instrument.has_r ? true_joints : nullptr;
  } else if (truth.has_prior && !run.options.no_prior) {
    prior = truth.prior.data();
  }
  const EstimateResult result = run.pipeline.process(view, prior);
  const vision::Extraction& e = run.pipeline.extractor().result();
  const CornerScore score = score_corners(truth, result, e, run.options.tolerance_px, run.totals.errors_px);
  const double tcp_err = run.totals.add(truth, result, score, tally);
  if (run.csv != nullptr) {
    write_corner_rows(run.csv, dir.c_str(), run.pooled, truth, result, e, run.setup);
  }
  if (run.options.verbose) {
    // Pooled: the image named with its directory, as in the corner rows.
    // The image fit's pose beside the solve's (docs/solver.md); -1 without a kept round.
    const double fit_err = result.guided_rounds > 0 && tcp_err >= 0.0
                               ? (result.fit_tcp - truth.instrument.tcp).norm()
                               : -1.0;
    std::printf("%s%s%s: %s, visible %d, found ok %d of %d found, %s%s, TCP error %.2f mm (image fit's pose %.2f mm), "
                "stages %.0f us\n",
                run.pooled ? dir.c_str() : "", run.pooled ? "/" : "", truth.image, to_string(result.status),
                score.visible, score.found_ok, e.corner_count, result.extraction_ok ? "extraction ok" : "extraction: ",
                result.extraction_ok ? "" : result.extraction_error, tcp_err, fit_err, run.totals.stages_total_us.back());
  }
}

}  // namespace

int cmd_evaluate(int argc, char** argv) {
  Args args;
  char error[512];
  if (!args.parse(argc, argv, 1, kSpecs, kSpecCount, error, sizeof error)) {
    std::fprintf(stderr, "tcpest evaluate: %s\n", error);
    return kExitUsage;
  }
  if (args.help_requested() || args.positional_count() < 1U) {
    print_usage("tcpest evaluate [--calib CAM.yaml] [--config CFG] [--colors MODEL] [--fixed-model] "
                "[--guided-rounds N] [--dense] [--no-prior | --true-prior] "
                "[--max N] [--verbose] DATASET_DIR...",
                "Runs extraction and the solver on every image of one or more datasets and scores them against the "
                "sidecars; several datasets are pooled, with a frame-success line for each.",
                kSpecs, kSpecCount);
    return args.help_requested() ? kExitOk : kExitUsage;
  }
  EvaluateOptions options;
  if (!read_evaluate_options(args, options)) {
    return kExitUsage;
  }
  // The pipeline's options and files first: a usage error is reported as
  // one, whatever the datasets hold.
  ModelSetup setup;
  static EstimatePipeline pipeline;
  int exit_code = kExitOk;
  if (!init_pipeline_from_args("evaluate", args, setup, pipeline, exit_code)) {
    return exit_code;
  }
  // Every directory is listed before any image is processed: a typo in the
  // last one fails at once, not after the others have run.
  const std::size_t dataset_count = args.positional_count();
  std::vector<DatasetTally> datasets(dataset_count);
  std::vector<std::vector<std::string>> sidecars(dataset_count);
  for (std::size_t i = 0U; i < dataset_count; ++i) {
    datasets[i].dir = args.positional(i);
    if (!list_sidecars("tcpest evaluate", datasets[i].dir, sidecars[i])) {
      return kExitConfig;
    }
  }
  ImageReader reader;
  const vision::RegionsConfig& frames = pipeline.extractor().config().regions;
  if (!reader.init(frames.max_width, frames.max_height)) {
    std::fprintf(stderr, "tcpest evaluate: JPEG decoder initialisation failed\n");
    return kExitFailure;
  }
  FILE* csv = nullptr;
  if (options.corners_csv != nullptr) {
    csv = std::fopen(options.corners_csv, "w");
    if (csv == nullptr) {
      std::fprintf(stderr, "tcpest evaluate: cannot write %s: %s\n", options.corners_csv, std::strerror(errno));
      return kExitFailure;
    }
    std::fprintf(csv, "image,k,visible,truth_u,truth_v,found,u,v,confidence,error_px,status,model_u,model_v\n");
  }
  std::vector<std::uint8_t> pixels;
  EvaluateTotals totals;
  EvaluateRun run{options, setup, pipeline, reader, pixels, totals, csv, dataset_count > 1U};
  for (std::size_t set = 0U; set < dataset_count; ++set) {
    pipeline.reset_sequence();  // a dataset is a sequence of its own
    pipeline.reset_appearance();  // ... and a scene of its own
    for (const std::string& name : sidecars[set]) {
      if (static_cast<unsigned long long>(totals.frames) + static_cast<unsigned long long>(totals.unreadable) >=
          options.max_images) {
        break;
      }
      evaluate_frame(run, datasets[set], name);
    }
  }
  if (csv != nullptr && std::fclose(csv) != 0) {
    std::fprintf(stderr, "tcpest evaluate: writing %s failed\n", options.corners_csv);
    return kExitFailure;
  }
  totals.print(datasets, options.tolerance_px);
  return totals.frames > 0 ? kExitOk : kExitFailure;
}

}  // namespace cli
}  // namespace tcpest
