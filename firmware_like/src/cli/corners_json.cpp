#include "cli/corners_json.hpp"

#include <cmath>
#include <cstdio>

#include "tcpest/common/json.hpp"
#include "tcpest/common/json_escape.hpp"

namespace tcpest {
namespace cli {

namespace {

// 1 object + 2 members + 12 entries x 3 tokens + a prior of 4, with room
// for ignored members.
constexpr std::size_t kMaxTokens = 512U;

// Appends text and numbers to a caller's buffer; remembers overflow.
class Writer {
 public:
  Writer(char* out, std::size_t capacity) noexcept : out_(out), capacity_(capacity) {
    if (capacity_ > 0U) {
      out_[0] = '\0';
    }
  }
  void text(const char* literal) noexcept {
    for (const char* p = literal; *p != '\0'; ++p) {
      put(*p);
    }
  }
  void put(char c) noexcept {
    if (used_ + 1U >= capacity_) {
      ok_ = false;
      return;
    }
    out_[used_++] = c;
    out_[used_] = '\0';
  }
  // `text` as the contents of a JSON string (json_escape.hpp).
  void escaped(const char* text) noexcept {
    if (used_ >= capacity_) {
      ok_ = false;
      return;
    }
    bool complete = false;
    used_ += json::escape_string(text, out_ + used_, capacity_ - used_, &complete);
    ok_ = ok_ && complete;
  }
  void integer(long value) noexcept {
    char buffer[32];
    static_cast<void>(std::snprintf(buffer, sizeof buffer, "%ld", value));  // 32 bytes hold any long
    text(buffer);
  }
  void number(double value) noexcept {
    if (!std::isfinite(value)) {
      text("null");
      return;
    }
    char buffer[40];
    static_cast<void>(std::snprintf(buffer, sizeof buffer, "%.12g", value));  // 40 bytes hold any %.12g
    text(buffer);
  }
  template <typename Vector>
  void vector(const Vector& v) noexcept {
    put('[');
    for (int i = 0; i < static_cast<int>(v.size()); ++i) {
      if (i > 0) {
        text(", ");
      }
      number(v[i]);
    }
    put(']');
  }
  bool ok() const noexcept { return ok_ && capacity_ > 0U; }

 private:
  char* out_;
  std::size_t capacity_;
  std::size_t used_ = 0U;
  bool ok_ = true;
};

}  // namespace

bool parse_corners_json(const char* text, std::size_t length, CornersInput& out, char* error,
                        std::size_t error_capacity) noexcept {
  static json::Token tokens[kMaxTokens];  // reused for every line; the command is single-threaded
  json::Document doc(tokens, kMaxTokens);
  out = CornersInput{};
  const auto parsed = doc.parse(text, length);
  if (!parsed.ok()) {
    static_cast<void>(std::snprintf(error, error_capacity, "not valid JSON (%s at offset %u)",
                                    json::to_string(parsed.error().code), parsed.error().offset));  // cut is fine
    return false;
  }
  if (doc.type(doc.root()) != json::TokenType::Object) {
    static_cast<void>(std::snprintf(error, error_capacity, "expected a JSON object"));  // idem
    return false;
  }
  const auto corners = doc.member(doc.root(), "corners");
  if (!corners.ok()) {
    static_cast<void>(std::snprintf(error, error_capacity, "missing member \"corners\""));  // idem
    return false;
  }
  if (doc.type(corners.value()) != json::TokenType::Array ||
      doc.array_size(corners.value()) != static_cast<std::size_t>(solver::kNumCorners)) {
    static_cast<void>(std::snprintf(error, error_capacity, "\"corners\" must be an array of %d entries ([u, v] or null)",
                                    solver::kNumCorners));  // a cut message is still a message
    return false;
  }
  for (int k = 0; k < solver::kNumCorners; ++k) {
    const auto ku = static_cast<std::size_t>(k);
    const auto entry = doc.element(corners.value(), ku);
    if (!entry.ok()) {
      static_cast<void>(std::snprintf(error, error_capacity, "corner %d: unreadable", k));  // idem
      return false;
    }
    if (doc.is_null(entry.value())) {
      continue;
    }
    double uv[2] = {0.0, 0.0};
    if (!doc.numbers(entry.value(), uv, 2U).ok()) {
      static_cast<void>(std::snprintf(error, error_capacity, "corner %d: expected [u, v] (two numbers, pixels) or null",
                                      k));  // idem
      return false;
    }
    out.observed.pixel[ku] = solver::Vec2(uv[0], uv[1]);
    out.observed.visible[ku] = true;
  }
  const auto prior = doc.member(doc.root(), "prior");
  if (prior.ok()) {
    if (!doc.numbers(prior.value(), out.prior, 3U).ok()) {
      static_cast<void>(std::snprintf(error, error_capacity, "\"prior\" must be [lambda_mm, phi_rad, theta_rad]"));  // idem
      return false;
    }
    out.has_prior = true;
  }
  return true;
}

bool has_estimate(const solver::SolveSummary& summary) noexcept {
  return solver::is_converged(summary.status) || summary.status == solver::SolveStatus::MaxIterations ||
         summary.status == solver::SolveStatus::SingularSystem;
}

bool format_solve_json(const solver::SolveSummary& summary, const solver::PoseVector& r, const solver::Vec3& tcp,
                       char* out, std::size_t capacity) noexcept {
  Writer w(out, capacity);
  const bool estimate = has_estimate(summary);
  w.text("{\"status\": \"");
  w.text(solver::to_string(summary.status));
  w.text("\", \"tcp\": ");
  if (estimate) {
    w.vector(tcp);
  } else {
    w.text("null");
  }
  w.text(", \"r\": ");
  if (estimate) {
    w.vector(r);
  } else {
    w.text("null");
  }
  w.text(", \"rms_px\": ");
  if (estimate) {
    w.number(summary.rms_px);
  } else {
    w.text("null");
  }
  w.text(", \"iterations\": ");
  w.integer(summary.iterations);
  w.text(", \"corners_used\": ");
  w.integer(summary.corners_used);
  w.text("}\n");
  return w.ok();
}

bool format_error_json(const char* message, unsigned long line, char* out, std::size_t capacity) noexcept {
  Writer w(out, capacity);
  w.text("{\"error\": \"");
  w.escaped(message);  // messages may quote the input: any bytes
  w.text("\", \"line\": ");
  w.integer(static_cast<long>(line));
  w.text("}\n");
  return w.ok();
}

bool format_project_json(const solver::CornerSet& corners, char* out, std::size_t capacity) noexcept {
  Writer w(out, capacity);
  w.text("{\"corners\": [");
  for (std::size_t k = 0; k < corners.pixel.size(); ++k) {
    w.text(k > 0U ? ", " : "");
    if (corners.present[k]) {
      w.vector(corners.pixel[k]);
    } else {
      w.text("null");
    }
  }
  w.text("], \"corners_3d\": [");
  for (std::size_t k = 0; k < corners.point.size(); ++k) {
    w.text(k > 0U ? ", " : "");
    if (corners.present[k]) {
      w.vector(corners.point[k]);
    } else {
      w.text("null");
    }
  }
  w.text("], \"tcp\": ");
  w.vector(corners.tcp);
  w.text("}\n");
  return w.ok();
}

}  // namespace cli
}  // namespace tcpest
