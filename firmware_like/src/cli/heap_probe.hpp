// What `tcpest bench --soak` asks about the heap: how many allocations the
// measured cycles made, and how many bytes are in use.
//
// Counting allocations needs a replacement of the global allocation
// functions, and a program may hold only one. The tcpest executable installs
// its own (heap_counter.cpp, linked into the executable alone, never into the
// libraries); the tests install tests::AllocationScope's. Without a probe the
// soak says that the allocations were not counted.
#pragma once

#include <cstdint>

namespace tcpest {
namespace cli {

struct HeapProbe {
  const char* counts = "";  // what is counted, for the report ("operator new and malloc")
  // Starts counting the allocations of every thread.
  void (*arm)() noexcept = nullptr;
  // Stops counting; the allocations made since arm().
  std::uint64_t (*disarm)() noexcept = nullptr;
};

// Installs the probe (static storage; nullptr: none). Called once, before the command runs.
void set_heap_probe(const HeapProbe* probe) noexcept;
const HeapProbe* heap_probe() noexcept;

// Bytes the C allocator has handed out and not taken back (glibc's
// mallinfo2: the arena's blocks in use and the mmapped ones); -1 where it
// cannot tell.
long long heap_bytes_in_use() noexcept;

// The tcpest executable's counting probe (heap_counter.cpp; not in the libraries).
const HeapProbe* executable_heap_counter() noexcept;

}  // namespace cli
}  // namespace tcpest
