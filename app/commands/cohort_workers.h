#pragma once
// The worker processes of `octshape cohort` (docs/cohort.md, "Isolation and progress"): the
// pending eyes are analysed N at a time in N forked workers, each given eye after eye; a worker
// that crashes or outlives --eye-timeout-s has its eye recorded as a failure and is replaced.
// `octshape cohort-eye` runs its one eye through the same supervision (one worker).

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "commands/cohort_eye.h"

namespace octshape::app {

// Analyses items[i] for every i in `pending` in min(jobs, |pending|) workers, and marks each
// item done (its result taken, see take_result) or failed (record_failure with
// `fail_options`). `lock_fd` (the output folder's lock) is closed in the workers. All workers
// are reaped before it returns.
void run_workers(const CohortOptions& o, const SubjectSource& subjects, std::vector<Item>& items,
                 const std::vector<std::size_t>& pending, const std::filesystem::path& out,
                 const std::string& fail_options, int jobs, int lock_fd);

}  // namespace octshape::app
