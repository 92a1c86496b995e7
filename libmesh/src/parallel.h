#pragma once
// Private to libmesh: a static-partition parallel loop on std::thread.
//
// Every index is computed by exactly one thread from read-only inputs and writes only its own
// outputs, so results are bit-identical for any thread count (no reduction is split across
// threads). The first exception thrown by a worker is rethrown in the caller.

#include <algorithm>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace octshape::mesh::detail {

// Calls body(begin, end) on disjoint contiguous chunks covering [0, n).
template <class Body>
void parallel_for(int n, int threads, const Body& body) {
    const int workers = std::clamp(threads, 1, std::max(1, n / 256));
    if (workers <= 1 || n <= 0) {
        if (n > 0) body(0, n);
        return;
    }
    std::exception_ptr error;
    std::mutex error_mutex;
    std::vector<std::thread> pool;
    pool.reserve(static_cast<std::size_t>(workers) - 1);
    const auto chunk = [&](int w) {
        const int begin = static_cast<int>(static_cast<long long>(n) * w / workers);
        const int end = static_cast<int>(static_cast<long long>(n) * (w + 1) / workers);
        try {
            body(begin, end);
        } catch (...) {
            const std::lock_guard<std::mutex> lock(error_mutex);
            if (!error) error = std::current_exception();
        }
    };
    for (int w = 1; w < workers; ++w) pool.emplace_back(chunk, w);
    chunk(0);
    for (auto& t : pool) t.join();
    if (error) std::rethrow_exception(error);
}

}  // namespace octshape::mesh::detail
