// libmesh's parallel loop on its persistent worker pool (libmesh/src/parallel.h, header-only
// and private: included by path) and RoFi's progress callback.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <stdexcept>
#include <thread>
#include <vector>

#include "../../libmesh/src/parallel.h"
#include "octshape/mesh/rofi.h"

namespace octshape::mesh {
namespace {

// Every index of [0, n) is visited exactly once, in the chunks the documented formula gives
// (the bit-identity of every denoiser for any thread count rests on them), over many loops in
// a row with changing thread counts (the pool grows and idles threads beyond the count).
TEST(ParallelFor, EveryIndexOnceInTheDocumentedChunksOverManyLoops) {
    for (int round = 0; round < 200; ++round) {
        const int threads = 1 + round % 4;
        const int n = 1 + (round * 997) % 5000;
        const int workers = detail::parallel_workers(n, threads);
        std::vector<int> visits(static_cast<std::size_t>(n), 0);
        std::vector<int> chunk_of(static_cast<std::size_t>(n), -1);
        std::atomic<int> chunks{0};
        detail::parallel_for(n, threads, [&](int begin, int end) {
            ++chunks;
            for (int i = begin; i < end; ++i) {
                ++visits[static_cast<std::size_t>(i)];
                chunk_of[static_cast<std::size_t>(i)] = begin;
            }
        });
        ASSERT_EQ(chunks.load(), workers) << "n " << n << " threads " << threads;
        for (int i = 0; i < n; ++i) {
            ASSERT_EQ(visits[static_cast<std::size_t>(i)], 1) << "index " << i;
            // Chunk w starts at n·w/W: the chunk holding i starts at the largest such bound ≤ i.
            int w = 0;
            while (w + 1 < workers && static_cast<long long>(n) * (w + 1) / workers <= i) ++w;
            ASSERT_EQ(chunk_of[static_cast<std::size_t>(i)],
                      static_cast<int>(static_cast<long long>(n) * w / workers));
        }
    }
}

// A worker's exception reaches the caller, and the pool serves the next loop.
TEST(ParallelFor, WorkerExceptionIsRethrownAndThePoolStillWorks) {
    const int n = 4096;
    EXPECT_THROW(detail::parallel_for(n, 2, [&](int begin, int) {
                     if (begin > 0) throw std::runtime_error("worker");
                 }),
                 std::runtime_error);
    std::atomic<long long> sum{0};
    detail::parallel_for(n, 2, [&](int begin, int end) {
        long long s = 0;
        for (int i = begin; i < end; ++i) s += i;
        sum += s;
    });
    EXPECT_EQ(sum.load(), static_cast<long long>(n) * (n - 1) / 2);
}

// Two callers at once: one gets the pool, the other its own threads; both finish correctly.
TEST(ParallelFor, ConcurrentCallersBothComplete) {
    const int n = 100000;
    std::vector<long long> sums(2, 0);
    const auto caller = [&](int c) {
        for (int round = 0; round < 50; ++round) {
            std::atomic<long long> s{0};
            detail::parallel_for(n, 2, [&](int begin, int end) {
                long long t = 0;
                for (int i = begin; i < end; ++i) t += i;
                s += t;
            });
            sums[static_cast<std::size_t>(c)] += s.load();
        }
    };
    std::thread other(caller, 1);
    caller(0);
    other.join();
    const long long expected = 50LL * n * (n - 1) / 2;
    EXPECT_EQ(sums[0], expected);
    EXPECT_EQ(sums[1], expected);
}

// A child forked after the pool's threads started (as `cohort` forks its workers) has none of
// them: its loops run on threads of their own and finish (a pool waiting for the parent's
// threads would hang the child).
TEST(ParallelFor, ForkedChildRunsItsLoops) {
    const auto sum = [](int n) {
        std::atomic<long long> s{0};
        detail::parallel_for(n, 2, [&](int begin, int end) {
            long long t = 0;
            for (int i = begin; i < end; ++i) t += i;
            s += t;
        });
        return s.load();
    };
    ASSERT_EQ(sum(10000), 10000LL * 9999 / 2);  // the pool's thread now runs
    const pid_t pid = ::fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
        bool ok = true;
        for (int r = 0; r < 20; ++r) ok = ok && sum(10000) == 10000LL * 9999 / 2;
        ::_exit(ok ? 0 : 1);
    }
    int status = -1;
    ASSERT_EQ(::waitpid(pid, &status, 0), pid);
    EXPECT_TRUE(WIFEXITED(status));
    EXPECT_EQ(WEXITSTATUS(status), 0);
}

// RofiParams::progress is called once per iteration, with k = 1, 2, … and the maximum.
TEST(RofiProgressCallback, CalledOncePerIterationInOrder) {
    Vertices V(4, 3);
    V << 0, 0, 0, 1, 0, 0, 0, 1, 0.1, 1, 1, 0;
    Faces F(2, 3);
    F << 0, 1, 2, 1, 3, 2;
    RofiParams p;
    p.iterations = 7;
    p.fix_boundary = false;
    std::vector<int> seen;
    p.progress = [&](int k, int total) {
        EXPECT_EQ(total, 7);
        seen.push_back(k);
    };
    const auto r = rofi_denoise(V, F, p);
    ASSERT_EQ(static_cast<int>(seen.size()), r.iterations);
    for (int k = 0; k < r.iterations; ++k) EXPECT_EQ(seen[static_cast<std::size_t>(k)], k + 1);
}

}  // namespace
}  // namespace octshape::mesh
