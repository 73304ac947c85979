// eco instance SCENE.h5 --prototypes K --out DIR: parsing only; the quantisation and the
// outputs are synth/instancing's.
#include <cstdio>
#include <memory>
#include <string>

#include "cli_common.h"
#include "instancing.h"
#include "reporter.h"
#include "text_format.h"

namespace eco::cli {

void registerInstanceCommand(CLI::App& app) {
    auto a = std::make_shared<synth::InstancingRun>();
    auto weight = std::make_shared<std::string>("area");
    CLI::App* sub = app.add_subcommand(
        "instance",
        "Approximate instancing (Deussen et al. 1998): replace a scene's plants by instances of a few prototypes per "
        "species (weighted k-means in log height x log crown radius), so that a renderer keeps one model per prototype. "
        "Writes OUT/prototypes.csv, OUT/instances.csv (prototype, position, rotation, scale, id, species, size), "
        "OUT/instancing.md with the mean and max relative size error, OUT/error_vs_k.png (error against K), and for 3D "
        "packages OUT/instances.ply (the plants as a binary PLY point cloud with the same columns), "
        "OUT/grass.exr, OUT/litter.exr (forest floor densities) and OUT/terrain.exr (elevation) as float OpenEXR, "
        "grass and litter also as GeoTIFF. tools/blender_import_eco.py builds the scene in Blender (docs/export.md).");
    sub->add_option("scene", a->scene, "Scene file (eco synth)")->required()->check(CLI::ExistingFile);
    sub->add_option("--out", a->outDir, "Output folder")->required();
    sub->add_option("--prototypes", a->params.prototypesPerSpecies, "K: prototypes per species")
        ->capture_default_str()
        ->check(CLI::Range(1, 100000));
    sub->add_option("--weight", *weight, "Importance weight of a plant in the clustering: area (its crown area) or none")
        ->capture_default_str()
        ->check(oneOf({"area", "none"}));
    sub->add_option("--seed", a->params.seed, "Seed of the k-means starts and the rotations")->capture_default_str();
    sub->add_option("--biome", a->biome, "Biome TOML (default: the one recorded in the scene)")->check(CLI::ExistingFile);
    sub->add_option("--curve-max", a->curveMaxK, "Error curve for K = 1 .. this (default 2 K, at most 32)")->check(CLI::Range(1, 256));
    sub->callback([a, weight] {
        a->params.weightByCrownArea = *weight == "area";
        // Progress on stderr: a scene of 600,000 plants takes a minute (k-means for each K of
        // the error curve), which was silent.
        CliReporter reporter;
        std::unique_ptr<pipeline::ProgressBar> bar;
        synth::InstancingRun run = *a;
        run.progress = [&](int done, int total) {
            if (!bar) bar = reporter.progress("instance", total);
            bar->update(done);
            if (done == total) bar->finish();
        };
        const synth::InstancingSummary s = synth::runInstancing(run);
        printResult("%zu plants as %zu prototypes: size error unscaled mean %s %%, max %s %%; scaled to height mean %s %%, max %s %%\n%s",
                    s.plants, s.prototypes, formatNumber(100 * s.error.meanUnscaled, 3).c_str(), formatNumber(100 * s.error.maxUnscaled, 3).c_str(),
                    formatNumber(100 * s.error.meanScaled, 3).c_str(), formatNumber(100 * s.error.maxScaled, 3).c_str(), s.text.c_str());
        for (const std::string& f : s.files) printResult("%s\n", f.c_str());
        std::fflush(stdout);
    });
}

}  // namespace eco::cli
