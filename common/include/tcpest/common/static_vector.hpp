// StaticVector<T, N>: a vector with its storage inside it (ETL-style). It never
// allocates; push_back reports "full" instead of growing.
#pragma once

#include <array>
#include <cassert>
#include <cstddef>

namespace tcpest {

template <typename T, std::size_t Capacity>
class StaticVector {
 public:
  using value_type = T;
  using iterator = T*;
  using const_iterator = const T*;

  static constexpr std::size_t capacity() noexcept { return Capacity; }
  std::size_t size() const noexcept { return size_; }
  bool empty() const noexcept { return size_ == 0U; }
  bool full() const noexcept { return size_ == Capacity; }

  // Returns false (and changes nothing) when the vector is full.
  [[nodiscard]] bool push_back(const T& value) noexcept {
    if (size_ == Capacity) {
      return false;
    }
    items_[size_] = value;
    ++size_;
    return true;
  }
  void pop_back() noexcept {
    assert(size_ > 0U);
    --size_;
  }
  void clear() noexcept { size_ = 0U; }
  // Shrinks only; growing would expose unset items.
  void truncate(std::size_t new_size) noexcept {
    if (new_size < size_) {
      size_ = new_size;
    }
  }

  T& operator[](std::size_t i) noexcept {
    assert(i < size_);
    return items_[i];
  }
  const T& operator[](std::size_t i) const noexcept {
    assert(i < size_);
    return items_[i];
  }
  T& back() noexcept {
    assert(size_ > 0U);
    return items_[size_ - 1U];
  }
  const T& back() const noexcept {
    assert(size_ > 0U);
    return items_[size_ - 1U];
  }
  T* data() noexcept { return items_.data(); }
  const T* data() const noexcept { return items_.data(); }
  iterator begin() noexcept { return items_.data(); }
  iterator end() noexcept { return items_.data() + size_; }
  const_iterator begin() const noexcept { return items_.data(); }
  const_iterator end() const noexcept { return items_.data() + size_; }

 private:
  std::array<T, Capacity> items_{};
  std::size_t size_ = 0U;
};

}  // namespace tcpest
