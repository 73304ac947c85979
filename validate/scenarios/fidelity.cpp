// Kind "fidelity" (issue 24; docs/fidelity.md): the fidelity protocol of `eco fidelity` as a
// scenario. A generated terrain, CHM, abiotics and canopy; two simulations A and B of a plot
// with different seeds; the biome database from A; a synthesis with the structured sampler on
// the same terrain, canopy and abiotics; the scene against the held-out B, each figure beside
// the replicate level d(A, B) and the CSR level (validate/fidelity.h). Every stage runs in
// memory through the libraries (core, sim, analysis, synth), not through eco command lines.
// The old dart sampler is synthesized and measured alike as a control: its figures stand
// beside the checked ones in the report, so that a reader sees which checks it would fail.
// docs/validation.md defines the checks.
#include "scenario_context.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <set>
#include <type_traits>

#include "abiotics.h"
#include "analysis.h"
#include "atomic_file.h"
#include "biome_db.h"
#include "canopy_placer.h"
#include "error.h"
#include "fidelity.h"
#include "generate.h"
#include "html_report.h"
#include "plots.h"
#include "species_map.h"
#include "scenario_keys.h"
#include "strict_toml.h"
#include "undergrowth.h"

namespace eco::validate {

namespace {

/// Smallest plot side: the measures' pair correlation reaches 10 m, which must not exceed
/// half the plot's shorter side (FidelityParams::validate).
constexpr double kMinPlotSideM = 20.0;

struct FidelitySettings {
    // The scene, as `eco fidelity` makes it (terrain generate, chm generate, abiotics, canopy).
    std::uint64_t terrainSeed = 1;  ///< terrain, CHM trees and canopy placement
    double cellSizeM = 0.914;
    double sunStepMinutes = 10;
    std::vector<std::string> canopyTargetSpecies;  ///< share of the forested area per species
    std::vector<double> canopyTargetFractions;
    // The protocol.
    std::uint64_t seedA = 1, seedB = 2;  ///< simulations A (the database's source) and B (held out)
    std::uint64_t analysisSeed = 1;
    int kMax = 6;
    std::uint64_t synthSeed = 1;
    std::uint64_t csrSeed = 1;
    double edgeBandM = 2.0;
    /// Checks whose bound grows with the replicate level d(A, B): bound = max(factor x d(A, B),
    /// the [checks.ID] bound).
    double underCrownReplicateFactor = 1.0;
    double densityReplicateFactor = 2.0;
    struct Size {
        int terrainCells = 512;  ///< square terrain of this many cells a side
        RectWindow plot{100.0, 60.0, 220.0, 180.0};  ///< simulated and compared (world metres)
        int years = 150;
    };
    Size quick, full;
    sim::SimParams params;  ///< [model]
    /// [protocol] canopy_config: a canopy placer configuration (as eco canopy --config and
    /// eco run's [canopy] config read it) for the scene's canopy placement; "" = the placer's
    /// defaults. The placement's seed stays terrain_seed.
    std::string canopyConfig;      ///< as the scenario file writes it
    std::string canopyConfigPath;  ///< relative to the scenario file's directory
    synth::CanopyParams canopyParams;
    synth::SpeciesMapParams speciesParams;
};

using FsK = ParamDesc<FidelitySettings>::Kind;
using FsP = FidelitySettings;

/// [protocol]'s numeric keys (the canopy targets are read by hand; seed_b != seed_a is
/// checked after them).
const std::vector<ParamDesc<FsP>>& protocolFields() {
    auto seed = [](const char* key, const char* doc, std::uint64_t FsP::*member) {
        return ParamDesc<FsP>{key, doc, "", FsK::Seed, nullptr, nullptr, ParamRange::any(), member};
    };
    static const std::vector<ParamDesc<FsP>> fields = {
        seed("terrain_seed", "seed of the terrain, the CHM trees and the canopy placement", &FsP::terrainSeed),
        {"cell_size_m", "cell size of the generated terrain", "m", FsK::Real, &FsP::cellSizeM, nullptr,
         ParamRange::closed(0.05, 100.0)},
        {"sun_step_minutes", "sampling interval of the sun path (eco abiotics --sun-step)", "minutes", FsK::Real,
         &FsP::sunStepMinutes, nullptr, ParamRange::closed(1.0, 120.0)},
        seed("seed_a", "seed of simulation A, the database's source", &FsP::seedA),
        seed("seed_b", "seed of simulation B, held out (not seed_a)", &FsP::seedB),
        seed("analysis_seed", "seed of the analysis (eco analyse --seed)", &FsP::analysisSeed),
        {"kmax", "regions at most (eco analyse --kmax)", "", FsK::Integer, nullptr, &FsP::kMax, ParamRange::closed(1, 64)},
        seed("synth_seed", "seed of the synthesis (eco synth)", &FsP::synthSeed),
        seed("csr_seed", "seed of the CSR reference pattern (eco fidelity --csr-seed)", &FsP::csrSeed),
        {"edge_band_m", "light classes: the gap-edge band either side of the crown-cover edge (eco fidelity --edge-band)",
         "m", FsK::Real, &FsP::edgeBandM, nullptr, ParamRange::closed(0.2, 50.0)},
        {"under_crown_replicate_factor", "the under-crown check's bound is at least this x d(A, B)", "", FsK::Real,
         &FsP::underCrownReplicateFactor, nullptr, ParamRange::closed(0.0, 100.0)},
        {"density_replicate_factor", "the density check's bound is at least this x d(A, B)", "", FsK::Real,
         &FsP::densityReplicateFactor, nullptr, ParamRange::closed(0.0, 100.0)},
    };
    return fields;
}

/// Reads the placer configuration `path` into `st` ([canopy] table when there is one, else
/// the top level, as loadCanopyConfig). Strict: unknown keys and bad values are errors naming
/// the file, key and value; `seed` is refused (the scenario's terrain_seed, and each
/// replicate's, seeds the placement).
void readPlacerConfig(const std::string& path, FidelitySettings& st) {
    const toml::table root = parseTomlFile(path);
    const toml::table* t = &root;
    std::string context;
    if (const toml::node* n = root.get("canopy")) {
        t = n->as_table();
        if (!t) throw ValidationError(path + ": 'canopy' must be a table");
        context = "[canopy]";
    }
    StrictTable table(*t, path, context);
    if (table.has("seed"))
        table.fail("seed", "the canopy placement's seed is the scenario's [protocol] terrain_seed; remove it here");
    readCanopyConfig(table, st.canopyParams, st.speciesParams);
    table.finish();
}

/// The placer settings that differ from the defaults, "key = value, ..." ("" = none).
std::string placerSettingsText(const synth::CanopyParams& canopy, const synth::SpeciesMapParams& speciesMap) {
    std::string out;
    std::set<std::string> listed;  // canopy_threshold_m is a key of both tables
    const auto add = [&](const auto& p, const auto& fields) {
        using S = std::decay_t<decltype(p)>;
        static const S defaults{};  // static: every byte initialised (as paramDocRow)
        for (const auto& f : fields) {
            const std::string v = paramText(f, p, 17);
            if (v == paramText(f, defaults, 17) || !listed.insert(f.key).second) continue;
            out += (out.empty() ? "" : ", ") + std::string(f.key) + " = " + v;
        }
    };
    add(canopy, synth::canopyParamFields());
    add(speciesMap, synth::speciesMapParamFields());
    return out;
}

/// [quick] and [full]'s numeric keys (the plot window is read by hand).
const std::vector<ParamDesc<FsP::Size>>& fidelitySizeFields() {
    using P = FsP::Size;
    using K = ParamDesc<P>::Kind;
    static const std::vector<ParamDesc<P>> fields = {
        {"terrain_cells", "square terrain of this many cells a side (cell_size_m each)", "", K::Integer, nullptr,
         &P::terrainCells, ParamRange::closed(16, 8192)},
        {"years", "years simulated", "years", K::Integer, nullptr, &P::years, ParamRange::closed(1, 100000)},
    };
    return fields;
}

/// The figures the checks read, of one synthesized scene (structured or darts).
struct CheckedFigures {
    FidelityFigure pooledG, underCrown, radiusMedian, density;
    double tallerThanCrown = kNaN;  ///< plants of the scene taller than the crown above them
};

const FidelityFigure& overallFigure(const FidelityReport& r, const std::string& name) {
    for (const FidelityFigure& f : r.figures)
        if (f.scope == "overall" && f.figure == name) return f;
    throw Error("validate: fidelity report has no overall figure '" + name + "'");
}

const ValueRow& overallValue(const FidelityReport& r, const std::string& name) {
    for (const ValueRow& v : r.values)
        if (v.scope == "overall" && v.quantity == name) return v;
    throw Error("validate: fidelity report has no overall value '" + name + "'");
}

CheckedFigures checkedFigures(const FidelityReport& r) {
    CheckedFigures c;
    c.pooledG = overallFigure(r, "g pooled undergrowth (RMS, regions)");
    c.underCrown = overallFigure(r, "under-crown share (|difference|, weighted by species)");
    c.radiusMedian = overallFigure(r, "radius / allometric radius, median (|difference|, weighted)");
    c.density = overallFigure(r, "density (relative |difference|)");
    c.tallerThanCrown = overallValue(r, "taller than the crown above (plants)").scene;
    return c;
}

/// The inputs of the plot: terrain, CHM, abiotics (no canopy shade) and canopy trees.
struct SceneInputs {
    Grid<float> terrainM, chmM;
    Abiotics abiotics;
    std::vector<Plant> canopy;
    std::vector<synth::TargetResult> targets;
};

SceneInputs makeSceneInputs(const FidelitySettings& st, const FidelitySettings::Size& size, const Biome& biome) {
    SceneInputs in;
    TerrainGenParams tp;
    tp.width = tp.height = size.terrainCells;
    tp.cellSizeM = st.cellSizeM;
    tp.seed = st.terrainSeed;
    in.terrainM = generateTerrain(tp);
    // As `eco chm generate --seed S`: the density sketch keeps its default seed.
    const Grid<std::int32_t> sketch = generateDensitySketch(in.terrainM, SketchParams{});
    ChmGenParams cp;
    cp.seed = st.terrainSeed;
    in.chmM = generateChm(sketch, cp);
    AbioticParams ap;
    ap.sun.stepMinutes = st.sunStepMinutes;
    in.abiotics = computeAbiotics(in.terrainM, biome, ap);
    // As `eco canopy [--config canopy_config] --seed S --target ...`.
    synth::CanopyParams canopyParams = st.canopyParams;
    canopyParams.seed = st.terrainSeed;
    synth::SpeciesMapParams speciesParams = st.speciesParams;
    speciesParams.canopyThresholdM = canopyParams.canopyThresholdM;
    synth::validateCanopyParams(canopyParams);
    std::vector<synth::SpeciesTarget> targets;
    for (std::size_t i = 0; i < st.canopyTargetSpecies.size(); ++i)
        targets.push_back(synth::SpeciesTarget{st.canopyTargetSpecies[i], st.canopyTargetFractions[i]});
    const synth::SpeciesMapInputs mapInputs = synth::speciesMapInputs(in.abiotics, in.chmM);
    if (!targets.empty()) in.targets = synth::meetTargets(biome, mapInputs, speciesParams, targets);
    const Grid<std::int32_t> speciesMap = synth::computeSpeciesMap(biome, mapInputs, speciesParams);
    in.canopy = synth::placeCanopy(in.chmM, in.terrainM, speciesMap, biome, canopyParams).trees;
    return in;
}

/// A simulation of the plot, as `eco simulate --crop PLOT --seed SEED --years N`.
struct PlotSimulation {
    std::vector<Plant> undergrowth;  ///< the last year's plants
    std::vector<Plant> canopy;       ///< the trees that reach the plot (as a simulation file keeps them)
    RectWindow area;
    double seconds = 0;
    std::int64_t plantMonths = 0;
};

PlotSimulation simulatePlot(const FidelitySettings& st, const FidelitySettings::Size& size, const SceneInputs& scene,
                            const Biome& biome, std::uint64_t seed, const std::string& label, const ScenarioContext& ctx) {
    const auto t0 = Clock::now();
    sim::SimInputs in;
    in.biome = biome;
    in.abiotics = scene.abiotics;
    in.abiotics.elevationM = scene.terrainM;
    in.chmM = scene.chmM;
    in.canopy = scene.canopy;
    in.area = sim::SimArea{size.plot.x0, size.plot.y0, size.plot.x1, size.plot.y1};
    sim::Simulation s(std::move(in), st.params, seed);
    auto lastPrint = Clock::now();
    for (int y = 1; y <= size.years; ++y) {
        s.stepYear();
        if (secondsSince(lastPrint) >= 5.0 || y == size.years) {
            lastPrint = Clock::now();
            ctx.log("validate:   fidelity: simulation " + label + " (seed " + std::to_string(seed) + "): year " +
                    std::to_string(y) + "/" + std::to_string(size.years) + ", " + std::to_string(s.plantCount()) +
                    " plants, " + fixed(secondsSince(t0), 1) + " s");
        }
    }
    PlotSimulation out;
    for (const sim::UndergrowthPlant& p : s.plants())
        out.undergrowth.push_back(Plant{p.speciesId, p.xM, p.yM, p.groundZM, p.heightM, p.crownRadiusM});
    out.canopy = s.relevantCanopy();
    const sim::SimArea a = s.area();
    out.area = RectWindow{a.x0, a.y0, a.x1, a.y1};
    out.plantMonths = s.counters().plantMonths;
    out.seconds = secondsSince(t0);
    return out;
}

/// The biome database from simulation A, as `eco analyse A --seed S --kmax K`.
BiomeDatabase analyseSimulation(const FidelitySettings& st, const PlotSimulation& a, int years, const SceneInputs& scene,
                                const Biome& biome) {
    analysis::AnalysisInput in;
    in.biome = &biome;
    in.canopy = a.canopy;
    in.undergrowth = a.undergrowth;
    // Region features: the sun under the simulation's canopy, as readSimulation makes them.
    const Grid<float> shadedSun = applyCanopyShade(scene.abiotics.sunHours, shadingTrees(in.canopy, biome)).annualMean();
    in.features = annualFactors(scene.abiotics, &shadedSun);
    in.window = a.area;
    in.provenance.path = "(in memory) fidelity simulation A";
    in.provenance.abioticsPath = "(in memory) generated";
    in.provenance.seed = st.seedA;
    in.provenance.year = years;
    in.provenance.parameters = st.params.toToml();
    analysis::AnalysisParams params;
    params.kMax = st.kMax;
    params.seed = st.analysisSeed;
    params.seedingRadiusFactor = st.params.seedOuterRadiusFactor;  // the simulation's seeding disc
    return analysis::analyse({in}, params);
}

/// Undergrowth synthesized by `method` on the scene's terrain, canopy and abiotics.
synth::UndergrowthSample synthesize(const BiomeDatabase& db, const Biome& dbBiome, const SceneInputs& scene,
                                    const synth::ClusterMap& clusters, synth::SynthMethod method, std::uint64_t seed) {
    synth::SynthParams p;
    p.method = method;
    p.seed = seed;
    p.validate();
    return synth::sampleUndergrowth(db, dbBiome, scene.canopy, clusters, scene.terrainM, p);
}

/// Text for a Markdown table cell: '|' escaped.
std::string cellText(const std::string& s) {
    std::string out;
    for (char c : s) {
        if (c == '|') out += '\\';
        out += c;
    }
    return out;
}

std::string plotText(const RectWindow& w) {
    return num(w.x0, 6) + "," + num(w.y0, 6) + "," + num(w.x1, 6) + "," + num(w.y1, 6);
}

class Fidelity final : public Scenario {
public:
    explicit Fidelity(const ScenarioParse& in);
    std::vector<std::string> checkIds() const override {
        return {"pooled_g_score", "under_crown_share", "radius_ratio_median", "taller_than_crown", "density"};
    }
    std::vector<std::pair<std::string, std::string>> speciesNamed() const override {
        std::vector<std::pair<std::string, std::string>> out;
        for (const std::string& s : settings_.canopyTargetSpecies) out.emplace_back("[protocol] canopy_target_species", s);
        return out;
    }
    void run(const ScenarioConfig& sc, ScenarioContext& ctx, ScenarioResult& r) const override;

private:
    FidelitySettings settings_;
};

Fidelity::Fidelity(const ScenarioParse& in) {
    FidelitySettings& st = settings_;
    StrictTable s(in.top.table("protocol"), in.path, "[protocol]");
    readScenarioParams(s, st, protocolFields());
    st.canopyTargetSpecies = s.strings("canopy_target_species");
    st.canopyTargetFractions = s.numbers("canopy_target_fractions", st.canopyTargetSpecies.size());
    double total = 0;
    for (double f : st.canopyTargetFractions) {
        if (!(f >= 0 && f <= 1)) s.fail("canopy_target_fractions", "fraction " + num(f) + " outside [0, 1]");
        total += f;
    }
    if (total > 1 + 1e-9) s.fail("canopy_target_fractions", "fractions sum to " + num(total) + ", more than 1");
    if (st.seedA == st.seedB) s.fail("seed_b", "equals seed_a (" + std::to_string(st.seedA) + "): the replicate must be another seed");
    if (s.has("canopy_config")) {
        st.canopyConfig = s.string("canopy_config");
        st.canopyConfigPath = pathRelativeToConfig(in.path, st.canopyConfig);
        if (!std::filesystem::is_regular_file(st.canopyConfigPath))
            s.fail("canopy_config", "'" + st.canopyConfigPath + "': no such file (a path relative to this file's directory)");
        try {
            readPlacerConfig(st.canopyConfigPath, st);
        } catch (const IoError& e) {
            throw IoError(in.path + ": [protocol] canopy_config: " + e.what());
        } catch (const ValidationError& e) {
            throw ValidationError(in.path + ": [protocol] canopy_config: " + e.what());
        }
    }
    s.finish();
    in.sizes([&](Mode m, StrictTable& z) {
        auto& size = m == Mode::Quick ? st.quick : st.full;
        readScenarioParams(z, size, fidelitySizeFields());
        const auto p = z.numbers("plot", 4);
        size.plot = RectWindow{p[0], p[1], p[2], p[3]};
        const double extentM = size.terrainCells * st.cellSizeM;
        if (!(p[2] > p[0] && p[3] > p[1])) z.fail("plot", "expected x0, y0, x1, y1 with x1 > x0 and y1 > y0 (metres)");
        if (std::min(p[2] - p[0], p[3] - p[1]) < kMinPlotSideM)
            z.fail("plot", "sides of " + num(p[2] - p[0]) + " m x " + num(p[3] - p[1]) + " m: the measures reach 10 m, so each side must be at least " +
                               num(kMinPlotSideM) + " m");
        if (p[0] < 0 || p[1] < 0 || p[2] > extentM || p[3] > extentM)
            z.fail("plot", "[" + plotText(size.plot) + "] is not inside the terrain, 0 .. " + num(extentM, 6) + " m (terrain_cells x cell_size_m)");
    });
    st.params = in.model();
}

void Fidelity::run(const ScenarioConfig& sc, ScenarioContext& ctx, ScenarioResult& r) const {
    // Every seed of the configuration as this replicate uses it (ScenarioContext::seed).
    FidelitySettings withSeeds = settings_;
    for (std::uint64_t* s : {&withSeeds.terrainSeed, &withSeeds.seedA, &withSeeds.seedB, &withSeeds.analysisSeed, &withSeeds.synthSeed,
                             &withSeeds.csrSeed})
        *s = ctx.seed(*s);
    const FidelitySettings& st = withSeeds;
    const FidelitySettings::Size& size = ctx.mode() == Mode::Quick ? st.quick : st.full;
    const Biome& biome = ctx.biome();
    const auto t0 = Clock::now();
    ctx.log("validate: fidelity: scene of " + std::to_string(size.terrainCells) + " x " + std::to_string(size.terrainCells) +
            " cells, plot " + plotText(size.plot) + ", " + std::to_string(size.years) + " years");

    auto t = Clock::now();
    const SceneInputs scene = makeSceneInputs(st, size, biome);
    const double inputsS = secondsSince(t);
    ctx.log("validate:   fidelity: terrain, CHM, abiotics and " + std::to_string(scene.canopy.size()) + " canopy trees in " +
            fixed(inputsS, 1) + " s");
    const PlotSimulation A = simulatePlot(st, size, scene, biome, st.seedA, "A", ctx);
    const PlotSimulation B = simulatePlot(st, size, scene, biome, st.seedB, "B", ctx);

    t = Clock::now();
    const BiomeDatabase db = analyseSimulation(st, A, size.years, scene, biome);
    const double analyseS = secondsSince(t);
    if (db.regions.empty()) throw ValidationError(sc.path + ": the database from simulation A holds no region");
    const Biome dbBiome = synth::databaseBiome(db);

    // The cluster map of the scene (the sun under its canopy, as the analyser's regions were
    // made); it does not depend on the sampler.
    t = Clock::now();
    Abiotics shaded = scene.abiotics;
    shaded.sunHours = applyCanopyShade(scene.abiotics.sunHours, shadingTrees(scene.canopy, dbBiome));
    synth::SynthParams clusterParams;
    clusterParams.seed = st.synthSeed;
    const synth::ClusterMap clusters = synth::computeClusterMap(db, dbBiome, scene.canopy, annualFactors(shaded), clusterParams);
    const synth::UndergrowthSample structured = synthesize(db, dbBiome, scene, clusters, synth::SynthMethod::Structured, st.synthSeed);
    const synth::UndergrowthSample darts = synthesize(db, dbBiome, scene, clusters, synth::SynthMethod::Darts, st.synthSeed);
    const double synthS = secondsSince(t);

    // The protocol's measures (docs/fidelity.md), for both samplers against the same A, B and CSR.
    t = Clock::now();
    FidelityContext fc;
    fc.biome = &dbBiome;
    fc.canopy = scene.canopy;
    fc.regionMap = clusters.region;
    fc.nRegions = static_cast<int>(db.regions.size());
    for (int k = 0; k < fc.nRegions; ++k) {
        const DbRegion& reg = db.regions[static_cast<std::size_t>(k)];
        fc.regionNames.push_back("region " + std::to_string(k) + " (" + db.combinationName(reg.combination) + " / " +
                                 std::to_string(reg.cluster) + ")");
    }
    fc.chmM = scene.chmM;
    FidelityParams fp;
    fp.window = size.plot;
    fp.edgeBandM = st.edgeBandM;
    fp.csrSeed = st.csrSeed;
    const FidelityReport rs = evaluateFidelity(structured.plants, A.undergrowth, B.undergrowth, fc, fp);
    const FidelityReport rd = evaluateFidelity(darts.plants, A.undergrowth, B.undergrowth, fc, fp);
    const double measureS = secondsSince(t);
    const CheckedFigures cs = checkedFigures(rs), cd = checkedFigures(rd);

    // Checks.
    const Mode mode = ctx.mode();
    r.checks.push_back(makeCheck(sc, mode, "pooled_g_score",
                                 "score of the pooled undergrowth g(r) of the scene against held-out simulation B "
                                 "(0 = as good as replicate A, 1 = no structure)",
                                 cs.pooledG.scored ? cs.pooledG.score : kNaN,
                                 cs.pooledG.scored ? "d(scene, B) " + fixed(cs.pooledG.scene, 3) + ", replicate " +
                                                         fixed(cs.pooledG.replicate, 3) + ", CSR " + fixed(cs.pooledG.csr, 3)
                                                   : "not scored: the CSR level is not distinguishable from the replicate on this plot"));
    // A bound that grows with the replicate level: max(factor x d(A, B), the configured bound).
    const auto relative = [&](const std::string& id, const std::string& title, const FidelityFigure& f, double factor) {
        CheckResult c = makeCheck(sc, mode, id, title, f.scene);
        const double floor = c.spec.target;
        const double allowance = std::max(factor * f.replicate, floor);
        c.spec.target = allowance;
        c.pass = c.spec.passes(f.scene);
        c.note = "replicate d(A, B) " + fixed(f.replicate, 3) + "; bound max(" + num(factor) + " x replicate, " + num(floor) +
                 ") = " + fixed(allowance, 3);
        r.checks.push_back(c);
    };
    relative("under_crown_share",
             "under-crown share per species against B: sum over species of B's plant share x |share_scene - share_B|",
             cs.underCrown, st.underCrownReplicateFactor);
    r.checks.push_back(makeCheck(sc, mode, "radius_ratio_median",
                                 "crown radius / allometric radius: median per species against B's, |difference| "
                                 "weighted by B's plants",
                                 cs.radiusMedian.scene, "replicate d(A, B) " + fixed(cs.radiusMedian.replicate, 3)));
    r.checks.push_back(makeCheck(sc, mode, "taller_than_crown",
                                 "undergrowth plants of the scene in the plot taller than the tallest canopy crown "
                                 "covering them",
                                 cs.tallerThanCrown,
                                 "A " + num(overallValue(rs, "taller than the crown above (plants)").reference) + ", B " +
                                     num(overallValue(rs, "taller than the crown above (plants)").replicate)));
    relative("density", "undergrowth density in the plot's region cells against B, relative |difference|", cs.density,
             st.densityReplicateFactor);

    // Details.
    std::int64_t seeded = 0;
    for (std::size_t i = 0; i < clusters.region.size(); ++i) seeded += clusters.region.data()[i] >= 0;
    std::string targets;
    for (const synth::TargetResult& tr : scene.targets)
        targets += (targets.empty() ? "" : ", ") + tr.species + " " + fixed(tr.achieved, 3) + " of the forest (asked " +
                   fixed(tr.requested, 3) + ")";
    r.details.push_back("- Scene (as `eco fidelity`, docs/fidelity.md, but every stage through the libraries in memory): "
                        "generated terrain of " + std::to_string(size.terrainCells) + " x " + std::to_string(size.terrainCells) +
                        " cells of " + num(st.cellSizeM) + " m (seed " + std::to_string(st.terrainSeed) + "), CHM and canopy "
                        "(seed " + std::to_string(st.terrainSeed) + (targets.empty() ? "" : "; " + targets) + "): " +
                        std::to_string(scene.canopy.size()) + " canopy trees; abiotics with a " + num(st.sunStepMinutes) +
                        "-minute sun step. Built in " + fixed(inputsS, 1) + " s." +
                        (st.canopyConfig.empty()
                             ? std::string()
                             : " Canopy placer configuration `" + st.canopyConfig + "` ([protocol] canopy_config): " +
                                   [&] {
                                       const std::string t = placerSettingsText(st.canopyParams, st.speciesParams);
                                       return t.empty() ? std::string("the defaults") : t;
                                   }() + "."));
    r.details.push_back("- Plot " + plotText(size.plot) + " (" + num(size.plot.widthM()) + " m x " + num(size.plot.heightM()) +
                        " m), simulated for " + std::to_string(size.years) + " years with seed " + std::to_string(st.seedA) +
                        " (A: " + std::to_string(A.undergrowth.size()) + " plants at the end, " + fixed(A.seconds, 1) +
                        " s, " + num(A.plantMonths / 1e6, 3) + " M plant-months) and seed " + std::to_string(st.seedB) +
                        " (B, held out: " + std::to_string(B.undergrowth.size()) + " plants, " + fixed(B.seconds, 1) + " s); growth rule " +
                        sim::growthRuleName(st.params.growthRule) + ".");
    r.details.push_back("- Database from A (k-means seed " + std::to_string(st.analysisSeed) + ", kmax " + std::to_string(st.kMax) +
                        "): " + std::to_string(db.regions.size()) + (db.regions.size() == 1 ? " region, " : " regions, ") + fixed(analyseS, 2) +
                        " s. Synthesis on the whole terrain (seed " + std::to_string(st.synthSeed) + "): structured sampler " +
                        std::to_string(structured.plants.size()) + " plants, dart sampler " + std::to_string(darts.plants.size()) +
                        " plants; " + std::to_string(seeded) + " cells in a region; " + fixed(synthS, 2) +
                        " s for the cluster map and both samples. Measures " + fixed(measureS, 2) + " s.");
    r.details.push_back("- The checks read the structured sampler's figures. The dart sampler (`SynthMethod::Darts`, the "
                        "synthesizer before issue 24) is measured alike as a **control**, not checked: where its value "
                        "would fail the bound, the check is able to fail for the reason it exists.");
    // Whether the control's value would meet check `id`'s bound (the relative bounds depend
    // only on the replicate level, which both samplers share).
    const auto bound = [&](const std::string& id, double value) {
        for (const CheckResult& c : r.checks)
            if (c.spec.id == id) return std::string(c.spec.passes(value) ? "pass" : "**fail**");
        return std::string();
    };
    std::string table =
        "\n| figure (overall) | replicate d(A, B) | CSR d(CSR, B) | structured (checked) | dart sampler (control) | "
        "control vs the bound |\n|---|---:|---:|---:|---:|---|\n";
    const auto figRow = [&](const std::string& id, const FidelityFigure& s, const FidelityFigure& d, bool score) {
        const double vs = score ? (s.scored ? s.score : kNaN) : s.scene;
        const double vd = score ? (d.scored ? d.score : kNaN) : d.scene;
        table += "| " + cellText(s.figure) + (score ? ", score" : "") + " | " + fixed(s.replicate, 3) + " | " + fixed(s.csr, 3) + " | " +
                 (score ? fixed(vs, 3) + " (d " + fixed(s.scene, 3) + ")" : fixed(vs, 3)) + " | " +
                 (score ? fixed(vd, 3) + " (d " + fixed(d.scene, 3) + ")" : fixed(vd, 3)) + " | " + bound(id, vd) + " |\n";
    };
    figRow("pooled_g_score", cs.pooledG, cd.pooledG, true);
    figRow("under_crown_share", cs.underCrown, cd.underCrown, false);
    figRow("radius_ratio_median", cs.radiusMedian, cd.radiusMedian, false);
    table += "| plants taller than the crown above (count) | " + num(overallValue(rs, "taller than the crown above (plants)").reference) +
             " (A) | " + num(overallValue(rs, "taller than the crown above (plants)").csr) + " | " + num(cs.tallerThanCrown) +
             " | " + num(cd.tallerThanCrown) + " | " + bound("taller_than_crown", cd.tallerThanCrown) + " |\n";
    figRow("density", cs.density, cd.density, false);
    r.details.push_back(table);
    // Context figures, not checked.
    std::string more = "\nOther figures of the protocol (not checked; scores 0 = replicate, 1 = CSR):\n\n"
                       "| figure (overall) | replicate | CSR | structured | score | darts | score |\n|---|---:|---:|---:|---:|---:|---:|\n";
    for (std::size_t i = 0; i < rs.figures.size(); ++i) {
        const FidelityFigure& s = rs.figures[i];
        if (s.scope != "overall") continue;
        const FidelityFigure& d = overallFigure(rd, s.figure);
        more += "| " + cellText(s.figure) + " | " + fixed(s.replicate, 3) + " | " + fixed(s.csr, 3) + " | " + fixed(s.scene, 3) + " | " +
                (s.scored ? fixed(s.score, 2) : "n/a") + " | " + fixed(d.scene, 3) + " | " + (d.scored ? fixed(d.score, 2) : "n/a") + " |\n";
    }
    for (const char* q : {"plants", "edge / deep", "clearing / deep", "under any crown, share of all", "taller than the CHM (plants)",
                          "pooled g at 0.875 m (plot rectangle)"}) {
        const ValueRow& v = overallValue(rs, q);
        const ValueRow& d = overallValue(rd, q);
        more += "| value: " + v.quantity + " | A " + num(v.reference) + " | B " + num(v.replicate) + " | " + num(v.scene) +
                " | | " + num(d.scene) + " | |\n";
    }
    r.details.push_back(more);

    // The protocol's full reports (Markdown and CSV) and the pooled g of the plot.
    const std::string heading = "## Fidelity scenario `" + sc.name + "` (" + modeName(mode) + "): ";
    writeTextFile(ctx.file(sc.name + "_structured.md"), fidelityMarkdown(rs, heading + "structured sampler against held-out B"));
    writeTextFile(ctx.file(sc.name + "_darts.md"), fidelityMarkdown(rd, heading + "dart sampler (control) against held-out B"));
    writeFidelityCsv(ctx.file(sc.name + "_structured.csv"), rs);
    writeFidelityCsv(ctx.file(sc.name + "_darts.csv"), rd);
    r.details.push_back("- Every figure per region and per species: [" + sc.name + "_structured.md](" + sc.name +
                        "_structured.md), [" + sc.name + "_darts.md](" + sc.name + "_darts.md) (CSV beside them).");
    std::vector<double> mids;
    for (int k = 0; k < fp.bins.count; ++k) mids.push_back(fp.bins.midM(k));
    const std::string png = sc.name + "_pooled_g.png";
    const std::vector<PlotSeries> pooled = {PlotSeries{"simulation B (held out)", mids, rs.gB, {0.1f, 0.1f, 0.1f}, true, 0},
                                            PlotSeries{"simulation A (replicate)", mids, rs.gA, {0.5f, 0.5f, 0.5f}, true, 0},
                                            PlotSeries{"structured sampler", mids, rs.gScene, {0.1f, 0.4f, 0.85f}, true, 0},
                                            PlotSeries{"dart sampler (control)", mids, rd.gScene, {0.85f, 0.3f, 0.1f}, true, 0},
                                            PlotSeries{"CSR", mids, rs.gCsr, {0.2f, 0.65f, 0.2f}, true, 0}};
    writeXYPlotPng(ctx.file(png), "Pooled undergrowth g(r) in the plot", "r (m)", "g(r)", pooled);
    html::LinePlot interactive = toLinePlot("Pooled undergrowth g(r) in the plot", "r (m)", "g(r)", pooled);
    interactive.hasReferenceY = true;
    interactive.referenceY = 1;
    interactive.referenceLabel = "g = 1: no interaction";
    r.figures.push_back({png,
                         "Pooled undergrowth g(r) in the plot rectangle: held-out simulation B, replicate A, the "
                         "structured and the dart sampler's scenes, and CSR.",
                         interactive});
    // report.html: the synthesized scene from above (the whole terrain: canopy and the
    // structured sampler's undergrowth), and the plot as simulation B left it beside the same
    // plot of the scene.
    {
        std::vector<std::string> names;
        for (const Species& sp : dbBiome.species) names.push_back(sp.name);
        const Grid<float>& tm = scene.terrainM;
        const double x1 = tm.originX() + tm.width() * tm.cellSizeM(), y1 = tm.originY() + tm.height() * tm.cellSizeM();
        r.figures.push_back({"",
                             "The synthesized scene from above: " + std::to_string(structured.plants.size()) +
                                 " undergrowth plants of the structured sampler and " + std::to_string(scene.canopy.size()) +
                                 " canopy trees on the whole terrain; the plot compared is " + plotText(size.plot) + " (m).",
                             html::plotView("Synthesized scene (structured sampler), whole terrain", tm.originX(), tm.originY(), x1,
                                            y1, names, scene.canopy, structured.plants)});
        const auto inPlot = [&](const std::vector<Plant>& plants) {
            std::vector<Plant> out;
            for (const Plant& p : plants)
                if (size.plot.contains(p.xM, p.yM)) out.push_back(p);
            return out;
        };
        r.figures.push_back({"", "The plot " + plotText(size.plot) + " (m) as the structured sampler synthesized it.",
                             html::plotView("Synthesized scene in the plot", size.plot.x0, size.plot.y0, size.plot.x1, size.plot.y1,
                                            names, scene.canopy, inPlot(structured.plants))});
        r.figures.push_back({"", "The same plot as the held-out simulation B left it after " + std::to_string(size.years) + " years.",
                             html::plotView("Held-out simulation B in the plot, year " + std::to_string(size.years), size.plot.x0,
                                            size.plot.y0, size.plot.x1, size.plot.y1, names, B.canopy, inPlot(B.undergrowth))});
    }
    ctx.log("validate:   fidelity: done in " + fixed(secondsSince(t0), 1) + " s");
}

}  // namespace

std::unique_ptr<Scenario> createFidelity(const ScenarioParse& in) { return std::make_unique<Fidelity>(in); }
std::vector<ScenarioKeyDoc> fidelityKeys() {
    return joinKeyDocs({scenarioKeyDocs("[protocol]", protocolFields()), scenarioKeyDocs("[quick], [full]", fidelitySizeFields())});
}

}  // namespace eco::validate
