// The recorder of `tcpest run --record`: the cycle's side allocates nothing;
// rows, candump lines and overlays reach the disk; the cap rotates the files
// and removes the oldest overlays; a writer that cannot keep up drops and
// counts; a full disk is reported, never lost silently.
#include "cli/recorder.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cerrno>
#include <memory>
#include <string>
#include <vector>

#include "command_test_support.hpp"
#include "tcpest/test/alloc_counter.hpp"

namespace tcpest {
namespace cli {
namespace {

using command_test::count_of;
using command_test::fresh_dir;
using command_test::slurp;

bool exists(const std::string& path) { return ::access(path.c_str(), F_OK) == 0; }

class RecorderTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(load_model_setup("test", nullptr, nullptr, models_));
    width_ = models_.camera.width();
    height_ = models_.camera.height();
    pixels_.assign(static_cast<std::size_t>(width_) * static_cast<std::size_t>(height_) * 3U, 90U);
  }
  RecorderOptions options(const std::string& dir) const {
    RecorderOptions o;
    o.dir = dir.c_str();
    o.width = width_;
    o.height = height_;
    o.max_bytes = 0U;
    return o;
  }
  ImageView frame() const {
    return ImageView{pixels_.data(), width_, height_, static_cast<std::size_t>(width_) * 3U};
  }
  static loop::CycleRecord record(std::uint64_t cycle) {
    loop::CycleRecord r;
    r.cycle = cycle;
    r.frame_sequence = static_cast<std::uint32_t>(cycle);
    r.have_frame = true;
    r.trigger_ns = static_cast<std::int64_t>(cycle) * 40'000'000;
    r.latency_ns = cycle % 2U == 0U ? 3'000'000 : -1;  // odd cycles sent nothing
    return r;
  }
  static can::Frame heartbeat() {
    can::Frame f;
    f.id = 0x710U;
    f.length = 1U;
    f.data[0] = 5U;
    return f;
  }
  // One cycle as the loop runs it: two frames on the bus, then the observer.
  void cycle(Recorder& recorder, std::uint64_t n) {
    recorder.on_frame(heartbeat(), 1'700'000'000'000'000 + static_cast<std::int64_t>(n));
    recorder.on_frame(heartbeat(), 1'700'000'000'000'001 + static_cast<std::int64_t>(n));
    recorder.on_cycle(record(n), frame());
  }
  std::unique_ptr<Recorder> make(const RecorderOptions& o) {
    auto created = Recorder::create(o, models_);
    EXPECT_TRUE(created.ok());
    return created.ok() ? std::move(created.value()) : nullptr;
  }

  ModelSetup models_;
  int width_ = 0;
  int height_ = 0;
  std::vector<std::uint8_t> pixels_;
};

TEST_F(RecorderTest, TheCyclesSideAllocatesNothing) {
  const std::string dir = fresh_dir("rec_alloc");
  RecorderOptions o = options(dir);
  o.overlay_every = 3U;
  o.queue_capacity = 8U;  // small: drops happen inside the scope too
  auto recorder = make(o);
  ASSERT_NE(recorder, nullptr);
  std::size_t allocations = 0U;
  {
    test::AllocationScope scope;
    for (std::uint64_t n = 0; n < 300U; ++n) {
      cycle(*recorder, n);
    }
    allocations = scope.count();
  }
  EXPECT_EQ(allocations, 0U);
  EXPECT_TRUE(recorder->finish());
  EXPECT_EQ(recorder->counts().entries + recorder->counts().dropped, 300U);
}

TEST_F(RecorderTest, WritesARowPerCycleTheCandumpLinesAndEveryNthOverlay) {
  const std::string dir = fresh_dir("rec_rows");
  RecorderOptions o = options(dir);
  o.overlay_every = 5U;
  auto recorder = make(o);
  ASSERT_NE(recorder, nullptr);
  for (std::uint64_t n = 0; n < 10U; ++n) {
    cycle(*recorder, n);
  }
  recorder->on_frame(heartbeat(), 1'800'000'000'000'000);  // after the last cycle: written too
  ASSERT_TRUE(recorder->finish());
  const std::string csv = slurp(dir + "/cycles.csv");
  EXPECT_EQ(count_of(csv, "\n"), 11U);  // header + 10 rows
  EXPECT_EQ(csv.find("truth"), std::string::npos);
  EXPECT_EQ(csv.find("-1"), std::string::npos);
  const std::string log = slurp(dir + "/can.log");
  EXPECT_EQ(count_of(log, "\n"), 21U);
  EXPECT_NE(log.find("(1700000000.000000) sim0 710#05\n"), std::string::npos);
  EXPECT_TRUE(exists(dir + "/overlays/frame_000000.png"));
  EXPECT_TRUE(exists(dir + "/overlays/frame_000005.png"));
  EXPECT_FALSE(exists(dir + "/overlays/frame_000001.png"));
  EXPECT_EQ(recorder->counts().rows, 10U);
  EXPECT_EQ(recorder->counts().can_lines, 21U);
  EXPECT_EQ(recorder->counts().overlays, 2U);
  EXPECT_EQ(slurp(dir + "/overlays/frame_000005.png").size(), overlay_png_bytes(width_, height_));
}

TEST_F(RecorderTest, TheCapRotatesTheFilesAndKeepsK) {
  const std::string dir = fresh_dir("rec_cap");
  RecorderOptions o = options(dir);
  o.overlay_every = 0U;
  o.keep_files = 3U;
  o.max_bytes = 2U * 3U * 8192U;  // 8 KiB per file of each stream
  o.queue_capacity = 1000U;
  auto recorder = make(o);
  ASSERT_NE(recorder, nullptr);
  ASSERT_EQ(recorder->file_limit_bytes(), 8192U);
  for (std::uint64_t n = 0; n < 600U; ++n) {
    cycle(*recorder, n);
  }
  ASSERT_TRUE(recorder->finish());
  EXPECT_EQ(recorder->counts().dropped, 0U);
  EXPECT_GT(recorder->counts().rotations, 2U);
  std::size_t rows_on_disk = 0U;
  for (const char* name : {"/cycles.csv", "/cycles.1.csv", "/cycles.2.csv"}) {
    ASSERT_TRUE(exists(dir + name)) << name;
    const std::string text = slurp(dir + name);
    EXPECT_LE(text.size(), 8192U) << name;
    EXPECT_EQ(text.rfind("cycle,frame,", 0), 0U) << name << ": every file starts with the header";
    rows_on_disk += count_of(text, "\n") - 1U;
  }
  EXPECT_FALSE(exists(dir + "/cycles.3.csv"));
  EXPECT_LT(rows_on_disk, 600U);  // the oldest were removed
  EXPECT_TRUE(exists(dir + "/can.2.log"));
  EXPECT_FALSE(exists(dir + "/can.3.log"));
  EXPECT_LE(slurp(dir + "/can.1.log").size(), 8192U);
}

TEST_F(RecorderTest, TheCapKeepsTheNewestOverlays) {
  const std::string dir = fresh_dir("rec_overlay_cap");
  RecorderOptions o = options(dir);
  o.overlay_every = 1U;
  o.overlay_slots = 5U;
  o.max_bytes = 4U * overlay_png_bytes(width_, height_) + 1000U;  // overlays' share: 2 of them
  auto recorder = make(o);
  ASSERT_NE(recorder, nullptr);
  ASSERT_EQ(recorder->max_overlays(), 2U);
  for (std::uint64_t n = 0; n < 5U; ++n) {
    cycle(*recorder, n);
  }
  ASSERT_TRUE(recorder->finish());
  EXPECT_EQ(recorder->counts().overlays, 5U);
  EXPECT_EQ(recorder->counts().overlays_removed, 3U);
  EXPECT_FALSE(exists(dir + "/overlays/frame_000002.png"));
  EXPECT_TRUE(exists(dir + "/overlays/frame_000003.png"));
  EXPECT_TRUE(exists(dir + "/overlays/frame_000004.png"));
}

TEST_F(RecorderTest, AWriterThatCannotKeepUpDropsAndCounts) {
  const std::string dir = fresh_dir("rec_drop");
  RecorderOptions o = options(dir);
  o.overlay_every = 1U;  // a PNG of a frame per entry: the writer is slow
  o.overlay_slots = 1U;
  o.queue_capacity = 1U;
  auto recorder = make(o);
  ASSERT_NE(recorder, nullptr);
  for (std::uint64_t n = 0; n < 200U; ++n) {
    cycle(*recorder, n);
  }
  ASSERT_TRUE(recorder->finish());
  const RecorderCounts& c = recorder->counts();
  EXPECT_GT(c.dropped, 0U);
  EXPECT_EQ(c.entries + c.dropped, 200U);
  EXPECT_EQ(c.rows, c.entries);
  EXPECT_EQ(count_of(slurp(dir + "/cycles.csv"), "\n"), c.rows + 1U);
  EXPECT_GT(c.overlays_skipped, 0U);
  EXPECT_EQ(c.can_frames_lost, 2U * c.dropped);
}

TEST_F(RecorderTest, AFullDiskIsReported) {
  const std::string dir = fresh_dir("rec_full");
  ASSERT_EQ(::symlink("/dev/full", (dir + "/cycles.csv").c_str()), 0);
  auto recorder = make(options(dir));
  ASSERT_NE(recorder, nullptr);
  for (std::uint64_t n = 0; n < 3U; ++n) {
    cycle(*recorder, n);
  }
  EXPECT_FALSE(recorder->finish());
  EXPECT_EQ(recorder->write_errors(), 3U);
  EXPECT_EQ(recorder->first_errno(), ENOSPC);
  EXPECT_EQ(std::string(recorder->first_error_path()), dir + "/cycles.csv");
  EXPECT_EQ(recorder->counts().rows, 0U);
  EXPECT_EQ(recorder->counts().can_lines, 6U);  // the other stream goes on
}

TEST_F(RecorderTest, RefusesATargetThatIsNotADirectoryAndACapTooSmall) {
  auto created = Recorder::create(options("/dev/full"), models_);
  ASSERT_FALSE(created.ok());
  EXPECT_EQ(created.error(), RecorderError::kCannotCreate);
  const std::string dir = fresh_dir("rec_small");
  RecorderOptions o = options(dir);
  o.max_bytes = 1024U;
  created = Recorder::create(o, models_);
  ASSERT_FALSE(created.ok());
  EXPECT_EQ(created.error(), RecorderError::kBadOptions);
}

}  // namespace
}  // namespace cli
}  // namespace tcpest
