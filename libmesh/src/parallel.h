#pragma once
// Private to libmesh: a static-partition parallel loop on a pool of persistent threads.
//
// Every index is computed by exactly one thread from read-only inputs and writes only its own
// outputs, so results are bit-identical for any thread count (no reduction is split across
// threads). The first exception thrown by a worker is rethrown in the caller.
//
// The threads are started once per process (on the first loop that asks for them) and then
// wait on a futex (std::atomic::wait) between loops: a loop costs a wake-up (a few µs), not a
// thread start and join (~36 µs per thread measured here; RoFi runs 4 loops per iteration,
// which made two threads slower than one on a 13k-face mesh, issue 35). The chunks are fixed
// by n and the thread count; which thread runs a chunk is decided at run time (the first to
// claim it), which changes nothing in what it computes. One caller uses the pool at a time;
// a second caller at the same moment (another thread of the application, or a loop nested in
// a loop body) runs on threads of its own as before.

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

    // Runs chunk(w) for w = 0 .. workers − 1 (workers ≤ 65535). The chunks are claimed one at
    // a time by whichever thread comes first, the caller included: a pool thread that the
    // machine has not scheduled yet (a loaded machine) leaves its chunk to the others instead
    // of holding the loop up, so a loop is never much slower than on one thread. Which thread
    // runs a chunk does not change what the chunk computes. Returns false (nothing run) when
    // the pool is in use by another caller, or in a child process forked after the pool's
    // threads were started (`cohort` forks its workers; a child has none of the parent's
    // threads).
    template <class Chunk>
    bool run(int workers, const Chunk& chunk) {
        if (workers > 0xffff || ::getpid() != owner_) return false;
        std::unique_lock<std::mutex> lock(use_, std::try_to_lock);
        if (!lock.owns_lock()) return false;
        try {
            while (static_cast<int>(threads_.size()) < workers - 1) {
                // The generation before this loop's: the new thread looks at this loop too.
                const std::uint64_t seen = generation_.load(std::memory_order_relaxed);
                threads_.emplace_back([this, seen] { serve(seen); });
            }
        } catch (...) {
            return false;  // no thread could be started: the caller's fallback reports it
        }
        context_ = &chunk;
        call_ = [](const void* c, int w) { (*static_cast<const Chunk*>(c))(w); };
        done_.store(0, std::memory_order_relaxed);
        ++loop_;
        // Publishes the fields above to every thread whose claim succeeds (acquire).
        claim_.store(pack(loop_, workers, 0), std::memory_order_release);
        generation_.fetch_add(1, std::memory_order_release);
        generation_.notify_all();
        work();
        // Every chunk claimed has to finish before the fields are written again; a thread
        // that comes late finds the loop fully claimed (or a newer one) and touches nothing.
        for (int spin = 0;; ++spin) {
            const int d = done_.load(std::memory_order_acquire);
            if (d == workers) break;
            if (spin < kSpins) {
                pause();
            } else {
                done_.wait(d, std::memory_order_acquire);
            }
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

    // The claim word: loop number (32 bits), chunk count (16), next chunk to claim (16).
    static std::uint64_t pack(std::uint32_t loop, int workers, int next) {
        return static_cast<std::uint64_t>(loop) << 32 |
               static_cast<std::uint64_t>(workers) << 16 | static_cast<std::uint64_t>(next);
    }

    // Claims and runs chunks of the current loop until none is left.
    void work() {
        std::uint64_t c = claim_.load(std::memory_order_acquire);
        for (;;) {
            const auto workers = static_cast<int>((c >> 16) & 0xffff);
            const auto next = static_cast<int>(c & 0xffff);
            if (next >= workers) return;
            if (!claim_.compare_exchange_weak(c, c + 1, std::memory_order_acquire,
                                              std::memory_order_acquire)) {
                continue;  // c now holds the current word
            }
            // The loop cannot end before this chunk is done: its fields stay valid.
            call_(context_, next);
            if (done_.fetch_add(1, std::memory_order_acq_rel) + 1 == workers) done_.notify_one();
            c = claim_.load(std::memory_order_acquire);
        }
    }

    void serve(std::uint64_t seen) {
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
            work();
        }
    }

    std::mutex use_;                     // one caller at a time
    std::vector<std::thread> threads_;   // the pool (workers − 1 at most are needed)
    std::atomic<std::uint64_t> generation_{0};  // one more per loop: wakes the pool
    std::atomic<std::uint64_t> claim_{0};       // pack(loop, workers, next chunk)
    std::atomic<int> done_{0};           // chunks of the current loop finished
    std::uint32_t loop_ = 0;             // the caller's loop counter (under use_)
    // The loop, written before claim_ is stored (release), read after a claim (acquire).
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
