#include "tcpest/common/yaml_lite.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>

namespace tcpest {
namespace yaml {

namespace {

constexpr std::size_t kMaxDepth = 16U;
constexpr std::size_t kUnsetIndent = static_cast<std::size_t>(-1);

bool is_blank(char c) noexcept { return c == ' ' || c == '\t' || c == '\r'; }

// A view of a piece of the text.
struct Span {
  const char* begin = nullptr;
  std::size_t size = 0U;
};

Span trim(Span s) noexcept {
  while (s.size > 0U && is_blank(s.begin[0])) {
    ++s.begin;
    --s.size;
  }
  while (s.size > 0U && is_blank(s.begin[s.size - 1U])) {
    --s.size;
  }
  return s;
}

// The offset of the first character outside quotes ('...' or "...") for
// which stop(i) holds, or s.size if there is none.
template <typename Stop>
std::size_t first_outside_quotes(Span s, Stop stop) noexcept {
  char quote = '\0';
  for (std::size_t i = 0U; i < s.size; ++i) {
    const char c = s.begin[i];
    if (quote != '\0') {
      if (c == quote) {
        quote = '\0';
      }
      continue;
    }
    if (c == '"' || c == '\'') {
      quote = c;
    } else if (stop(i)) {
      return i;
    }
  }
  return s.size;
}

// Cuts a comment: '#' at the start or after white space, outside quotes.
Span strip_comment(Span s) noexcept {
  s.size = first_outside_quotes(
      s, [&s](std::size_t i) noexcept { return s.begin[i] == '#' && (i == 0U || is_blank(s.begin[i - 1U])); });
  return s;
}

Span unquote(Span s) noexcept {
  if (s.size >= 2U && (s.begin[0] == '"' || s.begin[0] == '\'') && s.begin[s.size - 1U] == s.begin[0]) {
    ++s.begin;
    s.size -= 2U;
  }
  return s;
}

bool append(char* out, std::size_t capacity, std::size_t& used, Span s) noexcept {
  if (used + s.size + 1U > capacity) {
    return false;
  }
  std::memcpy(out + used, s.begin, s.size);
  used += s.size;
  out[used] = '\0';
  return true;
}

bool append_char(char* out, std::size_t capacity, std::size_t& used, char c) noexcept {
  if (used + 2U > capacity) {
    return false;
  }
  out[used] = c;
  ++used;
  out[used] = '\0';
  return true;
}

// Adds the items of a flow sequence piece ("a, b" or "a, b]") to entry e,
// or only checks them when e is not `stored`. Returns false on overflow;
// sets `closed` when the ']' is found.
bool add_flow_items(Entry& e, bool stored, Span piece, bool& closed, bool& nested) noexcept {
  closed = false;
  nested = false;
  std::size_t used = std::strlen(e.value);
  std::size_t start = 0U;
  for (std::size_t i = 0U; i <= piece.size; ++i) {
    const bool at_end = (i == piece.size);
    const char c = at_end ? ',' : piece.begin[i];
    if (c == '[' || c == '{') {
      nested = true;
      return true;
    }
    if (c == ',' || c == ']') {
      Span item = unquote(trim(Span{piece.begin + start, i - start}));
      if (stored && item.size > 0U) {
        if (used > 0U && !append_char(e.value, sizeof e.value, used, '\n')) {
          return false;
        }
        if (!append(e.value, sizeof e.value, used, item)) {
          return false;
        }
      }
      start = i + 1U;
      if (c == ']') {
        closed = true;
        return trim(Span{piece.begin + i + 1U, piece.size - i - 1U}).size == 0U;
      }
    }
  }
  return true;
}

// A mapping level: its children's indentation and the length of its path.
struct Level {
  std::size_t indent;
  std::size_t path_length;
};

// The state of one parse: the document's entries, the open mapping levels,
// the current key path and what the lines above left open.
struct Parser {
  Entry* entries = nullptr;
  std::size_t& count;
  const Document& doc;  // its find() sees the entries added so far
  const char* file = nullptr;
  KeySet keep;
  Entry* skipped = nullptr;  // the slot of an entry checked but not stored
  Level levels[kMaxDepth + 1U] = {};
  std::size_t depth = 0U;
  char path[kMaxPath] = {};
  Entry* open_key = nullptr;   // entry whose value is still to come (mapping or block sequence)
  Entry* last_key = nullptr;   // the last entry added (a flow sequence may continue it)
  bool open_flow = false;      // inside a flow sequence that continues on the next line
  std::size_t open_flow_line = 0U;
  std::uint32_t line_number = 0U;
};

bool is_stored(const Parser& p, const Entry& e) noexcept { return &e != p.skipped; }

// Whether the current path's top-level key is one to store.
bool keeps_path(const Parser& p) noexcept {
  if (p.keep.count == 0U) {
    return true;
  }
  const char* dot = std::strchr(p.path, '.');
  const std::size_t length = (dot != nullptr) ? static_cast<std::size_t>(dot - p.path) : std::strlen(p.path);
  return p.keep.contains(p.path, length);
}

Status<Diagnostic> fail(const Parser& p, std::uint32_t line, const char* field, const char* message) noexcept {
  return Status<Diagnostic>::failure(Diagnostic::make(p.file, line, field, message));
}


// Block sequence item: "- value", added to the key above it.
Status<Diagnostic> add_sequence_item(Parser& p, std::size_t indent, Span content) noexcept {
  if (p.open_key == nullptr) {
    return fail(p, p.line_number, "", "sequence item without a key above it");
  }
  Entry& e = *p.open_key;
  // The key was pushed as a mapping level; a sequence opens none.
  if (p.depth > 0U && p.levels[p.depth].indent == kUnsetIndent &&
      p.levels[p.depth].path_length == std::strlen(e.path)) {
    --p.depth;
  }
  if (indent < p.levels[p.depth].indent) {
    return fail(p, p.line_number, e.path, "sequence item indented less than its key");
  }
  Span item = unquote(trim(Span{content.begin + 1U, content.size - 1U}));
  if (item.size > 0U && (item.begin[0] == '[' || item.begin[0] == '{' ||
                         std::memchr(item.begin, ':', item.size) != nullptr)) {
    return fail(p, p.line_number, e.path, "sequences of mappings or sequences are not supported");
  }
  e.is_mapping = false;
  e.is_sequence = true;
  if (!is_stored(p, e)) {
    return ok_status<Diagnostic>();
  }
  std::size_t used = std::strlen(e.value);
  if ((used > 0U && !append_char(e.value, sizeof e.value, used, '\n')) ||
      !append(e.value, sizeof e.value, used, item)) {
    return fail(p, p.line_number, e.path, "sequence too long");
  }
  return ok_status<Diagnostic>();
}

// Offset of the colon of "key: value" or "key:" (outside quotes), or
// content.size if there is none.
std::size_t key_colon(Span content) noexcept {
  return first_outside_quotes(content, [&content](std::size_t i) noexcept {
    return content.begin[i] == ':' && (i + 1U == content.size || content.begin[i + 1U] == ' ');
  });
}

// A flow sequence whose ']' never came: reported at its '['.
Status<Diagnostic> unclosed_flow(const Parser& p) noexcept {
  return fail(p, static_cast<std::uint32_t>(p.open_flow_line), p.last_key->path,
              "flow sequence '[' not closed with ']'");
}

// A line that continues the flow sequence of the last entry. A key ("k: v")
// or a block item ("- v") cannot be one of its items: the '[' above was not
// closed, and that is where the error is.
Status<Diagnostic> continue_flow(Parser& p, Span content) noexcept {
  Entry& e = *p.last_key;
  const bool block_item = content.begin[0] == '-' && (content.size == 1U || content.begin[1] == ' ');
  if (key_colon(content) != content.size || block_item) {
    return unclosed_flow(p);
  }
  bool closed = false;
  bool nested = false;
  if (!add_flow_items(e, is_stored(p, e), content, closed, nested)) {
    return fail(p, p.line_number, e.path, "sequence too long");
  }
  if (nested) {
    return fail(p, p.line_number, e.path, "nested sequences are not supported");
  }
  p.open_flow = !closed;
  return ok_status<Diagnostic>();
}

// Sets the path of a key at `indent`: its parent level's path, '.', the key.
Status<Diagnostic> place_key(Parser& p, std::size_t indent, Span key) noexcept {
  // Find the parent: a mapping opened by the key above takes its
  // indentation from its first child; then close every deeper level.
  if (p.depth > 0U && p.levels[p.depth].indent == kUnsetIndent) {
    if (indent > p.levels[p.depth - 1U].indent) {
      p.levels[p.depth].indent = indent;
    } else {
      --p.depth;  // the key above has no children: an empty value
    }
  }
  while (p.depth > 0U && indent < p.levels[p.depth].indent) {
    --p.depth;
  }
  if (indent != p.levels[p.depth].indent) {
    return fail(p, p.line_number, "", "unexpected indentation");
  }
  p.path[p.levels[p.depth].path_length] = '\0';
  std::size_t used = p.levels[p.depth].path_length;
  if ((used > 0U && !append_char(p.path, sizeof p.path, used, '.')) || !append(p.path, sizeof p.path, used, key)) {
    return fail(p, p.line_number, "", "key path too long");
  }
  return ok_status<Diagnostic>();
}

// The value after "key:" of the new entry e: a nested mapping to come, a
// flow sequence or a scalar.
Status<Diagnostic> set_value(Parser& p, Entry& e, Span value) noexcept {
  if (value.size > 0U && value.begin[0] == '!') {
    // A tag (e.g. !!opencv-matrix): ignored.
    std::size_t t = 0U;
    while (t < value.size && value.begin[t] != ' ') {
      ++t;
    }
    value = trim(Span{value.begin + t, value.size - t});
  }
  if (value.size == 0U) {
    if (p.depth == kMaxDepth) {
      return fail(p, p.line_number, p.path, "nesting too deep");
    }
    e.is_mapping = true;
    p.open_key = &e;
    ++p.depth;
    p.levels[p.depth] = Level{kUnsetIndent, std::strlen(p.path)};  // indentation fixed by the first child
    return ok_status<Diagnostic>();
  }
  if (value.begin[0] == '&' || value.begin[0] == '*') {
    return fail(p, p.line_number, p.path, "anchors and aliases are not supported");
  }
  if (value.begin[0] == '|' || value.begin[0] == '>') {
    return fail(p, p.line_number, p.path, "multi-line strings are not supported");
  }
  if (value.begin[0] == '[') {
    e.is_sequence = true;
    bool closed = false;
    bool nested = false;
    if (!add_flow_items(e, is_stored(p, e), Span{value.begin + 1U, value.size - 1U}, closed, nested)) {
      return fail(p, p.line_number, p.path, "sequence too long, or text after ']'");
    }
    if (nested) {
      return fail(p, p.line_number, p.path, "nested sequences are not supported");
    }
    p.open_flow = !closed;
    p.open_flow_line = p.line_number;
    return ok_status<Diagnostic>();
  }
  Span scalar = unquote(value);
  std::size_t value_used = 0U;
  if (is_stored(p, e) && !append(e.value, sizeof e.value, value_used, scalar)) {
    return fail(p, p.line_number, p.path, "value too long");
  }
  return ok_status<Diagnostic>();
}

// "key: value" or "key:": a new entry below its parent mapping.
Status<Diagnostic> add_key(Parser& p, std::size_t indent, Span content) noexcept {
  const std::size_t colon = key_colon(content);
  if (colon == content.size) {
    return fail(p, p.line_number, "", "expected 'key: value'");
  }
  Span key = unquote(trim(Span{content.begin, colon}));
  Span value = trim(Span{content.begin + colon + 1U, content.size - colon - 1U});
  if (key.size == 0U) {
    return fail(p, p.line_number, "", "empty key");
  }
  const auto placed = place_key(p, indent, key);
  if (!placed.ok()) {
    return placed;
  }
  const bool stored = keeps_path(p);
  if (stored && p.doc.find(p.path) != nullptr) {
    return fail(p, p.line_number, p.path, "duplicate key");
  }
  if (stored && p.count == kMaxEntries) {
    return fail(p, p.line_number, p.path, "too many keys");
  }
  Entry& e = stored ? p.entries[p.count] : *p.skipped;
  e = Entry{};
  copy_text(e.path, sizeof e.path, p.path);
  e.line = p.line_number;
  if (stored) {
    ++p.count;
  }
  p.last_key = &e;
  p.open_key = nullptr;
  return set_value(p, e, value);
}

// One line of the text (without its '\n').
Status<Diagnostic> parse_line(Parser& p, Span raw) noexcept {
  Span content = trim(strip_comment(raw));
  if (content.size == 0U) {
    return ok_status<Diagnostic>();
  }
  std::size_t indent = 0U;
  while (indent < raw.size && raw.begin[indent] == ' ') {
    ++indent;
  }
  if (indent < raw.size && raw.begin[indent] == '\t') {
    return fail(p, p.line_number, "", "tab in indentation (YAML allows spaces only)");
  }

  if (p.open_flow) {
    return continue_flow(p, content);
  }
  if (content.begin[0] == '%' || (content.size >= 3U && std::strncmp(content.begin, "---", 3U) == 0) ||
      (content.size >= 3U && std::strncmp(content.begin, "...", 3U) == 0)) {
    return ok_status<Diagnostic>();  // directive or document marker
  }
  if (content.begin[0] == '-' && (content.size == 1U || content.begin[1] == ' ')) {
    return add_sequence_item(p, indent, content);
  }
  return add_key(p, indent, content);
}

}  // namespace

bool parse_double(const char* text, double& out) noexcept {
  const char* p = text;
  while (*p == ' ') {
    ++p;
  }
  if (*p == '+') {
    ++p;
  }
  const char* end = p + std::strlen(p);
  while (end > p && end[-1] == ' ') {
    --end;
  }
  if (p == end) {
    return false;
  }
  double value = 0.0;
  const auto parsed = std::from_chars(p, end, value);
  if (parsed.ec != std::errc() || parsed.ptr != end || !std::isfinite(value)) {
    return false;
  }
  out = value;
  return true;
}

bool KeySet::contains(const char* key, std::size_t length) const noexcept {
  for (std::size_t i = 0U; i < count; ++i) {
    if (std::strlen(keys[i]) == length && std::strncmp(keys[i], key, length) == 0) {
      return true;
    }
  }
  return false;
}

Status<Diagnostic> Document::load(const char* path, KeySet keep) noexcept {
  copy_text(file_, sizeof file_, path);
  std::FILE* f = std::fopen(path, "rb");
  if (f == nullptr) {
    return Status<Diagnostic>::failure(Diagnostic::make(path, 0U, "", "cannot open the file"));
  }
  const std::size_t n = std::fread(buffer_, 1U, sizeof buffer_, f);
  const bool read_error = std::ferror(f) != 0;
  const bool too_big = (n == sizeof buffer_);
  static_cast<void>(std::fclose(f));  // read-only file: nothing to flush, a close error changes nothing
  if (read_error) {
    return Status<Diagnostic>::failure(Diagnostic::make(path, 0U, "", "cannot read the file"));
  }
  if (too_big) {
    return Status<Diagnostic>::failure(Diagnostic::make(path, 0U, "", "file too large (256 KiB at most)"));
  }
  return parse(buffer_, n, path, keep);
}

Status<Diagnostic> Document::parse(const char* text, std::size_t length, const char* file, KeySet keep) noexcept {
  if (file != file_) {
    copy_text(file_, sizeof file_, file);
  }
  count_ = 0U;
  Parser p{entries_, count_, *this, file_, keep, &skipped_};
  p.levels[0] = Level{0U, 0U};
  std::size_t pos = 0U;
  while (pos < length) {
    ++p.line_number;
    const char* line_begin = text + pos;
    std::size_t line_size = 0U;
    while (pos + line_size < length && text[pos + line_size] != '\n') {
      ++line_size;
    }
    pos += line_size + 1U;
    const auto status = parse_line(p, Span{line_begin, line_size});
    if (!status.ok()) {
      return status;
    }
  }
  if (p.open_flow) {
    return unclosed_flow(p);
  }
  return ok_status<Diagnostic>();
}

const Entry* Document::find(const char* path) const noexcept {
  for (std::size_t i = 0U; i < count_; ++i) {
    if (std::strcmp(entries_[i].path, path) == 0) {
      return &entries_[i];
    }
  }
  return nullptr;
}

Diagnostic Document::error_at(const Entry* e, const char* path, const char* message) const noexcept {
  return Diagnostic::make(file_, e != nullptr ? e->line : 0U, path, message);
}

Result<double, Diagnostic> Document::number(const char* path) const noexcept {
  using R = Result<double, Diagnostic>;
  const Entry* e = find(path);
  if (e == nullptr) {
    return R::failure(error_at(e, path, "missing"));
  }
  e->used = true;
  double value = 0.0;
  if (e->is_sequence || e->is_mapping || !parse_double(e->value, value)) {
    return R::failure(error_at(e, path, "expected a finite number"));
  }
  return R::success(value);
}

Result<double, Diagnostic> Document::number_or(const char* path, double fallback) const noexcept {
  if (find(path) == nullptr) {
    return Result<double, Diagnostic>::success(fallback);
  }
  return number(path);
}

Result<long long, Diagnostic> Document::integer(const char* path) const noexcept {
  using R = Result<long long, Diagnostic>;
  const Entry* e = find(path);
  if (e == nullptr) {
    return R::failure(error_at(e, path, "missing"));
  }
  e->used = true;
  long long value = 0;
  const char* begin = e->value;
  const char* end = begin + std::strlen(begin);
  const auto parsed = std::from_chars(begin, end, value);
  if (e->is_sequence || e->is_mapping || begin == end || parsed.ec != std::errc() || parsed.ptr != end) {
    return R::failure(error_at(e, path, "expected an integer"));
  }
  return R::success(value);
}

Status<Diagnostic> Document::text(const char* path, char* out, std::size_t capacity) const noexcept {
  const Entry* e = find(path);
  if (e == nullptr) {
    return Status<Diagnostic>::failure(error_at(e, path, "missing"));
  }
  e->used = true;
  if (e->is_sequence || e->is_mapping) {
    return Status<Diagnostic>::failure(error_at(e, path, "expected a text value"));
  }
  if (std::strlen(e->value) + 1U > capacity) {
    return Status<Diagnostic>::failure(error_at(e, path, "text too long"));
  }
  copy_text(out, capacity, e->value);
  return ok_status<Diagnostic>();
}

Status<Diagnostic> Document::numbers_upto(const char* path, double* out, std::size_t capacity,
                                          std::size_t& count) const noexcept {
  count = 0U;
  const Entry* e = find(path);
  if (e == nullptr) {
    return Status<Diagnostic>::failure(error_at(e, path, "missing"));
  }
  e->used = true;
  if (!e->is_sequence) {
    return Status<Diagnostic>::failure(error_at(e, path, "expected a sequence of numbers"));
  }
  const char* p = e->value;
  char item[64];
  while (*p != '\0') {
    std::size_t n = 0U;
    while (p[n] != '\0' && p[n] != '\n') {
      ++n;
    }
    if (n + 1U > sizeof item) {
      return Status<Diagnostic>::failure(error_at(e, path, "sequence item too long"));
    }
    std::memcpy(item, p, n);
    item[n] = '\0';
    if (count == capacity) {
      return Status<Diagnostic>::failure(error_at(e, path, "too many values"));
    }
    if (!parse_double(item, out[count])) {
      char message[128];
      static_cast<void>(std::snprintf(message, sizeof message, "item %zu is not a finite number", count + 1U));
      return Status<Diagnostic>::failure(error_at(e, path, message));
    }
    ++count;
    p += n;
    if (*p == '\n') {
      ++p;
    }
  }
  return ok_status<Diagnostic>();
}

Status<Diagnostic> Document::numbers(const char* path, double* out, std::size_t count) const noexcept {
  std::size_t got = 0U;
  auto status = numbers_upto(path, out, count, got);
  if (!status.ok()) {
    // More values than expected reads as "too many values"; say how many are wanted.
    const Entry* e = find(path);
    if (e != nullptr && e->is_sequence && std::strstr(status.error().message, "too many") != nullptr) {
      char message[128];
      static_cast<void>(std::snprintf(message, sizeof message, "expected %zu numbers, found more", count));
      return Status<Diagnostic>::failure(error_at(e, path, message));
    }
    return status;
  }
  if (got != count) {
    char message[128];
    static_cast<void>(std::snprintf(message, sizeof message, "expected %zu numbers, found %zu", count, got));
    return Status<Diagnostic>::failure(error_at(find(path), path, message));
  }
  return ok_status<Diagnostic>();
}

const Entry* Document::first_unused(const char* prefix) const noexcept {
  const std::size_t n = std::strlen(prefix);
  for (std::size_t i = 0U; i < count_; ++i) {
    const Entry& e = entries_[i];
    if (e.used || e.is_mapping) {
      continue;
    }
    if (n == 0U || (std::strncmp(e.path, prefix, n) == 0 && (e.path[n] == '.' || e.path[n] == '\0'))) {
      return &e;
    }
  }
  return nullptr;
}

}  // namespace yaml
}  // namespace tcpest
