// SpscQueue<T>: a fixed-capacity queue between exactly one producer thread
// and one consumer thread, without locks. The storage is allocated once, by
// create() (start-up); pushing and popping never allocate and never wait:
// a full queue refuses the push, an empty one gives nothing.
//
// Items are written and read in place (they may be large): the producer
// fills begin_push()'s slot and publishes it with commit_push(); the
// consumer reads front() and frees it with pop().
#pragma once

#include <atomic>
#include <cstddef>
#include <memory>
#include <new>

namespace tcpest {

template <typename T>
class SpscQueue {
 public:
  SpscQueue() noexcept = default;

  // Capacity in items (>= 1). False when the storage cannot be allocated or
  // the capacity is 0; the queue then stays unusable (capacity() == 0).
  [[nodiscard]] bool create(std::size_t capacity) noexcept {
    if (capacity == 0U) {
      return false;
    }
    // One slot more than the capacity: head == tail means empty.
    slots_.reset(new (std::nothrow) T[capacity + 1U]);
    if (!slots_) {
      return false;
    }
    size_ = capacity + 1U;
    head_.store(0U, std::memory_order_relaxed);
    tail_.store(0U, std::memory_order_relaxed);
    return true;
  }
  std::size_t capacity() const noexcept { return size_ > 0U ? size_ - 1U : 0U; }

  // Producer: the next free slot, or nullptr when the queue is full.
  T* begin_push() noexcept {
    if (size_ == 0U) {
      return nullptr;
    }
    const std::size_t tail = tail_.load(std::memory_order_relaxed);
    const std::size_t next = tail + 1U == size_ ? 0U : tail + 1U;
    if (next == head_.load(std::memory_order_acquire)) {
      return nullptr;
    }
    return &slots_[tail];
  }
  // Producer: publishes the slot begin_push() gave (which must not be nullptr).
  void commit_push() noexcept {
    const std::size_t tail = tail_.load(std::memory_order_relaxed);
    tail_.store(tail + 1U == size_ ? 0U : tail + 1U, std::memory_order_release);
  }

  // Consumer: the oldest item, or nullptr when the queue is empty.
  T* front() noexcept {
    if (size_ == 0U) {
      return nullptr;
    }
    const std::size_t head = head_.load(std::memory_order_relaxed);
    if (head == tail_.load(std::memory_order_acquire)) {
      return nullptr;
    }
    return &slots_[head];
  }
  // Consumer: frees the item front() gave (which must not be nullptr).
  void pop() noexcept {
    const std::size_t head = head_.load(std::memory_order_relaxed);
    head_.store(head + 1U == size_ ? 0U : head + 1U, std::memory_order_release);
  }

  // Either side: true when nothing is queued (a snapshot).
  bool empty() const noexcept {
    return head_.load(std::memory_order_acquire) == tail_.load(std::memory_order_acquire);
  }

 private:
  std::unique_ptr<T[]> slots_;
  std::size_t size_ = 0U;
  std::atomic<std::size_t> head_{0U};  // written by the consumer
  std::atomic<std::size_t> tail_{0U};  // written by the producer
};

}  // namespace tcpest
