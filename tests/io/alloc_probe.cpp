#include "io/alloc_probe.h"

#include <atomic>
#include <cstdlib>
#include <new>

namespace {

std::atomic<bool> g_recording{false};
std::atomic<std::size_t> g_largest{0};

void* allocate(std::size_t n) {
    if (g_recording.load(std::memory_order_relaxed)) {
        std::size_t prev = g_largest.load(std::memory_order_relaxed);
        while (n > prev && !g_largest.compare_exchange_weak(prev, n)) {
        }
    }
    if (void* p = std::malloc(n == 0 ? 1 : n)) return p;
    throw std::bad_alloc();
}

}  // namespace

namespace octshape::test {

AllocProbe::AllocProbe() {
    g_largest.store(0);
    g_recording.store(true);
}
AllocProbe::~AllocProbe() { g_recording.store(false); }
std::size_t AllocProbe::largest() const { return g_largest.load(); }

}  // namespace octshape::test

// Replaceable global allocation functions ([new.delete.single], [new.delete.array]). The nothrow
// forms are replaced too: libstdc++ frees memory from `new(n, nothrow)` (std::stable_sort's
// temporary buffer) with plain `operator delete`, so both must use the same allocator. The
// aligned forms keep their library definitions, which pair only with each other.
void* operator new(std::size_t n) { return allocate(n); }
void* operator new[](std::size_t n) { return allocate(n); }
void* operator new(std::size_t n, const std::nothrow_t& /*tag*/) noexcept {
    try {
        return allocate(n);
    } catch (const std::bad_alloc&) {
        return nullptr;
    }
}
void* operator new[](std::size_t n, const std::nothrow_t& tag) noexcept {
    return operator new(n, tag);
}
void operator delete(void* p, const std::nothrow_t& /*tag*/) noexcept { std::free(p); }
void operator delete[](void* p, const std::nothrow_t& /*tag*/) noexcept { std::free(p); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t /*n*/) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t /*n*/) noexcept { std::free(p); }
