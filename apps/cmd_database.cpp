// eco database build: parsing only; the plan (an ensemble of every sub-biome combination on
// several terrains) and the coverage table are in pipeline/database_build, the run is eco
// ensemble's.
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "atomic_file.h"
#include "biome.h"
#include "biome_db.h"
#include "cli_common.h"
#include "database_build.h"

namespace eco::cli {

namespace {

struct BuildArgs {
    pipeline::DatabaseBuildOptions options;
    bool dryRun = false;
    CLI::Option* terrainsOpt = nullptr;
};

void buildDatabase(BuildArgs a) {
    pipeline::DatabaseBuildOptions& o = a.options;
    // Given terrains replace the generated ones unless --terrains asks for both.
    if (!o.terrainFiles.empty() && a.terrainsOpt->count() == 0) o.terrains = 0;
    if (o.workDir.empty()) {
        const std::filesystem::path out(o.out);
        o.workDir = (out.parent_path() / (out.stem().string() + "-ensemble")).string();
    }
    const std::string spec = pipeline::writeDatabaseBuildSpec(o);
    info("database build: " + spec + " (the ensemble's specification; members, logs and manifest in " + o.workDir + ")");
    if (runEnsembleFile(spec, "", a.dryRun) != 0 || a.dryRun) return;
    const BiomeDatabase db = readBiomeDatabase(o.out);
    const Biome biome = o.biome.empty() ? defaultBiome() : loadBiome(o.biome);
    const auto rows = pipeline::coverage(db, biome);
    const std::string csv = (std::filesystem::path(o.out).parent_path() / (std::filesystem::path(o.out).stem().string() + "-coverage.csv")).string();
    writeTextFile(csv, pipeline::coverageCsv(rows));
    printResult("coverage of %s (combination x cluster):\n%s%s\n", o.out.c_str(), pipeline::coverageText(rows).c_str(), csv.c_str());
    std::fflush(stdout);
}

/// "MIN,MAX" (or two values) into lo, hi.
bool parseRange(const CLI::results_t& r, double& lo, double& hi) {
    std::vector<std::string> parts;
    for (const std::string& item : r) {
        std::size_t start = 0;
        for (std::size_t comma; (comma = item.find(',', start)) != std::string::npos; start = comma + 1)
            parts.push_back(item.substr(start, comma - start));
        parts.push_back(item.substr(start));
    }
    if (parts.size() != 2) return false;
    try {
        std::size_t used = 0;
        lo = std::stod(parts[0], &used);
        if (used != parts[0].size()) return false;
        hi = std::stod(parts[1], &used);
        return used == parts[1].size();
    } catch (const std::exception&) {
        return false;
    }
}

}  // namespace

void registerDatabaseCommands(CLI::App& app) {
    CLI::App* group = app.add_subcommand("database", "Biome databases made from many simulations");
    group->require_subcommand(1);
    auto a = std::make_shared<BuildArgs>();
    pipeline::DatabaseBuildOptions& o = a->options;
    o.simConfig = "configs/sim-default.toml";
    CLI::App* sub = group->add_subcommand(
        "build",
        "A complete biome database from one command: an ensemble (eco ensemble) of one simulation per combination of the "
        "biome's canopy sub-biomes (15 for 4) on each of several terrains (generated with valley depth and base "
        "elevation spread over --valley-depth and --base-elevation, or given with --terrain), analysed into one database, and "
        "a coverage table (combination x cluster: simulated area, plants, replicates, mean sun, moisture, temperature "
        "and slope) printed and stored as DB-coverage.csv. Restartable and MPI-capable as eco ensemble (docs/ensemble.md).");
    sub->add_option("biome", o.biome, "Biome TOML (default: the embedded Sonoma biome)")->check(CLI::ExistingFile);
    sub->add_option("--out", o.out, "The database to write")->required();
    sub->add_option("--work-dir", o.workDir, "The ensemble's folder (default: DB's folder/<DB name>-ensemble)");
    sub->add_option("--sim-config", o.simConfig, "Simulation configuration (model constants)")
        ->capture_default_str()
        ->check(CLI::ExistingFile);
    a->terrainsOpt = sub->add_option("--terrains", o.terrains,
                                     "Generated terrains (replicates) per combination, 0..100 (default 2, or 0 when "
                                     "--terrain is given)")
                         ->capture_default_str();
    sub->add_option("--terrain", o.terrainFiles,
                    "A terrain of your own (.asc, .h5, .tif, ...; repeatable): every combination is also simulated on it, "
                    "on a plot of --plot metres centred in it")
        ->check(CLI::ExistingFile);
    sub->add_option("--valley-depth", [&o](const CLI::results_t& r) { return parseRange(r, o.valleyDepthMinM, o.valleyDepthMaxM); },
                    "Valley depth of the generated terrains, MIN,MAX metres: terrain t of N gets MIN + (t-1)/(N-1) (MAX - MIN); "
                    "it sets their slopes, moisture routing and sun on aspects")
        ->default_str("8,60");
    sub->add_option("--base-elevation",
                    [&o](const CLI::results_t& r) { return parseRange(r, o.baseElevationMinM, o.baseElevationMaxM); },
                    "Base elevation of the generated terrains, MIN,MAX metres (spread as --valley-depth; with the lapse rate "
                    "it spreads temperature)")
        ->default_str("0,600");
    sub->add_option("--terrain-cells", o.terrainCells, "Terrain width and height in cells of 0.914 m, 32..4096")->capture_default_str();
    sub->add_option("--plot", o.plotM, "Side of the simulated plot in metres, centred on the terrain")->capture_default_str();
    sub->add_option("--years", o.years, "Simulated years")->capture_default_str();
    sub->add_option("--kmax", o.kMax, "Largest number of clusters per combination, 1..64")->capture_default_str();
    sub->add_option("--members-at-once", o.membersAtOnce, "Members side by side in child processes (one process; "
                                                          "under MPI the ranks share the members)")
        ->capture_default_str()
        ->check(CLI::Range(1, 256));
    sub->add_option("--seed", o.seed, "Seed of the analysis")->capture_default_str();
    sub->add_flag("--dry-run", a->dryRun, "Write the specification and list the members without running them");
    sub->callback([a] { buildDatabase(*a); });
}

}  // namespace eco::cli
