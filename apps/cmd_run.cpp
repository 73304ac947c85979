// eco run CONFIG: parsing only; the plan of stages, their run and the report are in
// pipeline/run (each stage called directly, its equivalent command line printed).
#include <cstdio>
#include <memory>
#include <string>

#include "cli_common.h"
#include "run.h"

namespace eco::cli {

namespace {

struct RunArgs {
    std::string config;
    std::string outDir;  // overrides [run] out_dir
    bool dryRun = false;
};

void runPipeline(const RunArgs& args) {
    const pipeline::RunPlan plan = pipeline::planRun(args.config, args.outDir);
    CliReporter reporter;
    if (args.dryRun) {
        pipeline::printPlan(plan, reporter);
        return;
    }
    pipeline::runPlan(plan, reporter);
    printResult("outputs in %s/ ; report: %s/report.md and %s/report.html (self-contained, interactive)\n",
                plan.outDir.c_str(), plan.outDir.c_str(), plan.outDir.c_str());
}

}  // namespace

void registerRunCommand(CLI::App& app) {
    auto a = std::make_shared<RunArgs>();
    CLI::App* sub = app.add_subcommand(
        "run", "Run the whole pipeline from one configuration (configs/demo.toml: the embedded default data).\n"
               "Each stage is an ordinary eco command; its command line is printed so it can be rerun alone.\n"
               "Relative paths inside CONFIG (and inside the configuration files it names) are relative to the "
               "directory of the file that contains them, so the run works from any working directory; "
               "[simulate] config = \"embedded:sim-default.toml\" (or a sim-default.toml missing from an existing folder) is the copy built "
               "into eco, so configs/demo.toml also runs copied alone into an empty directory.\n"
               "Writes OUT/report.md and OUT/report.html: the same report as one self-contained page (pictures "
               "embedded, works offline) with interactive plots of the population and g(r) and a pan-and-zoom view "
               "of the synthesized scene (docs/report.md).");
    sub->add_option("config", a->config, "Pipeline configuration (TOML)")->required();
    sub->add_option("--out-dir", a->outDir, "Override [run] out_dir (relative to the working directory)");
    sub->add_flag("--dry-run", a->dryRun, "Print the stages without running them");
    sub->callback([a] { runPipeline(*a); });
}

}  // namespace eco::cli
