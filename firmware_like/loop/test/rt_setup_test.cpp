// The stack pre-fault of the rt: section: what the thread's stack cannot take
// is refused by the configuration (field and range named) and never done by
// apply_rt_settings() (it used to overflow the stack: SIGSEGV at start-up).
#include "tcpest/loop/rt_setup.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <string>

#include "tcpest/loop/config.hpp"

namespace tcpest {
namespace loop {
namespace {

Status<Diagnostic> parse(const std::string& text, LoopConfig& config) {
  static yaml::Document doc;
  const auto parsed = doc.parse(text.data(), text.size(), "rt.yaml");
  if (!parsed.ok()) {
    return parsed;
  }
  return read_loop_config(doc, config);
}

// Verifies: REQ-LOOP-014
TEST(RtSetup, TheSafePrefaultIsWithinTheStackAndTheFixedBound) {
  const long long max_kb = max_prefault_stack_kb();
  EXPECT_GT(max_kb, 0);  // a test thread has some stack to spare
  EXPECT_LE(max_kb, kMaxPrefaultStackKb);
}

// Verifies: REQ-LOOP-014
TEST(RtSetup, APrefaultBeyondTheStackIsRefusedByTheConfigurationWithItsRange) {
  const long long max_kb = max_prefault_stack_kb();
  const char* const too_large[] = {"rt:\n  prefault_stack_kb: 8192000\n", "rt:\n  prefault_stack_kb: -1\n"};
  LoopConfig config;
  for (const char* text : too_large) {
    const auto s = parse(text, config);
    ASSERT_FALSE(s.ok()) << text;
    EXPECT_STREQ(s.error().field, "rt.prefault_stack_kb");
    EXPECT_EQ(s.error().line, 2U);
    EXPECT_NE(std::strstr(s.error().message, "allowed 0.."), nullptr) << s.error().message;
  }
  // One KiB beyond what this thread can take (read deeper in the stack, the
  // reader's bound is at most the test's).
  if (max_kb < kMaxPrefaultStackKb) {
    const auto s = parse("rt:\n  prefault_stack_kb: " + std::to_string(max_kb + 1) + "\n", config);
    ASSERT_FALSE(s.ok());
    EXPECT_STREQ(s.error().field, "rt.prefault_stack_kb");
  }
  ASSERT_TRUE(parse("rt:\n  prefault_stack_kb: 0\n", config).ok());
  EXPECT_EQ(config.rt.prefault_stack_kb, 0);
  ASSERT_TRUE(parse("rt:\n  prefault_stack_kb: 16\n", config).ok());
  EXPECT_EQ(config.rt.prefault_stack_kb, 16);
}

// Verifies: REQ-LOOP-014
TEST(RtSetup, APrefaultBeyondTheStackIsSkippedAndReportedNotACrash) {
  RtSettings settings{0 != 0, 0, -1, 0};
  // 64 MiB: more than a default (8 MiB) stack, the size that crashed.
  settings.prefault_stack_kb = static_cast<int>(kMaxPrefaultStackKb);
  if (max_prefault_stack_kb() >= kMaxPrefaultStackKb) {
    settings.prefault_stack_kb = static_cast<int>(kMaxPrefaultStackKb) + 1;  // an unlimited stack: past the fixed bound
  }
  const RtReport report = apply_rt_settings(settings);
  EXPECT_FALSE(report.stack_prefaulted);
  ASSERT_EQ(report.message_count, 1U);
  EXPECT_NE(std::strstr(report.messages[0], "rt.prefault_stack_kb"), nullptr) << report.messages[0];
  EXPECT_NE(std::strstr(report.messages[0], "allowed 0.."), nullptr) << report.messages[0];
  settings.prefault_stack_kb = 16;
  EXPECT_TRUE(apply_rt_settings(settings).stack_prefaulted);
}

}  // namespace
}  // namespace loop
}  // namespace tcpest
