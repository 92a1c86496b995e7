#pragma once
// How a subcommand plugs into `octshape`: each command file has one `add_<name>_command`
// that creates the CLI11 subcommand and sets its callback. A callback reports failure by
// throwing an octshape::Error (main maps it to an exit code) or, for a partial success such as
// a batch with failed inputs, by setting `RunContext::exit_code`.


namespace CLI {
class App;
}  // namespace CLI

namespace octshape::app {

struct RunContext {
    int exit_code = 0;
};

void add_info_command(CLI::App& app, RunContext& ctx);
void add_macula_command(CLI::App& app, RunContext& ctx);
void add_onh_command(CLI::App& app, RunContext& ctx);
void add_denoise_command(CLI::App& app, RunContext& ctx);
void add_metrics_command(CLI::App& app, RunContext& ctx);
void add_features_command(CLI::App& app, RunContext& ctx);
void add_meanshape_command(CLI::App& app, RunContext& ctx);
void add_cohort_command(CLI::App& app, RunContext& ctx);
void add_merge_command(CLI::App& app, RunContext& ctx);
void add_pseudonym_command(CLI::App& app, RunContext& ctx);
// `phantom macula` under the `phantom` parent.
void add_phantom_macula_command(CLI::App& phantom, RunContext& ctx);
// `phantom onh` under the `phantom` parent command.
void add_phantom_onh_command(CLI::App& phantom, RunContext& ctx);
// `phantom cohort` under the `phantom` parent command.
void add_phantom_cohort_command(CLI::App& phantom, RunContext& ctx);
void add_stats_command(CLI::App& app, RunContext& ctx);
void add_gallery_command(CLI::App& app, RunContext& ctx);

}  // namespace octshape::app
