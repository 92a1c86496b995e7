#pragma once
// Records the largest single heap allocation made through operator new while a probe is
// active, so that tests can show a reader never allocates more than a hostile file allows.
// The test runner replaces the global operator new/delete (alloc_probe.cpp) with thin
// malloc/free wrappers; outside a probe they only forward.

#include <cstddef>

namespace octshape::test {

class AllocProbe {
  public:
    AllocProbe();   // starts recording (probes do not nest)
    ~AllocProbe();  // stops recording
    AllocProbe(const AllocProbe&) = delete;
    AllocProbe& operator=(const AllocProbe&) = delete;
    // Largest single allocation request, in bytes, since construction.
    [[nodiscard]] std::size_t largest() const;
};

}  // namespace octshape::test
