// `octshape pseudonym --subject-key-file F [PATIENT_ID...]`: the subject id a cohort gives a
// patient ID under a key (docs/cohort.md, "Subject pseudonyms"), one per line, so a clinician
// can find a patient's rows or write a groups file keyed by subject_id. Without IDs on the
// command line (where `ps` shows them) they are read from stdin, one per line.

#include <CLI/CLI.hpp>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "commands/command.h"
#include "commands/eye_record.h"
#include "octshape/error.h"

namespace octshape::app {
namespace {

struct PseudonymOptions {
    std::vector<std::string> ids;
    SubjectOptions subjects;
};

void run(const PseudonymOptions& o) {
    if (o.subjects.key.empty() && o.subjects.key_file.empty()) {
        throw UsageError("pseudonym needs --subject-key-file F (e.g. OUTDIR/private/subject.key) "
                         "or --subject-key KEY");
    }
    const SubjectSource subjects = SubjectSource::from_options(o.subjects);
    std::vector<std::string> ids = o.ids;
    if (ids.empty()) {
        for (std::string line; std::getline(std::cin, line);) {
            if (line.find_first_not_of(" \t\r") != std::string::npos) ids.push_back(line);
        }
    }
    for (const auto& id : ids) {
        const auto s = subjects.of_patient(id);
        if (!s) throw UsageError("pseudonym: an empty patient ID has no subject id");
        std::cout << *s << '\n';
    }
    std::cout.flush();
    if (!std::cout) throw OutputError("stdout", "write failed");
}

}  // namespace

void add_pseudonym_command(CLI::App& app, RunContext& /*ctx*/) {
    auto opts = std::make_shared<PseudonymOptions>();
    CLI::App* cmd = app.add_subcommand(
        "pseudonym",
        "Print the subject id (HMAC-SHA256 pseudonym) of each patient ID under a key, one per "
        "line, as `octshape cohort` writes it");
    cmd->add_option("ids", opts->ids,
                    "Patient IDs (default: read from stdin, one per line, so that `ps` does not "
                    "show them)");
    cmd->add_option("--subject-key", opts->subjects.key,
                    "The key (visible to other users in `ps`: prefer --subject-key-file)");
    cmd->add_option("--subject-key-file", opts->subjects.key_file,
                    "The key is the first line of this file (a cohort without a subject option "
                    "makes OUTDIR/private/subject.key)");
    cmd->callback([opts] { run(*opts); });
}

}  // namespace octshape::app
