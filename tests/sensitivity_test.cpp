// eco sensitivity (issue 28 item 3): the Morris design, the statistics on functions whose
// elementary effects are known, the seed-noise level, and the outputs measured from a
// simulation file written with known figures.
#include <catch2/catch.hpp>

#include <cmath>
#include <set>

#include "biome.h"
#include "sensitivity.h"
#include "sim_file.h"
#include "test_util.h"

using namespace eco;
using namespace eco::pipeline;

TEST_CASE("Morris design: every trajectory moves each parameter once by the step, on the grid in [0, 1]", "[sensitivity]") {
    for (const int levels : {2, 4, 6}) {
        const MorrisDesign d = morrisDesign(5, 40, levels, 3);
        const double delta = levels / (2.0 * (levels - 1));
        CHECK(d.delta == Approx(delta));
        REQUIRE(d.points.size() == 40);
        std::set<double> firstValues;
        for (std::size_t t = 0; t < d.points.size(); ++t) {
            REQUIRE(d.points[t].size() == 6);
            std::set<int> moved(d.moved[t].begin(), d.moved[t].end());
            CHECK(moved.size() == 5);
            for (std::size_t j = 0; j < 6; ++j)
                for (double x : d.points[t][j]) {
                    CHECK(x >= 0);
                    CHECK(x <= 1);
                    const double level = x * (levels - 1);
                    CHECK(std::fabs(level - std::round(level)) < 1e-12);
                }
            for (std::size_t j = 0; j < 5; ++j)
                for (int i = 0; i < 5; ++i) {
                    const double step = d.points[t][j + 1][static_cast<std::size_t>(i)] - d.points[t][j][static_cast<std::size_t>(i)];
                    if (i == d.moved[t][j]) CHECK(std::fabs(step) == Approx(delta));
                    else CHECK(step == 0);
                }
            firstValues.insert(d.points[t][0][0]);
        }
        // The start points differ between trajectories (all the levels are used).
        CHECK(static_cast<int>(firstValues.size()) == levels);
    }
    // The same seed, the same design; another seed, another.
    CHECK(morrisDesign(3, 5, 4, 9).points == morrisDesign(3, 5, 4, 9).points);
    CHECK(morrisDesign(3, 5, 4, 9).points != morrisDesign(3, 5, 4, 10).points);
    CHECK_THROWS_AS(morrisDesign(3, 5, 3, 1), ValidationError);
}

TEST_CASE("Morris statistics: the elementary effects of a known function", "[sensitivity]") {
    // y = 3 x0 - 2 x1 + 0 x2 + 4 x0 x3: the effect of x1 is -2 everywhere (sigma 0), x2 has
    // none, x0's depends on x3 (3 + 4 x3: spread) and x3's on x0.
    const MorrisDesign d = morrisDesign(4, 30, 4, 11);
    const auto f = [](const std::vector<double>& x) { return 3 * x[0] - 2 * x[1] + 4 * x[0] * x[3]; };
    std::vector<std::vector<double>> y;
    std::vector<double> meanX0Effect, meanX3Effect;
    for (std::size_t t = 0; t < d.points.size(); ++t) {
        y.emplace_back();
        for (const auto& p : d.points[t]) y.back().push_back(f(p));
        // The effects as the definition gives them, to compare the means with.
        for (std::size_t j = 0; j < 4; ++j) {
            const auto& a = d.points[t][j];
            if (d.moved[t][j] == 0) meanX0Effect.push_back(3 + 4 * a[3]);
            if (d.moved[t][j] == 3) meanX3Effect.push_back(4 * a[0]);
        }
    }
    const std::vector<MorrisStats> s = morrisStatistics(d, y);
    REQUIRE(s.size() == 4);
    for (const auto& st : s) CHECK(st.effects == 30);
    CHECK(s[1].mu == Approx(-2));
    CHECK(s[1].muStar == Approx(2));
    CHECK(s[1].sigma == Approx(0).margin(1e-12));
    CHECK(s[2].muStar == 0);
    double m0 = 0;
    for (double e : meanX0Effect) m0 += e;
    CHECK(s[0].mu == Approx(m0 / 30));
    CHECK(s[0].sigma > 0.5);
    double m3 = 0;
    for (double e : meanX3Effect) m3 += e;
    CHECK(s[3].mu == Approx(m3 / 30));
    CHECK(s[3].muStar == Approx(m3 / 30));  // 4 x0 >= 0: mu* = mu
    CHECK(s[0].muStar > s[3].muStar);
    // Ranking by mu*: x0, then x1 or x3, x2 last.
    CHECK(s[2].muStar < s[1].muStar);
}

TEST_CASE("Morris seed noise: common seeds cancel, independent noise is measured", "[sensitivity]") {
    const MorrisDesign d = morrisDesign(2, 10, 4, 5);
    // Replicate r adds the same offset at every point (what a shared seed gives): no noise
    // left in the steps.
    std::vector<std::vector<std::vector<double>>> shared, independent;
    for (std::size_t t = 0; t < d.points.size(); ++t) {
        shared.emplace_back();
        independent.emplace_back();
        for (std::size_t j = 0; j < d.points[t].size(); ++j) {
            const double base = d.points[t][j][0];
            shared.back().push_back({base + 0.3, base - 0.3});
            // Noise that flips sign from point to point: a step's two differences are +-0.6 + the
            // effect, whose sample variance is 0.72.
            const double e = j % 2 == 0 ? 0.3 : -0.3;
            independent.back().push_back({base + e, base - e});
        }
    }
    const SeedNoise a = seedNoise(d, shared);
    CHECK(a.replicateSd == Approx(std::sqrt(0.18)));
    CHECK(a.muStarNoise == Approx(0).margin(1e-12));
    const SeedNoise b = seedNoise(d, independent);
    CHECK(b.replicateSd == Approx(std::sqrt(0.18)));
    const double pi = 3.14159265358979323846;
    CHECK(b.muStarNoise == Approx(std::sqrt(2 / pi) * std::sqrt(0.72 / 2) / d.delta));
    // One replicate: not measured.
    std::vector<std::vector<std::vector<double>>> one(10, std::vector<std::vector<double>>(3, std::vector<double>{1.0}));
    CHECK(std::isnan(seedNoise(d, one).muStarNoise));
}

TEST_CASE("Sensitivity outputs: parsed from their text, measured from a simulation's time series", "[sensitivity]") {
    CHECK_THROWS_WITH(parseSimulationOutput("share@30", "s.toml"), Catch::Contains("s.toml") && Catch::Contains("needs a species"));
    CHECK_THROWS_WITH(parseSimulationOutput("height@30", "s.toml"), Catch::Contains("unknown measure 'height'"));
    CHECK_THROWS_WITH(parseSimulationOutput("density", "s.toml"), Catch::Contains("MEASURE[:SPECIES]@YEAR"));
    CHECK_THROWS_WITH(parseSimulationOutput("cv@30", "s.toml"), Catch::Contains("window"));
    CHECK_THROWS_WITH(parseSimulationOutput("cv@30-20", "s.toml"), Catch::Contains("must follow"));
    CHECK_THROWS_WITH(parseSimulationOutput("density@x1", "s.toml"), Catch::Contains("not a year"));

    test::TempDir dir("sensitivity_measure");
    const Biome biome = defaultBiome();
    const std::size_t ns = biome.species.size();
    const int toyon = biome.speciesIndex("Toyon"), fern = biome.speciesIndex("Western Swordfern");
    SimulationFileInfo info;
    info.years = 3;
    info.x0 = 0;
    info.y0 = 0;
    info.x1 = 10;
    info.y1 = 20;  // 200 m2
    std::vector<YearRecord> series;
    for (int year = 0; year <= 3; ++year) {
        YearRecord r;
        r.year = year;
        r.count.assign(ns, 0);
        r.meanHeightM.assign(ns, 0);
        r.meanVigour.assign(ns, 0);
        r.crownAreaM2.assign(ns, 0);
        r.count[static_cast<std::size_t>(toyon)] = 10 * (year + 1);  // 10, 20, 30, 40
        r.count[static_cast<std::size_t>(fern)] = 30;
        r.meanHeightM[static_cast<std::size_t>(toyon)] = 2.0;
        r.meanHeightM[static_cast<std::size_t>(fern)] = 1.0;
        r.crownAreaM2[static_cast<std::size_t>(toyon)] = 50;
        r.crownAreaM2[static_cast<std::size_t>(fern)] = 10;
        series.push_back(r);
    }
    const std::string path = dir.file("sim.h5");
    writeSimulationFile(path, info, biome, {{3, {}}}, series, {});
    CHECK(measureOutput(path, parseSimulationOutput("share:Toyon@1", "t")) == Approx(20.0 / 50));
    CHECK(measureOutput(path, parseSimulationOutput("density@3", "t")) == Approx(70.0 / 200));
    CHECK(measureOutput(path, parseSimulationOutput("mean_height@0", "t")) == Approx((10 * 2.0 + 30 * 1.0) / 40));
    CHECK(measureOutput(path, parseSimulationOutput("mean_height:Western Swordfern@2", "t")) == Approx(1.0));
    CHECK(measureOutput(path, parseSimulationOutput("cover@2", "t")) == Approx(60.0 / 200));
    CHECK(measureOutput(path, parseSimulationOutput("cover:Toyon@2", "t")) == Approx(50.0 / 200));
    // Totals 40, 50, 60, 70 over years 0-3: mean 55, population sd sqrt(125).
    CHECK(measureOutput(path, parseSimulationOutput("cv@0-3", "t")) == Approx(std::sqrt(125.0) / 55));
    CHECK_THROWS_WITH(measureOutput(path, parseSimulationOutput("density@9", "t")), Catch::Contains("year 9") && Catch::Contains("0 .. 3"));
    CHECK_THROWS_WITH(measureOutput(path, parseSimulationOutput("share:Nonesuch@1", "t")), Catch::Contains("no species 'Nonesuch'"));
}
