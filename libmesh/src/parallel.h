#pragma once
// Private to libmesh: a static-partition parallel loop on a pool of persistent threads.
//
// Every index is computed by exactly one thread from read-only inputs and writes only its own
// outputs, so results are bit-identical for any thread count (no reduction is split across
// threads). The first exception thrown by a worker is rethrown in the caller.
//
// The threads are started once per process (on the first loop that asks for them) and then
// wait on a futex (std::atomic::wait) between loops: a loop costs a wake-up (a few µs), not a
// thread start and join (~30–60 µs per thread on this kind of machine; RoFi runs 4–5 loops
// per iteration, which made two threads slower than one on a 13k-face mesh, issue 35). One
// caller uses the pool at a time; a second caller at the same moment (another thread of the
// application, or a loop nested in a loop body) runs on threads of its own as before.

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace octshape::mesh::detail {

class WorkerPool {
public:
    // The process's pool. Never destroyed: its threads sleep on the futex until the process
    // ends (no join at exit, which could wait on a thread of a loop still running elsewhere).
    static WorkerPool& instance() {
        static WorkerPool* const pool = new WorkerPool;
        return *pool;
    }

    WorkerPool(const WorkerPool&) = delete;
    WorkerPool& operator=(const WorkerPool&) = delete;

    // Runs chunk(w) for w = 0 .. workers − 1, chunk 0 on the calling thread. Returns false
    // (nothing run) when the pool is in use by another caller, or in a child process forked
    // after the pool's threads were started (`cohort` forks its workers; a child has none of
    // the parent's threads).
    template <class Chunk>
    bool run(int workers, const Chunk& chunk) {
        if (::getpid() != owner_) return false;
        std::unique_lock<std::mutex> lock(use_, std::try_to_lock);
        if (!lock.owns_lock()) return false;
        try {
            while (static_cast<int>(threads_.size()) < workers - 1) {
                const int k = static_cast<int>(threads_.size()) + 1;
                // The generation before this loop's: the new thread waits for the next one.
                const std::uint64_t seen = generation_.load(std::memory_order_relaxed);
                threads_.emplace_back([this, k, seen] { serve(k, seen); });
            }
        } catch (...) {
            return false;  // no thread could be started: the caller's fallback reports it
        }
        workers_ = workers;
        context_ = &chunk;
        call_ = [](const void* c, int w) { (*static_cast<const Chunk*>(c))(w); };
        pending_.store(static_cast<int>(threads_.size()), std::memory_order_relaxed);
        generation_.fetch_add(1, std::memory_order_release);
        generation_.notify_all();
        chunk(0);
        // Every pool thread acknowledges the loop (those beyond `workers` at once), so no
        // thread can still be reading this loop's fields when the next loop writes them.
        for (int spin = 0; pending_.load(std::memory_order_acquire) != 0; ++spin) {
            if (spin < kSpins) {
                pause();
                continue;
            }
            const int p = pending_.load(std::memory_order_acquire);
            if (p != 0) pending_.wait(p, std::memory_order_acquire);
        }
        return true;
    }

private:
    // Busy-wait rounds before sleeping on the futex: 200 x86 `pause` ≈ 5 µs on this machine
    // (measured: 2,000 take 50 µs on Zen 4), about a futex wake-up's latency; short, because
    // the machine may have fewer free cores than threads.
    static constexpr int kSpins = 200;

    WorkerPool() : owner_(::getpid()) {}

    static void pause() {
#if defined(__x86_64__) || defined(__i386__)
        __builtin_ia32_pause();
#endif
    }

    void serve(int k, std::uint64_t seen) {
        for (;;) {
            std::uint64_t now = seen;
            for (int spin = 0; (now = generation_.load(std::memory_order_acquire)) == seen;
                 ++spin) {
                if (spin < kSpins) {
                    pause();
                } else {
                    generation_.wait(seen, std::memory_order_acquire);
                }
            }
            seen = now;
            if (k < workers_) call_(context_, k);
            if (pending_.fetch_sub(1, std::memory_order_acq_rel) == 1) pending_.notify_one();
        }
    }

    std::mutex use_;                     // one caller at a time
    std::vector<std::thread> threads_;   // thread k − 1 runs chunk k
    std::atomic<std::uint64_t> generation_{0};  // one more per loop
    std::atomic<int> pending_{0};        // pool threads yet to acknowledge the loop
    // The loop, written before generation_ is raised (release) and read after (acquire).
    int workers_ = 0;
    const void* context_ = nullptr;
    void (*call_)(const void*, int) = nullptr;
    pid_t owner_;                        // the process whose threads these are
};

// The number of chunks parallel_for uses for n items: at most one per 256 items.
inline int parallel_workers(int n, int threads) {
    return std::clamp(threads, 1, std::max(1, n / 256));
}

// Calls body(begin, end) on disjoint contiguous chunks covering [0, n): chunk w of W =
// parallel_workers(n, threads) is [n·w/W, n·(w+1)/W).
template <class Body>
void parallel_for(int n, int threads, const Body& body) {
    const int workers = parallel_workers(n, threads);
    if (workers <= 1 || n <= 0) {
        if (n > 0) body(0, n);
        return;
    }
    std::exception_ptr error;
    std::mutex error_mutex;
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
    if (!WorkerPool::instance().run(workers, chunk)) {
        std::vector<std::thread> pool;
        pool.reserve(static_cast<std::size_t>(workers) - 1);
        for (int w = 1; w < workers; ++w) pool.emplace_back(chunk, w);
        chunk(0);
        for (auto& t : pool) t.join();
    }
    if (error) std::rethrow_exception(error);
}

}  // namespace octshape::mesh::detail
