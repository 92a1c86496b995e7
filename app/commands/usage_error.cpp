#include "commands/usage_error.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstddef>

namespace octshape::app {
namespace {

std::size_t edit_distance(const std::string& a, const std::string& b) {
    std::vector<std::size_t> row(b.size() + 1);
    for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
    for (std::size_t i = 1; i <= a.size(); ++i) {
        std::size_t diag = row[0];
        row[0] = i;
        for (std::size_t j = 1; j <= b.size(); ++j) {
            const std::size_t up = row[j];
            row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] != b[j - 1] ? 1 : 0)});
            diag = up;
        }
    }
    return row[b.size()];
}

// The deepest subcommand the parser entered ("octshape macula", "octshape phantom onh").
const CLI::App* deepest(const CLI::App& app) {
    for (const CLI::App* sub : app.get_subcommands()) {
        if (sub->parsed() > 0) return deepest(*sub);
    }
    return &app;
}

std::string command_path(const CLI::App* a) {
    std::string path;
    for (; a != nullptr && a->get_parent() != nullptr; a = a->get_parent()) {
        path = a->get_name() + (path.empty() ? "" : " " + path);
    }
    return path;
}

// The option names `a` accepts: its own and those it inherits (fallthrough: -q, -v, --help).
std::vector<std::string> option_names(const CLI::App* a) {
    std::vector<std::string> names;
    for (; a != nullptr; a = a->get_parent()) {
        for (const CLI::Option* o : a->get_options()) {
            for (const auto& l : o->get_lnames()) names.push_back("--" + l);
            for (const auto& s : o->get_snames()) names.push_back("-" + s);
        }
    }
    return names;
}

std::vector<std::string> subcommand_names(const CLI::App* a) {
    std::vector<std::string> names;
    for (const CLI::App* sub : a->get_subcommands({})) {
        if (!sub->get_group().empty()) names.push_back(sub->get_name());
    }
    return names;
}

std::string joined(const std::vector<std::string>& v) {
    std::string s;
    for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
    return s;
}

std::string did_you_mean(const std::string& word, const std::vector<std::string>& candidates) {
    const std::string near = nearest_name(word, candidates);
    return near.empty() ? std::string() : " (did you mean " + near + "?)";
}

// CLI11's text on one line, its "Run with --help" hint dropped.
std::string flattened(std::string what) {
    if (const auto at = what.find("Run with --help"); at != std::string::npos) what.resize(at);
    std::replace(what.begin(), what.end(), '\n', ' ');
    while (!what.empty() && what.back() == ' ') what.pop_back();
    if (!what.empty() && what[0] >= 'A' && what[0] <= 'Z' && (what.size() < 2 || what[1] > 'Z')) {
        what[0] = static_cast<char>(what[0] - 'A' + 'a');
    }
    return what;
}

}  // namespace

std::string nearest_name(const std::string& word, const std::vector<std::string>& candidates) {
    const auto bare = [](const std::string& s) {
        const auto b = s.find_first_not_of('-');
        return b == std::string::npos ? std::string() : s.substr(b);
    };
    const std::string w = bare(word.substr(0, word.find('=')));
    std::string best;
    std::size_t best_d = std::max<std::size_t>(1, w.size() / 3) + 1;
    for (const auto& c : candidates) {
        const std::string n = bare(c);
        if (n.empty() || n == w) continue;
        std::size_t d = edit_distance(w, n);
        const std::size_t common = std::min(w.size(), n.size());
        if (common >= 2 && (w.compare(0, common, n, 0, common) == 0)) {
            d = std::min<std::size_t>(d, 1);  // `--qc-dir` for `--qc`, `macul` for `macula`
        }
        if (d < best_d || (d == best_d && !best.empty() && c.size() < best.size())) {
            best_d = d;
            best = c;
        }
    }
    return best;
}

std::string usage_error_line(const CLI::App& app, const CLI::ParseError& e) {
    const CLI::App* at = deepest(app);
    const std::string where = command_path(at);
    const std::string prefix = where.empty() ? "" : where + ": ";
    const std::string help = " (octshape " + (where.empty() ? "" : where + " ") + "--help)";
    // The arguments nobody took: CLI11 hands a subcommand's unknown arguments up to its parent
    // (fallthrough), so they are gathered over the whole tree.
    const std::vector<std::string> extras = app.remaining(true);
    // An unknown option first: CLI11 may report a missing positional or subcommand before it.
    for (const auto& x : extras) {
        if (x.size() > 1 && x[0] == '-') {
            return prefix + "unknown option " + x.substr(0, x.find('=')) +
                   did_you_mean(x, option_names(at)) + help;
        }
    }
    const auto subs = subcommand_names(at);
    if (!subs.empty() && at->get_require_subcommand_min() > 0) {
        if (!extras.empty()) {
            return prefix + "unknown command '" + extras.front() + "'" +
                   did_you_mean(extras.front(), subs) + help;
        }
        return prefix + "a command is required: " + joined(subs) + help;
    }
    if (!extras.empty()) {
        return prefix + "unexpected argument '" + extras.front() + "'" + help;
    }
    return prefix + flattened(e.what()) + help;
}

}  // namespace octshape::app
