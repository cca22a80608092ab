// Result<T, E>: a value or an error, never both. Errors are values in tcpest:
// every fallible function returns one of these (or a unit's status enum), and
// the caller must look at it ([[nodiscard]]).
#pragma once

#include <cassert>
#include <type_traits>
#include <utility>

namespace tcpest {

// The value type of a Result that carries no value, only success or an error.
struct Unit {};

template <typename T, typename E>
class [[nodiscard]] Result {
  static_assert(std::is_default_constructible<T>::value, "Result<T, E> needs a default-constructible T");
  static_assert(std::is_enum<E>::value || std::is_class<E>::value, "E must be an error enum or struct");

 public:
  static Result success(T value) noexcept { return Result(std::move(value), E{}, true); }
  static Result failure(E error) noexcept { return Result(T{}, error, false); }

  bool ok() const noexcept { return ok_; }
  explicit operator bool() const noexcept { return ok_; }

  // Reading the value of a failed Result is our own bug, hence an assertion.
  const T& value() const& noexcept {
    assert(ok_);
    return value_;
  }
  T& value() & noexcept {
    assert(ok_);
    return value_;
  }
  const E& error() const noexcept {
    assert(!ok_);
    return error_;
  }
  T value_or(T fallback) const noexcept { return ok_ ? value_ : fallback; }

 private:
  Result(T value, E error, bool ok) noexcept : value_(std::move(value)), error_(error), ok_(ok) {}
  T value_;
  E error_;
  bool ok_;
};

template <typename E>
using Status = Result<Unit, E>;

template <typename E>
inline Status<E> ok_status() noexcept {
  return Status<E>::success(Unit{});
}

}  // namespace tcpest
