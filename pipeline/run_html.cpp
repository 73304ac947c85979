#include "run_html.h"

#include <algorithm>
#include <cstdio>
#include <optional>

#include "biome_db.h"
#include "error.h"
#include "h5io.h"
#include "scene.h"
#include "sim_file.h"
#include "undergrowth.h"

namespace eco::pipeline {

namespace {

template <class T>
const T* stageOptions(const RunPlan& plan) {
    for (const PlannedStage& s : plan.stages)
        if (const auto* o = std::get_if<T>(&s.options)) return o;
    return nullptr;
}

/// Plants per species and year of a simulation file's /timeseries (species that ever had a
/// plant), with the total.
html::LinePlot populationPlot(const std::string& simulationPath) {
    const SimulationFileData sim = readSimulationFile(simulationPath);
    const h5::File f = h5::File::openRead(simulationPath);
    const std::vector<YearRecord> ts = readTimeseries(f, "/timeseries", sim.biome.species.size());
    html::LinePlot plot;
    plot.title = "Undergrowth plants per species over the simulated years (" + simulationPath + ")";
    plot.xLabel = "year";
    plot.yLabel = "plants";
    plot.logYToggle = true;
    html::SeriesGroup group{"plants per species", {}};
    html::Series total{"all undergrowth", {}, {}, "#000000", false};
    for (const YearRecord& r : ts) {
        double sum = 0;
        for (std::int32_t c : r.count) sum += c;
        total.x.push_back(r.year);
        total.y.push_back(sum);
    }
    group.series.push_back(total);
    for (std::size_t s = 0; s < sim.biome.species.size(); ++s) {
        html::Series se{sim.biome.species[s].name, {}, {}, html::categoryHex(static_cast<int>(s)), false};
        bool any = false;
        for (const YearRecord& r : ts) {
            const double c = s < r.count.size() ? r.count[s] : 0;
            any = any || c > 0;
            se.x.push_back(r.year);
            se.y.push_back(c);
        }
        if (any) group.series.push_back(se);
    }
    plot.groups.push_back(group);
    return plot;
}

/// Pooled undergrowth g(r) of every region: the database's and, with a scene, the scene's.
html::LinePlot pairCorrelationPlot(const BiomeDatabase& db, const synth::SceneComparison* comparison) {
    html::LinePlot plot;
    plot.title = comparison ? "Pair correlation g(r) of all undergrowth per region: database (simulation) against the "
                              "synthesized scene"
                            : "Pair correlation g(r) of all undergrowth per region of the database";
    plot.xLabel = "r (m)";
    plot.yLabel = "g(r)";
    plot.hasReferenceY = true;
    plot.referenceY = 1;
    plot.referenceLabel = "g = 1: no interaction";
    std::vector<double> mids;
    for (int k = 0; k < db.pcfBins.count; ++k) mids.push_back(db.pcfBins.midM(k));
    std::vector<std::pair<double, int>> order;  // (-area, region): largest first
    if (comparison) {
        for (const auto& r : comparison->regions)
            if (r.cells > 0) order.emplace_back(-r.areaM2, r.region);
    } else {
        for (std::size_t i = 0; i < db.regions.size(); ++i) order.emplace_back(-db.regions[i].areaM2, static_cast<int>(i));
    }
    std::stable_sort(order.begin(), order.end());
    for (const auto& [negArea, region] : order) {
        const DbRegion& r = db.regions.at(static_cast<std::size_t>(region));
        char name[256];
        std::snprintf(name, sizeof name, "region %d: %s / cluster %d (%.0f m2)", region, db.combinationName(r.combination).c_str(),
                      r.cluster, -negArea);
        html::SeriesGroup group{name, {}};
        group.series.push_back({"database (simulation)", mids, synth::pooledUndergrowthG(r, db), "#000000", false});
        if (comparison)
            group.series.push_back(
                {"synthesized scene", mids, synth::pooledUndergrowthG(comparison->pairs, region, db.speciesCount()), "#d62728", false});
        plot.groups.push_back(group);
    }
    return plot;
}

void note(html::Document& doc, const std::string& what, const Error& e) {
    doc.raw("<p class=\"eco-help\">" + html::escape(what + " not available: " + e.what()) + "</p>\n");
}

}  // namespace

void addRunViews(html::Document& doc, const RunPlan& plan) {
    const auto* simulate = stageOptions<SimulateOptions>(plan);
    const auto* analyse = stageOptions<AnalyseOptions>(plan);
    const auto* synthesis = stageOptions<SynthOptions>(plan);
    const auto* compare = stageOptions<CompareOptions>(plan);
    if (!simulate && !analyse && !synthesis) return;
    doc.heading(2, "Interactive views");
    if (simulate) {
        try {
            doc.linePlot(populationPlot(simulate->out));
        } catch (const Error& e) {
            note(doc, "The population plot", e);
        }
    }
    std::optional<BiomeDatabase> db;
    if (analyse) {
        try {
            db = readBiomeDatabase(analyse->out);
        } catch (const Error& e) {
            note(doc, "The biome database", e);
        }
    }
    if (synthesis && db) {
        try {
            const Biome biome = synth::databaseBiome(*db);
            const synth::SceneData scene = synth::readSceneFile(synthesis->out, biome);
            const synth::SceneComparison c = synth::compareScene(scene.canopy, scene.undergrowth, scene.clusterMap, *db, nullptr,
                                                                compare ? compare->pcfSources : 20000);
            doc.linePlot(pairCorrelationPlot(*db, &c));
            html::SceneView view;
            view.title = "The synthesized scene from above (" + synthesis->out + "): canopy crowns outlined above the undergrowth";
            const Grid<float>& t = scene.terrainM;
            view.x0M = t.originX();
            view.y0M = t.originY();
            view.x1M = t.originX() + t.width() * t.cellSizeM();
            view.y1M = t.originY() + t.height() * t.cellSizeM();
            for (const Species& s : biome.species) view.speciesNames.push_back(s.name);
            view.canopy = scene.canopy;
            view.undergrowth = scene.undergrowth;
            doc.sceneView(view);
        } catch (const Error& e) {
            note(doc, "The scene view", e);
        }
    } else {
        if (db) doc.linePlot(pairCorrelationPlot(*db, nullptr));
        if (simulate) {
            try {
                const SimulationFileData sim = readSimulationFile(simulate->out);
                std::vector<std::string> names;
                for (const Species& s : sim.biome.species) names.push_back(s.name);
                // Without a recorded area, the plants' bounding box (plotView's fallback).
                const std::array<double, 4> area = sim.area ? *sim.area : std::array<double, 4>{0, 0, 0, 0};
                const html::SceneView view =
                    html::plotView("The simulated plot from above at year " + std::to_string(sim.year) + " (" + simulate->out + ")",
                                   area[0], area[1], area[2], area[3], names, sim.canopy, sim.undergrowth);
                doc.sceneView(view);
            } catch (const Error& e) {
                note(doc, "The plot view", e);
            }
        }
    }
}

}  // namespace eco::pipeline
