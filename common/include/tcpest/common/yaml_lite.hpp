// A reader for the small subset of YAML that calibration and configuration
// files use: block mappings by indentation, scalars, flow sequences of scalars
// (possibly over several lines), block sequences of scalars, comments,
// directives (%YAML), document markers and tags (OpenCV's !!opencv-matrix),
// which are ignored. Anything else (anchors, multi-line strings, sequences of
// mappings) is refused with the line it is on.
//
// The document is flattened into entries keyed by their dotted path
// ("camera_matrix.data"), each with its line, so that every error can name the
// file, the line and the field. Storage is fixed; nothing allocates. A reader
// that names the top-level keys it wants (KeySet) gets only those stored: every
// other entry is still checked as YAML line by line but not stored, so an
// unknown entry of any size (OpenCV's calibration writes matrices of
// thousands of numbers) takes no entry and no value space.
#pragma once

#include <cstddef>
#include <cstdint>

#include "tcpest/common/diagnostic.hpp"
#include "tcpest/common/result.hpp"

namespace tcpest {
namespace yaml {

constexpr std::size_t kMaxEntries = 160U;
constexpr std::size_t kMaxPath = 96U;
constexpr std::size_t kMaxValue = 1024U;
constexpr std::size_t kMaxFileBytes = std::size_t{256U} * 1024U;
constexpr std::size_t kMaxSequence = 64U;

struct Entry {
  char path[kMaxPath] = {};
  char value[kMaxValue] = {};  // scalar text, or the items of a sequence separated by '\n'
  std::uint32_t line = 0U;
  bool is_sequence = false;
  bool is_mapping = false;  // a key that opens a nested mapping (value empty)
  mutable bool used = false;  // set when read, to find unknown keys
};

// The top-level keys to store; an empty set (the default) stores every key.
struct KeySet {
  const char* const* keys = nullptr;
  std::size_t count = 0U;
  bool contains(const char* key, std::size_t length) const noexcept;
};

class Document {
 public:
  // Parses text; `file` only names the source in diagnostics. Top-level
  // entries not in `keep` (when it is not empty) are checked, not stored.
  Status<Diagnostic> parse(const char* text, std::size_t length, const char* file, KeySet keep = KeySet{}) noexcept;
  // Reads and parses a file (at most kMaxFileBytes; the buffer is a member).
  Status<Diagnostic> load(const char* path, KeySet keep = KeySet{}) noexcept;

  const char* file() const noexcept { return file_; }
  std::size_t size() const noexcept { return count_; }
  const Entry& entry(std::size_t i) const noexcept { return entries_[i]; }
  const Entry* find(const char* path) const noexcept;
  bool has(const char* path) const noexcept { return find(path) != nullptr; }

  // Typed access. Each failure names the field and its line.
  Result<double, Diagnostic> number(const char* path) const noexcept;
  Result<double, Diagnostic> number_or(const char* path, double fallback) const noexcept;
  Result<long long, Diagnostic> integer(const char* path) const noexcept;
  Status<Diagnostic> text(const char* path, char* out, std::size_t capacity) const noexcept;
  // A sequence of exactly `count` numbers.
  Status<Diagnostic> numbers(const char* path, double* out, std::size_t count) const noexcept;
  // A sequence of at most `capacity` numbers; the number read goes to `count`.
  Status<Diagnostic> numbers_upto(const char* path, double* out, std::size_t capacity,
                                  std::size_t& count) const noexcept;

  // First entry below `prefix` (a section name, or "" for all) that no typed
  // accessor has read: an unknown or misspelt key. nullptr if none.
  const Entry* first_unused(const char* prefix) const noexcept;

  Diagnostic error_at(const Entry* e, const char* path, const char* message) const noexcept;

 private:
  Entry entries_[kMaxEntries];
  std::size_t count_ = 0U;
  Entry skipped_{};  // the entry being checked but not stored (its value stays empty)
  char file_[256] = {};
  char buffer_[kMaxFileBytes] = {};
};

// Parses a whole string as one finite double (locale-independent).
bool parse_double(const char* text, double& out) noexcept;

}  // namespace yaml
}  // namespace tcpest
