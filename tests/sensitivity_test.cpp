// eco sensitivity (issue 28 item 3): the Morris design, the statistics on functions whose
// elementary effects are known, the seed-noise level, and the outputs measured from a
// simulation file written with known figures.
#include <catch2/catch.hpp>

#include <cmath>
#include <fstream>
#include <functional>
#include <map>
#include <set>

#include "biome.h"
#include "rng.h"
#include "sensitivity.h"
#include "sim_file.h"
#include "sim_file_fixture.h"
#include "sobol_sequence.h"
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
    // A share over a window: the mean of the yearly shares (10/40, 20/50, 30/60, 40/70 for Toyon),
    // not the share of the summed counts (100/220).
    CHECK(measureOutput(path, parseSimulationOutput("share:Toyon@1-3", "t")) == Approx((20.0 / 50 + 30.0 / 60 + 40.0 / 70) / 3));
    CHECK(measureOutput(path, parseSimulationOutput("share:Toyon@0-1", "t")) == Approx((10.0 / 40 + 20.0 / 50) / 2));
    // A species' count at one year over its count at another (either order).
    CHECK(measureOutput(path, parseSimulationOutput("ratio:Toyon@3/1", "t")) == Approx(2.0));
    CHECK(measureOutput(path, parseSimulationOutput("ratio:Toyon@0/3", "t")) == Approx(0.25));
    CHECK(measureOutput(path, parseSimulationOutput("ratio:Western Swordfern@3/0", "t")) == Approx(1.0));
    // No plants at the denominator's year: the count over 1 (here: Redwood is absent throughout).
    CHECK(measureOutput(path, parseSimulationOutput("ratio:Redwood@3/0", "t")) == 0.0);
    CHECK_THROWS_WITH(measureOutput(path, parseSimulationOutput("ratio:Toyon@3/9", "t")), Catch::Contains("year 9"));
    CHECK_THROWS_WITH(parseSimulationOutput("ratio@3/1", "s.toml"), Catch::Contains("s.toml") && Catch::Contains("needs a species"));
    CHECK_THROWS_WITH(parseSimulationOutput("ratio:Toyon@3", "s.toml"), Catch::Contains("two years"));
    CHECK_THROWS_WITH(parseSimulationOutput("ratio:Toyon@3/3", "s.toml"), Catch::Contains("must differ"));
    CHECK_THROWS_WITH(parseSimulationOutput("share:Toyon@3-1", "s.toml"), Catch::Contains("must follow"));
    CHECK_THROWS_WITH(measureOutput(path, parseSimulationOutput("density@9", "t")), Catch::Contains("year 9") && Catch::Contains("0 .. 3"));
    CHECK_THROWS_WITH(measureOutput(path, parseSimulationOutput("share:Nonesuch@1", "t")), Catch::Contains("no species 'Nonesuch'"));
}

namespace {

/// Ishigami (1990): y = sin x1 + a sin^2 x2 + b x3^4 sin x1 on [-pi, pi]^3, a = 7, b = 0.1.
/// Its indices are known in closed form (Sobol' and Levitan 1999).
struct Ishigami {
    static constexpr double kA = 7, kB = 0.1, kPi = 3.14159265358979323846;
    static double f(const std::vector<double>& u) {
        const double x1 = -kPi + 2 * kPi * u[0], x2 = -kPi + 2 * kPi * u[1], x3 = -kPi + 2 * kPi * u[2];
        return std::sin(x1) + kA * std::sin(x2) * std::sin(x2) + kB * std::pow(x3, 4) * std::sin(x1);
    }
    static double pi4() { return std::pow(kPi, 4); }
    static double v1() { return 0.5 * std::pow(1 + kB * pi4() / 5, 2); }
    static double v2() { return kA * kA / 8; }
    static double v13() { return kB * kB * std::pow(kPi, 8) * (1.0 / 18 - 1.0 / 50); }
    static double variance() { return v1() + v2() + v13(); }
};

SobolResult sobolOf(const SobolDesign& d, const std::function<double(const std::vector<double>&)>& f, int bootstrap) {
    std::vector<double> fA, fB;
    std::vector<std::vector<double>> fAB(static_cast<std::size_t>(d.parameters));
    for (int n = 0; n < d.samples; ++n) {
        fA.push_back(f(d.point(0, n)));
        fB.push_back(f(d.point(1, n)));
        for (int i = 0; i < d.parameters; ++i) fAB[static_cast<std::size_t>(i)].push_back(f(d.point(2 + i, n)));
    }
    return sobolIndices(fA, fB, fAB, bootstrap, 5);
}

}  // namespace

TEST_CASE("Sobol design: A, B and each AB_i differ from A in column i only", "[sensitivity]") {
    const SobolDesign d = sobolDesign(4, 50, 7);
    REQUIRE(d.a.size() == 50);
    REQUIRE(d.b.size() == 50);
    CHECK(d.matrices() == 6);
    for (int n = 0; n < 50; ++n) {
        CHECK(d.point(0, n) == d.a[static_cast<std::size_t>(n)]);
        CHECK(d.point(1, n) == d.b[static_cast<std::size_t>(n)]);
        for (int i = 0; i < 4; ++i) {
            const std::vector<double> x = d.point(2 + i, n);
            for (int j = 0; j < 4; ++j) {
                const double want = j == i ? d.b[static_cast<std::size_t>(n)][static_cast<std::size_t>(j)] : d.a[static_cast<std::size_t>(n)][static_cast<std::size_t>(j)];
                CHECK(x[static_cast<std::size_t>(j)] == want);
                CHECK(want >= 0);
                CHECK(want < 1);
            }
        }
    }
    // A larger design begins with the same rows; another seed gives others.
    const SobolDesign more = sobolDesign(4, 80, 7);
    CHECK(std::vector<std::vector<double>>(more.a.begin(), more.a.begin() + 50) == d.a);
    CHECK(sobolDesign(4, 50, 8).a != d.a);
    CHECK(sobolMemberName(0, 0, 0) == "A-0001-r01");
    CHECK(sobolMemberName(1, 9, 1) == "B-0010-r02");
    CHECK(sobolMemberName(4, 0, 0) == "AB03-0001-r01");
}

TEST_CASE("Sobol indices: the Ishigami function's known first-order and total indices", "[sensitivity]") {
    const double v = Ishigami::variance();
    const double s1 = Ishigami::v1() / v, s2 = Ishigami::v2() / v, s3 = 0;
    const double t1 = (Ishigami::v1() + Ishigami::v13()) / v, t2 = s2, t3 = Ishigami::v13() / v;
    // The closed forms, as published (Saltelli et al. 2008: 0.314, 0.442, 0; 0.558, 0.442, 0.244).
    CHECK(s1 == Approx(0.3139).margin(5e-4));
    CHECK(s2 == Approx(0.4424).margin(5e-4));
    CHECK(t3 == Approx(0.2437).margin(5e-4));
    const SobolResult r = sobolOf(sobolDesign(3, 8192, 1), Ishigami::f, 200);
    REQUIRE(r.indices.size() == 3);
    CHECK(r.variance == Approx(v).epsilon(0.05));
    const double want[3][2] = {{s1, t1}, {s2, t2}, {s3, t3}};
    for (std::size_t i = 0; i < 3; ++i) {
        INFO("parameter " << i + 1);
        const SobolIndex& s = r.indices[i];
        CHECK(s.first == Approx(want[i][0]).margin(0.04));
        CHECK(s.total == Approx(want[i][1]).margin(0.04));
        // The 95 % intervals hold the estimate and are narrow at this N.
        CHECK(s.firstLow <= s.first);
        CHECK(s.first <= s.firstHigh);
        CHECK(s.totalLow <= s.total);
        CHECK(s.total <= s.totalHigh);
        CHECK(s.firstHigh - s.firstLow < 0.12);
        CHECK(s.totalHigh - s.totalLow < 0.12);
        CHECK(s.firstLow - 0.02 < want[i][0]);
        CHECK(s.firstHigh + 0.02 > want[i][0]);
    }
    // x3 acts only with x1: no first-order effect, a total one; x2 acts alone: S = ST.
    CHECK(r.indices[2].total - r.indices[2].first > 0.15);
    CHECK(r.indices[1].total - r.indices[1].first == Approx(0).margin(0.03));
}

TEST_CASE("Sobol sequence: the first points are those of Joe and Kuo's reference program", "[sensitivity]") {
    // The output of Joe and Kuo's sobol.cc with new-joe-kuo-6.21201 (as published in Sobol.jl's
    // test/results/exp_results_5, _20 and _50): points 0 .. 7 in 5 dimensions, point 100 in
    // 20 and points 677 and 1023 in 50 (these need the direction numbers up to m_10).
    const double first[8][5] = {{0, 0, 0, 0, 0},
                                {0.5, 0.5, 0.5, 0.5, 0.5},
                                {0.75, 0.25, 0.25, 0.25, 0.75},
                                {0.25, 0.75, 0.75, 0.75, 0.25},
                                {0.375, 0.375, 0.625, 0.875, 0.375},
                                {0.875, 0.875, 0.125, 0.375, 0.875},
                                {0.625, 0.125, 0.875, 0.625, 0.625},
                                {0.125, 0.625, 0.375, 0.125, 0.125}};
    const SobolSequence five(5);
    for (std::uint32_t n = 0; n < 8; ++n) {
        INFO("point " << n);
        CHECK(five.point(n) == std::vector<double>(first[n], first[n] + 5));
    }
    CHECK(SobolSequence(20).point(100) ==
          std::vector<double>{0.4140625, 0.2578125, 0.7734375, 0.7265625, 0.8828125, 0.7421875, 0.0234375, 0.4765625, 0.6328125, 0.6953125,
                              0.4609375, 0.6796875, 0.4765625, 0.8515625, 0.3203125, 0.4921875, 0.6796875, 0.7421875, 0.8359375, 0.3359375});
    const SobolSequence fifty(50);
    CHECK(fifty.point(677) ==
          std::vector<double>{0.9365234375, 0.6923828125, 0.1689453125, 0.1279296875, 0.3369140625, 0.4443359375, 0.4228515625, 0.1083984375,
                              0.9052734375, 0.0908203125, 0.2626953125, 0.4560546875, 0.4208984375, 0.4013671875, 0.3486328125, 0.4228515625,
                              0.5107421875, 0.5888671875, 0.4189453125, 0.8564453125, 0.3564453125, 0.8408203125, 0.0068359375, 0.6748046875,
                              0.3349609375, 0.5693359375, 0.2451171875, 0.1533203125, 0.8935546875, 0.7880859375, 0.7275390625, 0.5263671875,
                              0.1181640625, 0.5439453125, 0.2412109375, 0.6474609375, 0.2529296875, 0.4345703125, 0.3173828125, 0.9736328125,
                              0.6728515625, 0.0341796875, 0.5400390625, 0.5556640625, 0.0419921875, 0.8369140625, 0.2099609375, 0.7255859375,
                              0.4892578125, 0.8994140625});
    CHECK(fifty.point(1023) ==
          std::vector<double>{0.0009765625, 0.7529296875, 0.6123046875, 0.1455078125, 0.1865234375, 0.4384765625, 0.1396484375, 0.6181640625,
                              0.3447265625, 0.8505859375, 0.6787109375, 0.0361328125, 0.1298828125, 0.6650390625, 0.3623046875, 0.4638671875,
                              0.3134765625, 0.8759765625, 0.5849609375, 0.3193359375, 0.8662109375, 0.0185546875, 0.7939453125, 0.1962890625,
                              0.2392578125, 0.3759765625, 0.5087890625, 0.7607421875, 0.8408203125, 0.4345703125, 0.9287109375, 0.6142578125,
                              0.4521484375, 0.8740234375, 0.3330078125, 0.8642578125, 0.9423828125, 0.9873046875, 0.9013671875, 0.6982421875,
                              0.6318359375, 0.9736328125, 0.9287109375, 0.1083984375, 0.4970703125, 0.3115234375, 0.9658203125, 0.7626953125,
                              0.8427734375, 0.8232421875});
    // Every 2^m first points are stratified in each dimension: one in each interval of 2^-m.
    for (int d = 0; d < 50; ++d) {
        std::set<std::uint32_t> cells;
        for (std::uint32_t n = 0; n < 256; ++n) cells.insert(static_cast<std::uint32_t>(fifty.point(n)[static_cast<std::size_t>(d)] * 256));
        CHECK(cells.size() == 256);
    }
    CHECK_THROWS_WITH(SobolSequence(51), Catch::Contains("1 .. 50"));
    CHECK_THROWS(SobolSequence(0));
}

TEST_CASE("Sobol indices: quasi-random designs estimate the Ishigami indices better than pseudo-random ones at equal N", "[sensitivity]") {
    const double v = Ishigami::variance();
    const double want[3][2] = {{Ishigami::v1() / v, (Ishigami::v1() + Ishigami::v13()) / v}, {Ishigami::v2() / v, Ishigami::v2() / v}, {0, Ishigami::v13() / v}};
    // The error of a design: the largest |estimate - truth| of the six indices.
    const auto error = [&](const SobolDesign& d) {
        const SobolResult r = sobolOf(d, Ishigami::f, 0);
        double e = 0;
        for (std::size_t i = 0; i < 3; ++i) e = std::max({e, std::abs(r.indices[i].first - want[i][0]), std::abs(r.indices[i].total - want[i][1])});
        return e;
    };
    for (const int n : {256, 1024}) {
        INFO("N = " << n);
        const SobolDesign q = sobolDesign(3, n, 1, SensitivitySpec::Sampling::QuasiRandom);
        CHECK(q.sampling == SensitivitySpec::Sampling::QuasiRandom);
        const double quasi = error(q);
        double randomMean = 0;
        int randomBetter = 0;
        const int seeds = 20;
        for (int seed = 1; seed <= seeds; ++seed) {
            const double e = error(sobolDesign(3, n, static_cast<std::uint64_t>(seed)));
            randomMean += e / seeds;
            if (e < quasi) ++randomBetter;
        }
        INFO("quasi-random error " << quasi << ", pseudo-random mean error " << randomMean << ", better in " << randomBetter << " of " << seeds);
        CHECK(quasi < 0.5 * randomMean);
        CHECK(randomBetter <= 2);
    }
    // The quasi-random design: rows n of A and B are point n + 1 of the 6-dimensional sequence;
    // no seed; a larger N begins with the same rows.
    const SobolDesign q = sobolDesign(3, 64, 1, SensitivitySpec::Sampling::QuasiRandom);
    const std::vector<double> p5 = SobolSequence(6).point(5);
    CHECK(q.a[4] == std::vector<double>(p5.begin(), p5.begin() + 3));
    CHECK(q.b[4] == std::vector<double>(p5.begin() + 3, p5.end()));
    CHECK(sobolDesign(3, 64, 2, SensitivitySpec::Sampling::QuasiRandom).a == q.a);
    const SobolDesign more = sobolDesign(3, 100, 1, SensitivitySpec::Sampling::QuasiRandom);
    CHECK(std::vector<std::vector<double>>(more.b.begin(), more.b.begin() + 64) == q.b);
    CHECK_THROWS_WITH(sobolDesign(26, 8, 1, SensitivitySpec::Sampling::QuasiRandom), Catch::Contains("25 parameters"));
}

TEST_CASE("Sobol indices: a linear model's shares c_i^2 / sum c^2, and a parameter without effect gets 0", "[sensitivity]") {
    // y = 4 x1 + 2 x2 + 1 x3 + 0 x4 on the unit cube: V_i = c_i^2 / 12, no interactions.
    const auto f = [](const std::vector<double>& x) { return 4 * x[0] + 2 * x[1] + x[2]; };
    const SobolResult r = sobolOf(sobolDesign(4, 8192, 3), f, 100);
    const double c2[4] = {16, 4, 1, 0};
    for (std::size_t i = 0; i < 4; ++i) {
        CHECK(r.indices[i].first == Approx(c2[i] / 21).margin(0.04));
        CHECK(r.indices[i].total == Approx(c2[i] / 21).margin(0.03));
    }
    CHECK(r.indices[3].total == 0);
    CHECK(r.indices[3].first == 0);
    CHECK(r.variance == Approx(21.0 / 12).epsilon(0.06));
    // Without bootstrap the intervals are the estimates.
    const SobolResult plain = sobolOf(sobolDesign(4, 64, 3), f, 0);
    CHECK(plain.indices[0].firstLow == plain.indices[0].first);
    CHECK(plain.indices[0].totalHigh == plain.indices[0].total);
}

TEST_CASE("Sobol seed noise: its share of the variance and the total index of noise alone", "[sensitivity]") {
    // y = x1 + noise: per point R = 4 replicates; the noise of replicate r is common to every
    // point (common seeds: it cancels in A - AB_i) plus an independent part of sd 0.2.
    const int N = 400, R = 4;
    const SobolDesign d = sobolDesign(2, N, 9);
    RandomStream rs(11, 0);
    std::vector<double> common(R);
    for (double& c : common) c = rs.uniform(-1, 1);
    const double sd = 0.2;
    std::vector<std::vector<std::vector<double>>> values(4, std::vector<std::vector<double>>(N));
    for (int m = 0; m < 4; ++m)
        for (int n = 0; n < N; ++n)
            for (int r = 0; r < R; ++r) {
                // A uniform of sd 0.2: width sd sqrt(12).
                const double e = (rs.uniform() - 0.5) * sd * std::sqrt(12.0);
                values[static_cast<std::size_t>(m)][static_cast<std::size_t>(n)].push_back(d.point(m, n)[0] + common[static_cast<std::size_t>(r)] + e);
            }
    const SobolNoise noise = sobolNoise(values);
    // Within a point the replicates differ by the common parts too.
    CHECK(noise.replicateSd > sd);
    // The mean of R replicates varies from point to point by sd^2 / R of noise (the common
    // part is the same at every point); V = 1/12 + sd^2 / R.
    const double noiseVar = sd * sd / R, v = 1.0 / 12 + noiseVar;
    CHECK(noise.varianceShare == Approx(noiseVar / v).epsilon(0.12));
    // One replicate: not measured.
    std::vector<std::vector<std::vector<double>>> one(4, std::vector<std::vector<double>>(3, std::vector<double>{1.0}));
    CHECK(std::isnan(sobolNoise(one).varianceShare));
}

TEST_CASE("Study parameters: log-scaled and integer ranges map the unit interval as documented", "[sensitivity]") {
    const StudyParameter lin = makeStudyParameter("model.x", 2, 6, "t");
    CHECK(lin.at(0.25) == Approx(3));
    CHECK(lin.unitOf(3) == Approx(0.25));
    // A probability over three decades: each decade a third of the interval.
    const StudyParameter lg = makeStudyParameter("model.p", 1e-4, 1e-1, "t", true);
    CHECK(lg.at(0) == Approx(1e-4));
    CHECK(lg.at(1.0 / 3) == Approx(1e-3));
    CHECK(lg.at(2.0 / 3) == Approx(1e-2));
    CHECK(lg.at(1) == Approx(1e-1));
    CHECK(lg.unitOf(1e-2) == Approx(2.0 / 3));
    CHECK(lg.describe() == "0.0001 .. 0.1 (log)");
    // Integers 1 .. 4: each a quarter of the interval; the middle of its quarter maps back.
    const StudyParameter in = makeStudyParameter("biome.species.Toyon.max_age_years", 1, 4, "t", false, true);
    CHECK(in.at(0) == 1);
    CHECK(in.at(0.2499) == 1);
    CHECK(in.at(0.25) == 2);
    CHECK(in.at(0.74) == 3);
    CHECK(in.at(1) == 4);
    for (int v = 1; v <= 4; ++v) CHECK(in.at(in.unitOf(v)) == v);
    CHECK(in.unitOf(3) == Approx(0.625));
    std::map<double, int> counts;
    for (int k = 0; k < 400; ++k) ++counts[in.at((k + 0.5) / 400)];
    CHECK(counts == std::map<double, int>{{1, 100}, {2, 100}, {3, 100}, {4, 100}});
    // Log and integer: 1 .. 99 over [log 1, log 100): 1 .. 9 take half the interval.
    const StudyParameter li = makeStudyParameter("biome.species.Toyon.max_age_years", 1, 99, "t", true, true);
    CHECK(li.at(0.4999) == 9);
    CHECK(li.at(0.5) == 10);
    CHECK(li.at(1) == 99);
    CHECK_THROWS_WITH(makeStudyParameter("model.p", 0, 1, "t", true), Catch::Contains("LOW > 0"));
    CHECK_THROWS_WITH(makeStudyParameter("model.n", 1, 2.5, "t", false, true), Catch::Contains("whole numbers"));
}

TEST_CASE("Sensitivity specification: method sobol, log and integer parameters, refused keys", "[sensitivity]") {
    test::TempDir dir("sensitivity_spec");
    const auto write = [&](const std::string& head, const std::string& params) {
        const std::string path = dir.file("s.toml");
        std::ofstream(path) << "[sensitivity]\nout_dir = \"" << dir.file("out") << "\"\noutputs = [\"density@3\"]\n" << head
                            << "\n[sensitivity.parameters]\n" << params << "\n[sensitivity.base.run]\nout_dir = \"x\"\n";
        return path;
    };
    const std::string params = "\"model.seeding_probability\" = { low = 0.0001, high = 0.01, scale = \"log\" }\n"
                               "\"biome.species.Toyon.max_age_years\" = { low = 50, high = 200, integer = true }\n"
                               "\"biome.species.Toyon.alpha\" = [0.5, 0.8]\n";
    const SensitivitySpec s = loadSensitivitySpec(write("method = \"sobol\"\nsamples = 16\nbootstrap = 50\nreplicates = 3", params));
    CHECK(s.method == SensitivitySpec::Method::Sobol);
    CHECK(s.samples == 16);
    CHECK(s.bootstrap == 50);
    CHECK(s.sampling == SensitivitySpec::Sampling::Random);
    CHECK(loadSensitivitySpec(write("method = \"sobol\"\nsampling = \"quasi-random\"", params)).sampling == SensitivitySpec::Sampling::QuasiRandom);
    REQUIRE(s.parameters.size() == 3);
    // toml++ keeps a table's keys sorted.
    std::map<std::string, StudyParameter> byKey;
    for (const auto& p : s.parameters) byKey[p.key] = p;
    CHECK(byKey["model.seeding_probability"].logScale);
    CHECK(!byKey["model.seeding_probability"].integer);
    CHECK(byKey["biome.species.Toyon.max_age_years"].integer);
    CHECK(!byKey["biome.species.Toyon.alpha"].logScale);
    const std::vector<std::pair<std::pair<std::string, std::string>, std::string>> bad = {
        {{"method = \"sobol\"\ntrajectories = 4", params}, "trajectories"},
        {{"samples = 8", params}, "samples"},
        {{"method = \"sobol\"\nsamples = 2", params}, "samples"},
        {{"method = \"fast\"", params}, "morris or sobol"},
        {{"sampling = \"quasi-random\"", params}, "sampling"},
        {{"method = \"sobol\"\nsampling = \"halton\"", params}, "random or quasi-random"},
        {{"", "\"model.p\" = { low = 0, high = 1, scale = \"log\" }"}, "LOW > 0"},
        {{"", "\"model.p\" = { low = 1, high = 2, scale = \"ln\" }"}, "scale"},
        {{"", "\"model.p\" = { low = 1, high = 2.5, integer = true }"}, "whole numbers"},
        {{"", "\"model.p\" = { low = 1, high = 2, start = 1.5 }"}, "start"},
    };
    for (const auto& [text, expect] : bad) {
        INFO(text.first << "\n" << text.second);
        CHECK_THROWS_WITH(loadSensitivitySpec(write(text.first, text.second)), Catch::Contains("s.toml") && Catch::Contains(expect));
    }
    // The members' file writes an integer parameter as a TOML integer.
    const SobolDesign d = sobolDesign(3, 4, 1);
    const std::string ens = writeSobolEnsemble(s, d);
    const toml::table t = toml::parse_file(ens);
    const toml::array& members = *t["member"].as_array();
    CHECK(members.size() == 4 * 5 * 3);
    for (const auto& m : members) {
        const toml::table& mt = *m.as_table();
        CHECK(mt.get("biome.species.Toyon.max_age_years")->is_integer());
        const double p = mt.get("model.seeding_probability")->as_floating_point()->get();
        CHECK(p >= 1e-4);
        CHECK(p <= 1e-2);
    }
}

TEST_CASE("Height quantile output: from a snapshot, of all plants or one species", "[sensitivity]") {
    CHECK_THROWS_WITH(parseSimulationOutput("height_q0@3", "s.toml"), Catch::Contains("1 .. 99"));
    CHECK_THROWS_WITH(parseSimulationOutput("height_q100@3", "s.toml"), Catch::Contains("1 .. 99"));
    CHECK_THROWS_WITH(parseSimulationOutput("height_qx@3", "s.toml"), Catch::Contains("height_qNN"));
    const SimulationOutput q90 = parseSimulationOutput("height_q90@3", "t");
    CHECK(q90.quantile == Approx(0.9));
    CHECK(q90.units() == "m");
    CHECK(heightQuantile({}, 0.5) == 0);
    CHECK(heightQuantile({4, 1, 3, 2}, 0.5) == Approx(2.5));
    CHECK(heightQuantile({1, 2, 3, 4, 5}, 0.9) == Approx(4.6));

    test::TempDir dir("sensitivity_quantile");
    const Biome biome = defaultBiome();
    const int toyon = biome.speciesIndex("Toyon"), fern = biome.speciesIndex("Western Swordfern");
    // Year 3: Toyons of 1 .. 10 m, ferns of 0.1 m; year 1: nothing.
    std::vector<UndergrowthPlant> plants;
    for (int i = 1; i <= 10; ++i) {
        UndergrowthPlant p;
        p.id = static_cast<std::uint64_t>(i);
        p.speciesId = toyon;
        p.xM = i;
        p.yM = 1;
        p.heightM = i;
        p.crownRadiusM = 0.5;
        plants.push_back(p);
    }
    for (int i = 0; i < 10; ++i) {
        UndergrowthPlant p;
        p.id = static_cast<std::uint64_t>(100 + i);
        p.speciesId = fern;
        p.xM = i;
        p.yM = 5;
        p.heightM = 0.1;
        p.crownRadiusM = 0.1;
        plants.push_back(p);
    }
    const std::string path = dir.file("sim.h5");
    test::writeSnapshotSimulation(path, biome, 3, {{1, {}}, {3, plants}});
    CHECK(measureOutput(path, parseSimulationOutput("height_q50:Toyon@3", "t")) == Approx(5.5));
    CHECK(measureOutput(path, parseSimulationOutput("height_q90:Toyon@3", "t")) == Approx(9.1));
    CHECK(measureOutput(path, parseSimulationOutput("height_q50@3", "t")) == Approx(0.55));  // 10 ferns of 0.1 m and Toyons of 1 .. 10 m
    CHECK(measureOutput(path, parseSimulationOutput("height_q50@1", "t")) == 0);
    CHECK_THROWS_WITH(measureOutput(path, parseSimulationOutput("height_q50@2", "t")), Catch::Contains("no snapshot of year 2") && Catch::Contains("1, 3"));
}
