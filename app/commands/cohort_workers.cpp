// The worker processes of `octshape cohort`: scheduling, supervision (crash, hang), progress.
// Design and tests: docs/cohort.md, "Isolation and progress".

#include "commands/cohort_workers.h"

#include <poll.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <stdexcept>

#include "octshape/error.h"

namespace octshape::app {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

std::string signal_name(int sig) {
    const char* d = ::strsignal(sig);
    return "signal " + std::to_string(sig) + (d != nullptr ? std::string(" (") + d + ")" : "");
}

// ---- The workers: eye after eye ----------------------------------------------------------

// A worker is a child process forked by the batch that analyses eye after eye: the parent sends
// it an eye's index, the worker writes the eye's JSON (atomically) and answers with an EyeDone
// record, then waits for the next index. Parent and worker talk over a SOCK_SEQPACKET socket
// pair: every message arrives whole, a worker's death reads as end-of-file, and a send to a dead
// peer fails with EPIPE instead of raising SIGPIPE (MSG_NOSIGNAL). Supervision: docs/cohort.md.
struct EyeDone {
    std::uint64_t index = 0;  // the eye's index in the batch's item list
    std::int32_t code = 0;    // 0: the eye's JSON is written; else the exit code of the failure
    std::uint32_t length = 0;  // bytes of the failure message that follow
};
constexpr std::size_t kMaxMessage = 4000;  // a failure message is cut to this many bytes


// The worker's life: eye after eye until the parent closes its end of the socket.
[[noreturn]] void worker_main(const CohortOptions& o, const SubjectSource& subjects,
                              const std::vector<Item>& items, const fs::path& out, int sock) {
    // Ctrl-C reaches the whole process group: the batch stops its workers itself (stop_batch),
    // so that an eye cut short is never recorded as a crash.
    ::signal(SIGINT, SIG_IGN);
    ::signal(SIGTERM, SIG_IGN);
    for (;;) {
        std::uint64_t index = 0;
        const auto n = ::recv(sock, &index, sizeof index, 0);
        if (n < 0 && errno == EINTR) continue;
        if (n != static_cast<ssize_t>(sizeof index) || index >= items.size()) break;
        std::string message;
        const int code = analyse_eye(o, subjects, items[index], out, message);
        if (message.size() > kMaxMessage) message.resize(kMaxMessage);
        EyeDone done;
        done.index = index;
        done.code = code;
        done.length = static_cast<std::uint32_t>(message.size());
        std::string record(sizeof done, '\0');
        std::memcpy(record.data(), &done, sizeof done);
        record += message;
        spdlog::default_logger()->flush();
        // A failed send means the parent is gone (and this worker with it: PR_SET_PDEATHSIG).
        if (::send(sock, record.data(), record.size(), MSG_NOSIGNAL) < 0) break;
    }
    spdlog::default_logger()->flush();
    ::_exit(0);
}

// ---- The parent: scheduling, progress, records -------------------------------------------

class Progress {
public:
    Progress(std::size_t total, std::size_t pending, bool bar)
        : total_(total), pending_(pending), bar_(bar), start_(Clock::now()) {}

    void finished(const Item& item, bool ok, const std::string& reason, double seconds) {
        ++done_;
        if (!ok) ++failed_;
        if (bar_) {
            if (!ok) {
                clear();
                spdlog::warn("eye {}: {}", item.key, scrub(reason, item.path));
            }
            draw();
        } else if (ok) {
            spdlog::info("[{}/{}] eye {} ({:.1f} s)", done_, pending_, item.key, seconds);
        } else {
            spdlog::warn("[{}/{}] eye {}: FAILED: {}", done_, pending_, item.key,
                         scrub(reason, item.path));
        }
    }
    void end() {
        if (bar_ && pending_ > 0) {
            draw();
            std::fputc('\n', stderr);
        }
    }
    void draw() const {
        if (!bar_) return;
        const double t = std::chrono::duration<double>(Clock::now() - start_).count();
        const double rate = t > 0 ? static_cast<double>(done_) / t : 0.0;
        constexpr int kWidth = 30;
        const int fill = pending_ == 0 ? kWidth
                                    : static_cast<int>(kWidth * static_cast<double>(done_) /
                                                       static_cast<double>(pending_));
        std::string bar(static_cast<std::size_t>(fill), '#');
        bar.resize(kWidth, '.');
        std::string eta = "--";
        if (rate > 0) {
            const auto s = static_cast<long>(static_cast<double>(pending_ - done_) / rate);
            eta = fmt::format("{}:{:02}:{:02}", s / 3600, (s / 60) % 60, s % 60);
        }
        std::fprintf(stderr, "\r[%s] %zu/%zu files  %.2f files/s  ETA %s  failed %zu   ",
                     bar.c_str(), done_, pending_, rate, eta.c_str(), failed_);
        std::fflush(stderr);
    }

private:
    void clear() const { std::fprintf(stderr, "\r%80s\r", ""); }
    std::size_t total_;
    std::size_t pending_;
    bool bar_;
    Clock::time_point start_;
    std::size_t done_ = 0;
    std::size_t failed_ = 0;
};

// The parent's view of one worker process.
struct Worker {
    pid_t pid = -1;  // -1: no worker in this slot
    int sock = -1;   // the parent's end of the worker's socket pair
    bool busy = false;
    std::size_t index = 0;        // the eye in progress (when busy)
    Clock::time_point start = {};  // when that eye was sent
};

// ---- Interruption: SIGINT (Ctrl-C), SIGTERM (scancel, kill) --------------------------------

volatile sig_atomic_t g_stop_signal = 0;
extern "C" void on_stop_signal(int sig) { g_stop_signal = sig; }

// The batch's handlers of SIGINT and SIGTERM for its life (no SA_RESTART: poll returns EINTR);
// the previous dispositions are restored when it ends.
class StopSignals {
public:
    StopSignals() {
        g_stop_signal = 0;
        struct sigaction sa {};
        sa.sa_handler = on_stop_signal;
        sigemptyset(&sa.sa_mask);
        ::sigaction(SIGINT, &sa, &old_int_);
        ::sigaction(SIGTERM, &sa, &old_term_);
    }
    ~StopSignals() {
        ::sigaction(SIGINT, &old_int_, nullptr);
        ::sigaction(SIGTERM, &old_term_, nullptr);
    }
    StopSignals(const StopSignals&) = delete;
    StopSignals& operator=(const StopSignals&) = delete;

private:
    struct sigaction old_int_ {};
    struct sigaction old_term_ {};
};

// The batch was told to stop: its workers are killed (an eye in progress is neither a result
// nor a failure: the next run does it), the records written so far reach the disk, one line
// says how many eyes are finished and that a re-run resumes, and the process ends by the signal
// (a shell sees 128 + N, and a script's loop stops as on any Ctrl-C).
// An eye in progress may have written its result before the kill (the re-run keeps such a
// result): it is counted.
[[noreturn]] void stop_batch(int sig, const std::vector<Worker>& workers,
                             const std::vector<pid_t>& retired, const std::vector<Item>& items,
                             const fs::path& out, int lock_fd) {
    std::vector<pid_t> pids = retired;
    std::vector<std::size_t> busy;
    for (const Worker& w : workers) {
        if (w.pid > 0) pids.push_back(w.pid);
        if (w.pid > 0 && w.busy) busy.push_back(w.index);
    }
    for (const pid_t pid : pids) ::kill(pid, SIGKILL);
    for (const pid_t pid : pids) {
        while (::waitpid(pid, nullptr, 0) < 0 && errno == EINTR) {
        }
    }
    (void)::syncfs(lock_fd);
    auto finished = std::count_if(items.begin(), items.end(),
                                  [](const Item& it) { return it.settled(); });
    std::error_code ec;
    for (const std::size_t i : busy) {
        finished += fs::exists(eye_result_file(out, items[i].key), ec) ? 1 : 0;
    }
    std::fprintf(stderr,
                 "%soctshape: interrupted by %s: %zu of %zu eyes finished (results and recorded "
                 "failures are kept); run the same command again to resume\n",
                 ::isatty(STDERR_FILENO) != 0 ? "\n" : "",  // below the progress bar
                 sig == SIGINT ? "SIGINT" : "SIGTERM", static_cast<std::size_t>(finished),
                 items.size());
    std::fflush(stderr);
    ::signal(sig, SIG_DFL);
    ::raise(sig);
    std::_Exit(128 + sig);
}

// The parent's side of a batch: its workers, the eyes still to send, and what each message or
// end of a worker means for the eye it had. One object per run_workers call.
class Batch {
public:
    Batch(const CohortOptions& o, const SubjectSource& subjects, std::vector<Item>& items,
          const std::vector<std::size_t>& pending, const fs::path& out,
          const std::string& fail_options, int jobs, int lock_fd, Progress& progress)
        : o_(o),
          subjects_(subjects),
          items_(items),
          pending_(pending),
          out_(out),
          fail_options_(fail_options),
          lock_fd_(lock_fd),
          progress_(progress),
          workers_(std::min(pending.size(), static_cast<std::size_t>(jobs))),
          parent_(::getpid()),
          worker_level_(spdlog::get_level() <= spdlog::level::debug ? spdlog::get_level()
                                                                   : spdlog::level::err) {}

    // Until every pending eye is done or failed and every worker has ended.
    void run() {
        for (Worker& w : workers_) {
            start_worker(w);
            dispatch(w);
        }
        std::vector<pollfd> fds;
        std::vector<Worker*> polled;
        for (;;) {
            if (g_stop_signal != 0) {
                stop_batch(g_stop_signal, workers_, retired_, items_, out_, lock_fd_);
            }
            fds.clear();
            polled.clear();
            int wait_ms = 1000;  // a bound, should an end go unnoticed by poll
            const auto now = Clock::now();
            for (Worker& w : workers_) {
                if (w.pid < 0) continue;
                fds.push_back({w.sock, POLLIN, 0});
                polled.push_back(&w);
                if (w.busy && o_.eye_timeout_s > 0.0) {
                    const double left = o_.eye_timeout_s - seconds_since(w.start, now);
                    wait_ms = std::clamp(static_cast<int>(std::ceil(left * 1000.0)), 0, wait_ms);
                }
            }
            if (fds.empty()) break;
            if (::poll(fds.data(), fds.size(), wait_ms) < 0 && errno != EINTR) {
                throw std::runtime_error(std::string("poll: ") + std::strerror(errno));
            }
            for (std::size_t k = 0; k < fds.size(); ++k) {
                if (fds[k].revents != 0) read_worker(*polled[k]);
            }
            stop_overdue();
        }
        for (const pid_t pid : retired_) {
            while (::waitpid(pid, nullptr, 0) < 0 && errno == EINTR) {
            }
        }
    }

private:
    static double seconds_since(Clock::time_point start, Clock::time_point now) {
        return std::chrono::duration<double>(now - start).count();
    }

    // Forks a worker into the slot `w` (the child never returns from here).
    void start_worker(Worker& w) {
        int sv[2];
        if (::socketpair(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0, sv) != 0) {
            throw OutputError("socketpair", std::strerror(errno));
        }
        std::fflush(stderr);
        spdlog::default_logger()->flush();
        const pid_t pid = ::fork();
        if (pid < 0) throw OutputError("fork", std::strerror(errno));
        if (pid == 0) {
            // The worker dies with the parent (SIGKILL of the batch kills its eyes too).
            ::prctl(PR_SET_PDEATHSIG, SIGKILL);
            if (::getppid() != parent_) ::_exit(static_cast<int>(ExitCode::kInternal));
            ::close(sv[0]);
            // The other workers' sockets: each must see end-of-file when the parent closes it.
            for (const Worker& other : workers_) {
                if (other.sock >= 0) ::close(other.sock);
            }
            // The lock is the batch's: an eye outliving a killed batch must not block the
            // re-run (its atomic write of the same result is harmless).
            ::close(lock_fd_);
            spdlog::set_level(worker_level_);
            worker_main(o_, subjects_, items_, out_, sv[1]);
        }
        ::close(sv[1]);
        w = Worker{};
        w.pid = pid;
        w.sock = sv[0];
    }

    // Gives an idle worker the next eye, or tells it to stop (closes its socket) if none is left.
    void dispatch(Worker& w) {
        if (next_ >= pending_.size()) {
            ::close(w.sock);
            retired_.push_back(w.pid);
            w = Worker{};
            return;
        }
        const std::uint64_t index = pending_[next_++];
        if (::send(w.sock, &index, sizeof index, MSG_NOSIGNAL) !=
            static_cast<ssize_t>(sizeof index)) {
            --next_;  // the worker died while idle: the eye stays pending, poll sees the end
            return;
        }
        w.busy = true;
        w.index = index;
        w.start = Clock::now();
    }

    // A worker that ended or was killed: a new one in its slot if eyes are left.
    void replace(Worker& w) {
        w = Worker{};
        if (next_ < pending_.size()) {
            start_worker(w);
            dispatch(w);
        }
    }

    void eye_failed(std::size_t index, const std::string& reason, int code, double secs) {
        record_failure(items_[index], out_, fail_options_, reason, code);
        progress_.finished(items_[index], false, reason, secs);
    }

    void eye_done(std::size_t index, double secs) {
        std::string reason;
        if (take_result(items_[index], out_, reason)) {
            progress_.finished(items_[index], true, "", secs);
        } else {
            eye_failed(index, reason, static_cast<int>(ExitCode::kInternal), secs);
        }
    }

    // The worker's socket is readable: an EyeDone record, or the end of the worker.
    void read_worker(Worker& w) {
        std::array<char, sizeof(EyeDone) + kMaxMessage> buf{};
        const auto got = ::recv(w.sock, buf.data(), buf.size(), MSG_DONTWAIT);
        if (got < 0 && (errno == EINTR || errno == EAGAIN)) return;
        const double secs = w.busy ? seconds_since(w.start, Clock::now()) : 0.0;
        if (got >= static_cast<ssize_t>(sizeof(EyeDone))) {
            EyeDone d;
            std::memcpy(&d, buf.data(), sizeof d);
            if (w.busy && d.index == w.index) {
                w.busy = false;
                const auto length =
                    std::min<std::size_t>(d.length, static_cast<std::size_t>(got) - sizeof d);
                std::string message(buf.data() + sizeof d, length);
                if (d.code == 0) {
                    eye_done(d.index, secs);
                } else {
                    eye_failed(d.index, message.empty() ? "failed without a message" : message,
                               d.code, secs);
                }
            }
            dispatch(w);
            return;
        }
        // End of file: the worker has ended (a short record cannot come from a worker; one
        // that sent it is stopped).
        if (got != 0) ::kill(w.pid, SIGKILL);
        ::close(w.sock);
        int status = 0;
        while (::waitpid(w.pid, &status, 0) < 0 && errno == EINTR) {
        }
        if (w.busy) {
            if (WIFSIGNALED(status)) {
                eye_failed(w.index, "the analysis crashed: " + signal_name(WTERMSIG(status)),
                           static_cast<int>(ExitCode::kInternal), secs);
            } else {
                const int code = WIFEXITED(status) ? WEXITSTATUS(status) : 0;
                eye_failed(w.index,
                           fmt::format("failed without a message (the worker exited with "
                                       "status {} during the analysis)",
                                       code),
                           code != 0 ? code : static_cast<int>(ExitCode::kInternal), secs);
            }
        }
        replace(w);
    }

    // Eyes over the limit: the worker is killed (reaped before the tables) and replaced.
    void stop_overdue() {
        for (Worker& w : workers_) {
            if (w.pid < 0 || !w.busy || o_.eye_timeout_s <= 0.0) continue;
            const double secs = seconds_since(w.start, Clock::now());
            if (secs < o_.eye_timeout_s) continue;
            ::kill(w.pid, SIGKILL);
            ::close(w.sock);
            retired_.push_back(w.pid);
            eye_failed(w.index,
                       fmt::format("the analysis did not finish within --eye-timeout-s {:g} s "
                                   "and was stopped",
                                   o_.eye_timeout_s),
                       static_cast<int>(ExitCode::kAnalysisFailed), secs);
            replace(w);
        }
    }

    const CohortOptions& o_;
    const SubjectSource& subjects_;
    std::vector<Item>& items_;
    const std::vector<std::size_t>& pending_;
    const fs::path& out_;
    const std::string& fail_options_;
    int lock_fd_;
    Progress& progress_;
    std::vector<Worker> workers_;
    std::vector<pid_t> retired_;  // workers told to stop, or killed; reaped before the tables
    std::size_t next_ = 0;        // the next of `pending_` to send
    pid_t parent_;
    spdlog::level::level_enum worker_level_;
};

}  // namespace

void run_workers(const CohortOptions& o, const SubjectSource& subjects, std::vector<Item>& items,
                 const std::vector<std::size_t>& pending, const fs::path& out,
                 const std::string& fail_options, int jobs, int lock_fd) {
    const StopSignals stop_signals;
    const bool bar = ::isatty(STDERR_FILENO) != 0 && spdlog::get_level() <= spdlog::level::info;
    Progress progress(items.size(), pending.size(), bar);
    progress.draw();
    // The eyes run in `jobs` worker processes, each forked once and given eye after eye; a
    // worker that dies mid-eye (crash) or is killed (--eye-timeout-s) has its eye recorded as a
    // failure and is replaced. Supervision: docs/cohort.md.
    Batch(o, subjects, items, pending, out, fail_options, jobs, lock_fd, progress).run();
    progress.end();
}

}  // namespace octshape::app
