// Kind "abiotic_gradients" (paper §7.2), forest scene: sun-tolerant species grow where the
// site is sunnier than where shade-tolerant ones grow. docs/validation.md defines the measure.
#include "scenario_context.h"

#include <algorithm>
#include <cmath>

#include "image_out.h"
#include "scenario_keys.h"
#include "strict_toml.h"

namespace eco::validate {

namespace {

struct GradientSettings {
    std::vector<std::string> shadeSpecies, sunSpecies;
    int windowYears = 25;
    int minPlants = 10;  ///< a species with fewer plants in the window makes the check not evaluable
};

/// [gradients]'s numeric keys (the species lists are read by hand).
const std::vector<ParamDesc<GradientSettings>>& gradientFields() {
    using P = GradientSettings;
    using K = ParamDesc<P>::Kind;
    static const std::vector<ParamDesc<P>> fields = {
        {"window_years", "the mean site sun is taken over this many years ending at the measured year", "years", K::Integer,
         nullptr, &P::windowYears, ParamRange::closed(1, 100000)},
        {"min_plants", "plant-snapshots a species needs in the window (fewer: the check is not evaluable)", "", K::Integer,
         nullptr, &P::minPlants, ParamRange::closed(1, 1000000000)},
    };
    return fields;
}

class AbioticGradients final : public Scenario {
public:
    explicit AbioticGradients(const ScenarioParse& in);
    std::vector<std::string> checkIds() const override { return {"sun_gap"}; }
    std::vector<std::pair<std::string, std::string>> speciesNamed() const override {
        std::vector<std::pair<std::string, std::string>> out;
        for (const auto& s : settings_.shadeSpecies) out.emplace_back("[gradients] shade_species", s);
        for (const auto& s : settings_.sunSpecies) out.emplace_back("[gradients] sun_species", s);
        return out;
    }
    int windowYears() const override { return settings_.windowYears; }
    void run(const ScenarioConfig& sc, ScenarioContext& ctx, ScenarioResult& r) const override;

private:
    GradientSettings settings_;
};

AbioticGradients::AbioticGradients(const ScenarioParse& in) {
    GradientSettings& g = settings_;
    StrictTable s(in.top.table("gradients"), in.path, "[gradients]");
    g.shadeSpecies = nonEmptyStrings(s, "shade_species");
    g.sunSpecies = nonEmptyStrings(s, "sun_species");
    readScenarioParams(s, g, gradientFields());
    s.finish();
}

void AbioticGradients::run(const ScenarioConfig& sc, ScenarioContext& ctx, ScenarioResult& r) const {
    const Biome& biome = ctx.biome();
    const GradientSettings& cfg = settings_;
    const ForestRun& run = ctx.forest(sc.scenePath, sim::CompetitionMode::Resources, 0);
    const int Y = ctx.measureYear(sc);
    ctx.describeRun(run, Y, r, ctx.scene(sc));
    const auto snaps = run.window(Y - cfg.windowYears + 1, Y);
    const std::size_t ns = biome.species.size();
    std::vector<double> sum(ns, 0), n(ns, 0), shareSum(ns, 0);
    const Grid<float>& g = run.site[Factor::Sun];
    for (const Snapshot* s : snaps)
        for (const LitePlant& p : s->plants) {
            const auto k = static_cast<std::size_t>(p.species);
            sum[k] += g.clamped(g.cellX(p.x), g.cellY(p.y));
            shareSum[k] += p.sunShare;
            n[k] += 1;
        }
    auto meanSun = [&](const std::string& name) {
        const auto k = static_cast<std::size_t>(biome.speciesIndex(name));
        return n[k] >= cfg.minPlants ? sum[k] / n[k] : kNaN;
    };
    double gap = kNaN;
    std::string note;
    bool first = true;
    for (const auto& shade : cfg.shadeSpecies)
        for (const auto& sun : cfg.sunSpecies) {
            const double d = meanSun(sun) - meanSun(shade);
            if (std::isnan(d)) {
                note = "fewer than " + std::to_string(cfg.minPlants) + " plants of " +
                       (std::isnan(meanSun(sun)) ? sun : shade) + " in the window";
                gap = kNaN;
                first = false;
                continue;
            }
            if (!note.empty()) continue;
            gap = first ? d : std::min(gap, d);
            first = false;
        }
    r.checks.push_back(makeCheck(sc, "sun_gap",
                                 "smallest difference of mean site sunlight (h/day), sun-tolerant minus shade-tolerant species",
                                 gap, note));
    r.details.push_back("- Site sunlight of a plant: the annual mean of the monthly sun map (terrain shadows, no canopy) "
                        "at its root times the canopy transmission there (product of 1 - alpha of the covering canopy "
                        "crowns), hours per day; averaged over the plants of each species in the " +
                        std::to_string(snaps.size()) + " snapshots of the last " + std::to_string(cfg.windowYears) +
                        " years. Undergrowth shading is not included (it is what the plant receives, not where it sits).");
    std::string table = "\n| species | role | plant-snapshots | mean site sun (h/day) | mean last-month sun share (h/day, December) |\n|---|---|---|---|---|\n";
    auto row = [&](const std::string& name, const std::string& role) {
        const auto k = static_cast<std::size_t>(biome.speciesIndex(name));
        table += "| " + name + " | " + role + " | " + num(n[k], 7) + " | " + (n[k] > 0 ? fixed(sum[k] / n[k], 2) : "n/a") +
                 " | " + (n[k] > 0 ? fixed(shareSum[k] / n[k], 2) : "n/a") + " |\n";
    };
    for (const auto& s : cfg.shadeSpecies) row(s, "shade-tolerant");
    for (const auto& s : cfg.sunSpecies) row(s, "sun-tolerant");
    r.details.push_back(table);
    const std::string png = sc.name + "_site_sun.png";
    writeMapPng(ctx.file(png), run.site[Factor::Sun], "Annual-mean sun under the canopy", "hours/day", Colormap::Heat);
    r.figures.push_back({png, "Site sunlight (annual mean after canopy shade) that the measure samples."});
}

}  // namespace

std::unique_ptr<Scenario> createAbioticGradients(const ScenarioParse& in) { return std::make_unique<AbioticGradients>(in); }
std::vector<ScenarioKeyDoc> abioticGradientsKeys() { return scenarioKeyDocs("[gradients]", gradientFields()); }

}  // namespace eco::validate
