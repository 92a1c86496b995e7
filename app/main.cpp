// octshape: shape parameters of the fovea and the optic nerve head from Spectralis exports.
//
// main only parses the command line, configures logging and maps errors to exit codes; all
// work is in the commands (app/commands) and the libraries.

#include <exception>
#include <iostream>
#include <new>

#include <CLI/CLI.hpp>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include "commands/command.h"
#include "commands/man_page.h"
#include "commands/usage_error.h"
#include "octshape/version.h"
#include "commands/provenance.h"
#include "octshape/error.h"

namespace {

constexpr const char* kExitCodes = R"(Exit codes:
  0   success
  1   batch finished, some inputs failed (each recorded with its reason)
  64  usage error (bad command line or option value)
  65  input corrupt, truncated, hostile or unsupported
  66  input missing, not a regular file, or unreadable
  69  analysis not possible on this input (wrong scan pattern, segmentation missing)
  70  internal error in octshape (please report it)
  73  output cannot be written
Every mistake on the command line (an unknown command or option, a missing or bad value)
exits 64, whether CLI11 or octshape finds it.)";

void configure_logging(bool quiet, int verbose) {
    auto logger = spdlog::stderr_color_mt("octshape");
    logger->set_pattern("%^%l%$: %v");
    spdlog::set_default_logger(logger);
    if (quiet) {
        spdlog::set_level(spdlog::level::err);
    } else if (verbose >= 2) {
        spdlog::set_level(spdlog::level::trace);
    } else if (verbose == 1) {
        spdlog::set_level(spdlog::level::debug);
    } else {
        spdlog::set_level(spdlog::level::info);
    }
}

}  // namespace

int main(int argc, char** argv) {
    CLI::App app{"octshape: 3-D shape parameters of the fovea and optic nerve head from "
                 "Heidelberg Spectralis OCT exports"};
    app.footer(kExitCodes);
    // Version, the source revision built (and whether the tree was modified), build type.
    app.set_version_flag("--version", octshape::app::version_text());
    app.require_subcommand(1);
    bool quiet = false;
    int verbose = 0;
    app.add_flag("-q,--quiet", quiet, "Only print errors on stderr");
    app.add_flag("-v,--verbose", verbose, "More detail on stderr (-vv for trace)");
    app.parse_complete_callback([&] { configure_logging(quiet, verbose); });
    // -q / -v anywhere on the line: after the subcommand too (`octshape macula FILE -v`); every
    // subcommand added below inherits this.
    app.fallthrough();

    octshape::app::RunContext ctx;
    octshape::app::add_denoise_command(app, ctx);
    octshape::app::add_metrics_command(app, ctx);
    octshape::app::add_features_command(app, ctx);
    octshape::app::add_meanshape_command(app, ctx);
    octshape::app::add_info_command(app, ctx);
    octshape::app::add_macula_command(app, ctx);
    octshape::app::add_cohort_command(app, ctx);
    octshape::app::add_merge_command(app, ctx);
    octshape::app::add_pseudonym_command(app, ctx);
    octshape::app::add_stats_command(app, ctx);
    octshape::app::add_gallery_command(app, ctx);
    octshape::app::add_onh_command(app, ctx);
    auto* phantom = app.add_subcommand(
        "phantom", "Write a synthetic Spectralis export whose true shape parameters are known");
    phantom->require_subcommand(1);
    octshape::app::add_phantom_macula_command(*phantom, ctx);
    octshape::app::add_phantom_onh_command(*phantom, ctx);
    octshape::app::add_phantom_cohort_command(*phantom, ctx);

    // Hidden (no group): prints the manual page octshape(1) made from the help text above; the
    // build writes share/man/man1/octshape.1 with it (cmake/ManPage.cmake).
    app.add_flag_callback(
           "--man-page",
           [&app] {
               std::cout << octshape::app::man_page(app, kExitCodes, octshape::kVersion);
               throw CLI::Success();
           },
           "Print the manual page (roff) and exit")
        ->group("");

    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        // CLI11 prints the help or the version; a mistake is one line (with a "did you mean"
        // for a near miss), and CLI11's own codes (105 for a value outside a set, 106 for a
        // conversion, ...) become the one usage code, as for the checks octshape makes itself
        // (UsageError).
        if (e.get_exit_code() == 0) return app.exit(e);
        std::cerr << "octshape: error: " << octshape::app::usage_error_line(app, e) << '\n';
        return static_cast<int>(octshape::ExitCode::kUsage);
    } catch (const octshape::Error& e) {
        std::cerr << "octshape: error: " << e.what() << '\n';
        return static_cast<int>(e.exit_code());
    } catch (const std::bad_alloc&) {
        std::cerr << "octshape: error: out of memory\n";
        return static_cast<int>(octshape::ExitCode::kInternal);
    } catch (const std::exception& e) {
        std::cerr << "octshape: internal error: " << e.what() << '\n';
        return static_cast<int>(octshape::ExitCode::kInternal);
    }
    return ctx.exit_code;
}
