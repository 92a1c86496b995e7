#include "commands/man_page.h"

#include <CLI/CLI.hpp>
#include <sstream>
#include <vector>

namespace octshape::app {
namespace {

// "  CODE  meaning": indentation, decimal digits, spaces, the rest. (No std::regex: GCC 12
// warns inside <regex> at -O1 with the sanitizers.)
bool split_code_line(const std::string& line, std::string& code, std::string& meaning) {
    std::size_t i = line.find_first_not_of(" \t");
    if (i == 0 || i == std::string::npos) return false;
    const std::size_t digits = i;
    while (i < line.size() && line[i] >= '0' && line[i] <= '9') ++i;
    if (i == digits || i == line.size() || (line[i] != ' ' && line[i] != '\t')) return false;
    code = line.substr(digits, i - digits);
    i = line.find_first_not_of(" \t", i);
    if (i == std::string::npos) return false;
    meaning = line.substr(i);
    return true;
}


// Text as roff shows it verbatim: backslashes escaped, a leading '.' or '\'' neutralised.
std::string roff_escape(const std::string& text) {
    std::string out;
    std::istringstream in(text);
    std::string line;
    while (std::getline(in, line)) {
        std::string esc;
        for (const char c : line) {
            if (c == '\\') {
                esc += "\\e";
            } else if (c == '-') {
                esc += "\\-";
            } else {
                esc += c;
            }
        }
        if (!esc.empty() && (esc[0] == '.' || esc[0] == '\'')) esc = "\\&" + esc;
        out += esc + '\n';
    }
    return out;
}

// The help text of `cmd` as `octshape ... --help` prints it, without the footer that every
// command repeats (it is the EXIT STATUS section once).
std::string help_of(const CLI::App& cmd, const std::string& full_name, const std::string& footer) {
    std::string text = cmd.get_formatter()->make_help(&cmd, full_name, CLI::AppFormatMode::Normal);
    const auto at = text.rfind(footer);
    if (!footer.empty() && at != std::string::npos) text.erase(at);
    while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
    return text;
}

void section(std::ostringstream& out, const CLI::App& cmd, const std::string& full_name,
             const std::string& footer) {
    out << ".SS \"" << full_name << "\"\n.nf\n"
        << roff_escape(help_of(cmd, full_name, footer)) << ".fi\n";
    for (const CLI::App* sub : cmd.get_subcommands([](const CLI::App*) { return true; })) {
        section(out, *sub, full_name + " " + sub->get_name(), footer);
    }
}

// "octshape: what it does" -> "what it does" (NAME already starts with the program).
std::string name_line(std::string description) {
    const std::string prefix = "octshape: ";
    if (description.rfind(prefix, 0) == 0) description.erase(0, prefix.size());
    return description;
}

}  // namespace

std::string man_page(const CLI::App& app, const std::string& footer, const std::string& version) {
    std::ostringstream out;
    out << ".\\\" The manual page of octshape, generated from its --help text at build time.\n"
        << ".TH OCTSHAPE 1 \"\" \"octshape " << version << "\" \"User Commands\"\n"
        << ".SH NAME\noctshape \\- " << roff_escape(name_line(app.get_description()))
        << ".SH SYNOPSIS\n.B octshape\n[\\fB\\-q\\fR|\\fB\\-v\\fR] \\fICOMMAND\\fR "
           "[\\fIOPTIONS\\fR] [\\fIARGS\\fR]\n"
        << ".br\n.B octshape\n\\fICOMMAND\\fR \\fB\\-\\-help\\fR\n"
        << ".SH DESCRIPTION\n.nf\n" << roff_escape(help_of(app, "octshape", footer)) << ".fi\n"
        << ".SH COMMANDS\nEach command's help, as \\fBoctshape\\fR \\fICOMMAND\\fR "
           "\\fB\\-\\-help\\fR prints it.\n";
    for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; })) {
        section(out, *sub, "octshape " + sub->get_name(), footer);
    }
    // The footer: "  CODE  meaning" lines become the EXIT STATUS list, the rest a paragraph.
    out << ".SH \"EXIT STATUS\"\n";
    std::istringstream in(footer);
    std::string line;
    std::string rest;
    while (std::getline(in, line)) {
        std::string code;
        std::string meaning;
        if (split_code_line(line, code, meaning)) {
            out << ".TP\n.B " << code << "\n" << roff_escape(meaning);
        } else if (line.rfind("Exit codes", 0) != 0) {
            rest += line + '\n';
        }
    }
    if (!rest.empty()) out << ".PP\n" << roff_escape(rest);
    out << ".SH FILES\nThe documentation: \\fIshare/doc/octshape/\\fR under the installation "
           "prefix (outputs.md: every output and column; cohort.md: cohorts, privacy).\n"
        << ".SH \"SEE ALSO\"\n\\fBoctshape \\-\\-version\\fR prints the version and the source "
           "revision every output records.\n";
    return out.str();
}

}  // namespace octshape::app
