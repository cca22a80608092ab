// cycles.csv: every row has the header's columns, the row says why its
// estimate has its status (the last four columns), and "none" is an empty
// field, never a sentinel.
#include "cli/cycles_csv.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <initializer_list>
#include <string>
#include <vector>

namespace tcpest {
namespace cli {
namespace {

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> fields;
  std::string field;
  for (const char c : line) {
    if (c == ',') {
      fields.push_back(field);
      field.clear();
    } else if (c != '\n') {
      field += c;
    }
  }
  fields.push_back(field);
  return fields;
}

// The header and one row of `r`, written through a temporary file.
// The truth of the record's frame, as a simulated source gives it beside the loop.
hal::FrameTruth truth_at_50mm() {
  hal::FrameTruth truth;
  truth.valid = true;
  truth.tcp_mm[2] = 50.0;
  return truth;
}

std::vector<std::vector<std::string>> header_and_row(const loop::CycleRecord& r, std::int64_t t0_ns,
                                                     const hal::FrameTruth* truth, bool with_truth = true) {
  std::FILE* f = std::tmpfile();
  EXPECT_NE(f, nullptr);
  if (f == nullptr) {
    return {};
  }
  EXPECT_TRUE(write_cycles_csv_header(f, with_truth));
  EXPECT_TRUE(write_cycles_csv_row(f, r, truth, with_truth, t0_ns));
  std::rewind(f);
  std::vector<std::vector<std::string>> lines;
  char buffer[4096];
  while (std::fgets(buffer, sizeof buffer, f) != nullptr) {
    lines.push_back(split(buffer));
  }
  static_cast<void>(std::fclose(f));  // a read-back stream: nothing to lose
  return lines;
}

// The value of column `name` in `row`, by the header.
std::string column(const std::vector<std::vector<std::string>>& lines, const std::string& name) {
  for (std::size_t i = 0U; i < lines[0].size(); ++i) {
    if (lines[0][i] == name) {
      return lines[1][i];
    }
  }
  ADD_FAILURE() << "no column " << name;
  return "";
}

struct Expected {
  const char* column;
  std::string value;
};

// Each named column of the row holds its value.
void expect_columns(const std::vector<std::vector<std::string>>& lines, std::initializer_list<Expected> expected) {
  for (const Expected& e : expected) {
    EXPECT_EQ(column(lines, e.column), e.value) << e.column;
  }
}

loop::CycleRecord degraded_by_the_image_fit() {
  loop::CycleRecord r;
  r.cycle = 7U;
  r.frame_sequence = 6U;
  r.have_frame = true;
  r.trigger_ns = 2'040'000'000;
  r.total_ns = 3'500'000;
  r.latency_ns = 4'000'000;
  r.send_offset_ns = 100'000;
  r.solve_status = solver::SolveStatus::ConvergedStep;
  r.quality = solver::EstimateQuality::Degraded;
  r.solved = true;
  r.refined = true;
  r.fit_disagrees = true;
  r.corners_rejected = 2;
  r.publication.status = loop::EstimateStatus::kDegraded;
  r.publication.tcp_mm[0] = 3.0;
  r.publication.tcp_mm[1] = 4.0;
  r.publication.tcp_mm[2] = 50.0;
  r.publication.corners_detected = 11U;
  r.publication.corners_used = 9U;
  return r;
}

TEST(CyclesCsv, EveryRowHasTheHeadersColumns) {
  const hal::FrameTruth truth = truth_at_50mm();
  const auto lines = header_and_row(degraded_by_the_image_fit(), 2'000'000'000, &truth);
  ASSERT_EQ(lines.size(), 2U);
  EXPECT_EQ(lines[1].size(), lines[0].size());
  // Appended last, so that a reader of the first columns by position keeps working.
  const std::size_t n = lines[0].size();
  ASSERT_GE(n, 4U);
  EXPECT_EQ(lines[0][n - 4U], "refined");
  EXPECT_EQ(lines[0][n - 3U], "corners_rejected");
  EXPECT_EQ(lines[0][n - 2U], "encoder_disagrees");
  EXPECT_EQ(lines[0][n - 1U], "fit_disagrees");
  EXPECT_EQ(lines[0][0], "cycle");
  for (const auto& step : loop::kSchedule) {
    EXPECT_NE(column(lines, std::string(step.name) + "_ms"), "");
  }
}

TEST(CyclesCsv, TheRowSaysWhyTheEstimateIsDegraded) {
  const hal::FrameTruth truth = truth_at_50mm();
  const auto lines = header_and_row(degraded_by_the_image_fit(), 2'000'000'000, &truth);
  ASSERT_EQ(lines.size(), 2U);
  expect_columns(lines, {{"status", "degraded"},
                         {"t_ms", "40.000"},
                         {"error_mm", "5.000"},  // (3, 4, 0) mm from the truth
                         {"refined", "1"},
                         {"corners_rejected", "2"},
                         {"encoder_disagrees", "0"},
                         {"fit_disagrees", "1"},
                         {"failed_stage", ""}});
}

TEST(CyclesCsv, WithoutTruthThereAreNoTruthColumnsAndNothingIsAnEmptyField) {
  loop::CycleRecord r = degraded_by_the_image_fit();
  r.publication.status = loop::EstimateStatus::kInvalid;
  r.latency_ns = -1;
  r.send_offset_ns = -1;
  const auto lines = header_and_row(r, r.trigger_ns, nullptr, false);
  ASSERT_EQ(lines.size(), 2U);
  EXPECT_EQ(lines[1].size(), lines[0].size());
  for (const std::string& name : lines[0]) {
    EXPECT_EQ(name.find("truth"), std::string::npos) << name;
    EXPECT_NE(name, "error_mm");
  }
  expect_columns(lines, {{"latency_ms", ""}, {"send_offset_ms", ""}, {"tcp_x_mm", ""}, {"rms_px", ""}});
  for (const std::string& field : lines[1]) {
    EXPECT_NE(field, "-1.000");
  }
}

TEST(CyclesCsv, AFailedStageAndNoTruthAreSaidSo) {
  loop::CycleRecord r = degraded_by_the_image_fit();
  r.failed_stage = 1;  // classify
  r.solved = false;
  r.refined = false;
  r.fit_disagrees = false;
  r.encoder_disagrees = true;
  r.publication.status = loop::EstimateStatus::kHeld;
  r.latency_ns = -1;
  const auto lines = header_and_row(r, r.trigger_ns, nullptr);
  ASSERT_EQ(lines.size(), 2U);
  expect_columns(lines, {{"failed_stage", loop::kSchedule[1].name},
                         {"solve_status", ""},
                         {"error_mm", ""},
                         {"truth_x_mm", ""},
                         {"latency_ms", ""},
                         {"encoder_disagrees", "1"},
                         {"fit_disagrees", "0"}});
}

// Verifies: REQ-ERR-009
TEST(CyclesCsv, AStreamThatRefusesTheWriteIsReported) {
  std::FILE* read_only = std::fopen("/dev/null", "r");
  ASSERT_NE(read_only, nullptr);
  EXPECT_FALSE(write_cycles_csv_header(read_only, true));
  EXPECT_FALSE(write_cycles_csv_row(read_only, degraded_by_the_image_fit(), nullptr, true, 0));
  static_cast<void>(std::fclose(read_only));  // opened for reading: nothing to flush
}

}  // namespace
}  // namespace cli
}  // namespace tcpest
