// libFuzzer target: the JSON reader (tokenise, then walk every token with the
// typed accessors) and each JSON loader on the same bytes: colour model
// (vision), dataset sidecar (hal/render), corners input (`tcpest solve`).
// A loader may refuse the input; it must never crash, overrun or hang.
#include <cstddef>
#include <cstdint>

#include "cli/corners_json.hpp"
#include "tcpest/common/json.hpp"
#include "tcpest/render/sidecar.hpp"
#include "tcpest/vision/color_model.hpp"

namespace {

using namespace tcpest;

constexpr std::size_t kTokens = 4096U;
json::Token g_tokens[kTokens];

// Every accessor on every token: lookups run on whatever the parser built.
void walk(const json::Document& doc) {
  char text[64] = {};
  double numbers[3] = {};
  for (std::size_t i = 0U; i < doc.token_count(); ++i) {
    switch (doc.type(i)) {
      case json::TokenType::Object:
        static_cast<void>(doc.member(i, "corners"));  // any outcome is fine
        break;
      case json::TokenType::Array:
        static_cast<void>(doc.array_size(i));
        static_cast<void>(doc.element(i, 1U));       // any outcome is fine
        static_cast<void>(doc.numbers(i, numbers, 3U));
        break;
      case json::TokenType::String:
        static_cast<void>(doc.string(i, text, sizeof text));
        static_cast<void>(doc.string_equals(i, "format"));
        break;
      default:
        static_cast<void>(doc.number(i));
        break;
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const char* text = reinterpret_cast<const char*>(data);  // NOLINT(cppcoreguidelines-pro-type-reinterpret-cast): bytes as text
  json::Document doc(g_tokens, kTokens);
  if (doc.parse(text, size).ok()) {
    walk(doc);
  }
  static_cast<void>(vision::parse_color_model(text, size, "fuzz.json"));  // refusal is a valid outcome
  static_cast<void>(render::parse_sidecar(text, size, "fuzz.json"));
  static cli::CornersInput corners;
  char error[256] = {};
  static_cast<void>(cli::parse_corners_json(text, size, corners, error, sizeof error));
  return 0;
}
