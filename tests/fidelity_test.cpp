// Tests of the fidelity protocol's measures (validate/fidelity.h) on patterns with known
// answers, and of `eco fidelity`'s error paths. No simulation runs here: every pattern is
// constructed (fixed seeds; each statistical bound below was checked on seeds 1-20 with the
// hidden case "[.seeds]" at the end and holds with room, see the comments).
#include <omp.h>

#include <catch2/catch.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "biome.h"
#include "fidelity.h"
#include "method_comparison.h"
#include "rng.h"
#include "test_util.h"

using namespace eco;

namespace {

const Biome& biome() {
    static const Biome b = defaultBiome();
    return b;
}

/// A 60 x 60 m plot on a 1 m grid that is one region everywhere, with the given canopy.
validate::FidelityContext plotContext(std::vector<Plant> canopy = {}) {
    validate::FidelityContext ctx;
    ctx.biome = &biome();
    ctx.canopy = std::move(canopy);
    ctx.regionMap = Grid<std::int32_t>(60, 60, 1.0, 0.0, 0.0, 0);
    ctx.nRegions = 1;
    ctx.regionNames = {"region 0"};
    return ctx;
}

validate::FidelityParams plotParams() {
    validate::FidelityParams p;
    p.window = RectWindow{0, 0, 60, 60};
    return p;
}

Plant plant(int species, double x, double y, double h = 0.5, double r = -1) {
    Plant p;
    p.speciesId = species;
    p.xM = x;
    p.yM = y;
    p.heightM = h;
    p.crownRadiusM = r >= 0 ? r : biome().species[static_cast<std::size_t>(species)].allometry.crownRadiusM(h);
    return p;
}

/// Uniform (binomial) pattern of n plants of `species` in [0, side]^2.
std::vector<Plant> uniformPattern(std::size_t n, double side, std::uint64_t seed, int species = 0) {
    RandomStream rng(seed, 11);
    std::vector<Plant> out;
    for (std::size_t i = 0; i < n; ++i) out.push_back(plant(species, rng.uniform(0, side), rng.uniform(0, side)));
    return out;
}

/// Thomas cluster process in [0, side]^2: Poisson-free (fixed counts) parents, `perCluster`
/// offspring each, Gaussian displacement sigma; offspring outside are dropped.
std::vector<Plant> thomasPattern(std::size_t parents, std::size_t perCluster, double sigmaM, double side,
                                 std::uint64_t seed, int species = 0) {
    RandomStream rng(seed, 22);
    std::vector<Plant> out;
    for (std::size_t c = 0; c < parents; ++c) {
        const double px = rng.uniform(0, side), py = rng.uniform(0, side);
        for (std::size_t k = 0; k < perCluster; ++k) {
            const double x = px + sigmaM * rng.normal(), y = py + sigmaM * rng.normal();
            if (x >= 0 && x <= side && y >= 0 && y <= side) out.push_back(plant(species, x, y));
        }
    }
    return out;
}

double figure(const validate::FidelityReport& r, const std::string& name, const std::string& scope, bool& scored, double& scene) {
    for (const auto& f : r.figures)
        if (f.figure == name && f.scope == scope) {
            scored = f.scored;
            scene = f.scene;
            return f.score;
        }
    FAIL("figure not found: " << name);
    return 0;
}

}  // namespace

TEST_CASE("fidelity: a pattern compared with itself is at distance 0 in every figure", "[fidelity]") {
    const std::vector<Plant> canopy = {plant(0, 20, 20, 30, 6), plant(0, 45, 40, 25, 4)};
    const validate::FidelityContext ctx = plotContext(canopy);
    std::vector<Plant> pattern = thomasPattern(60, 12, 1.0, 60, 3, 1);
    for (const Plant& p : uniformPattern(400, 60, 4, 2)) pattern.push_back(p);
    const validate::PatternSummary s = validate::summarisePattern("x", pattern, ctx, plotParams());
    REQUIRE(s.scopes[0].total() == static_cast<std::int64_t>(pattern.size()));
    const validate::FigureDistances d = validate::figureDistances(s, s, ctx);
    REQUIRE(d.overall.size() >= 12);
    for (const auto& [name, v] : d.overall) {
        INFO(name);
        if (std::isfinite(v)) CHECK(v == 0.0);
    }
    // The ones that must be defined here are.
    CHECK(std::isfinite(d.overall[0].second));  // pooled g
    CHECK(std::isfinite(d.overall[1].second));  // species pairs incl. canopy
}

TEST_CASE("fidelity: CSR scores near 1 and a replicate near 0 against a clustered reference", "[fidelity]") {
    // B and A: two realisations of one Thomas process (90 clusters of 25, sigma 0.8 m; g(0.5 m)
    // about 1 + 1 / (4 pi sigma^2 kappa) = 6); the CSR reference is made from B. A uniform
    // scene must score about 1 (0.99-1.02 over seeds 1-20, the hidden "[.seeds]" case), a
    // third Thomas realisation about 0 (-0.12-0.20); the uniform scene's L score >= 1.00.
    const validate::FidelityContext ctx = plotContext();
    const validate::FidelityParams params = plotParams();
    for (std::uint64_t seed : {1u, 7u}) {
        const auto B = thomasPattern(90, 25, 0.8, 60, 100 + seed);
        const auto A = thomasPattern(90, 25, 0.8, 60, 200 + seed);
        const auto thomasScene = thomasPattern(90, 25, 0.8, 60, 300 + seed);
        const auto uniformScene = uniformPattern(B.size(), 60, 400 + seed);
        bool scored = false;
        double d = 0;
        const validate::FidelityReport rU = validate::evaluateFidelity(uniformScene, A, B, ctx, params);
        const double sU = figure(rU, "g pooled undergrowth (RMS, regions)", "overall", scored, d);
        REQUIRE(scored);
        CHECK(sU > 0.85);
        CHECK(sU < 1.15);
        const double lU = figure(rU, "L(r) - r, plot rectangle (RMS, m)", "overall", scored, d);
        REQUIRE(scored);
        CHECK(lU > 0.85);
        const validate::FidelityReport rT = validate::evaluateFidelity(thomasScene, A, B, ctx, params);
        const double sT = figure(rT, "g pooled undergrowth (RMS, regions)", "overall", scored, d);
        REQUIRE(scored);
        CHECK(sT < 0.4);
        CHECK(sT > -0.35);
    }
}

TEST_CASE("fidelity: under-crown shares and heights against the crown of a constructed layout", "[fidelity]") {
    // One crown of radius 5 m, 20 m tall, at (30, 30).
    const validate::FidelityContext ctx = plotContext({plant(0, 30, 30, 20, 5)});
    std::vector<Plant> p = {plant(1, 30, 31), plant(1, 33, 33), plant(1, 26, 30, 25), plant(1, 10, 10),  // 3 of 4 under
                            plant(2, 50, 50), plant(2, 5, 55)};                                       // 0 of 2 under
    const validate::PatternSummary s = validate::summarisePattern("x", p, ctx, plotParams());
    const auto& sc = s.scopes[0];
    CHECK(sc.count[1] == 4);
    CHECK(sc.underCrown[1] == 3);
    CHECK(sc.count[2] == 2);
    CHECK(sc.underCrown[2] == 0);
    CHECK(sc.tallerThanCrown == 1);  // the 25 m plant under the 20 m crown
    // Against a layout with everything in the open: |0.75 - 0| weighted 4, |0 - 0| weighted 2.
    std::vector<Plant> open = {plant(1, 5, 5), plant(1, 6, 5), plant(1, 7, 5), plant(1, 8, 5), plant(2, 50, 50), plant(2, 5, 55)};
    const validate::PatternSummary o = validate::summarisePattern("open", open, ctx, plotParams());
    const validate::FigureDistances d = validate::figureDistances(s, o, ctx);
    CHECK(d.overall[6].first.rfind("under-crown share", 0) == 0);
    CHECK(d.overall[6].second == Approx(0.75 * 4.0 / 6.0));
}

TEST_CASE("fidelity: crown radius over allometric radius of a constructed layout", "[fidelity]") {
    const validate::FidelityContext ctx = plotContext();
    const Allometry& al = biome().species[1].allometry;
    std::vector<Plant> p;
    const double ratios[] = {1.0, 0.2, 0.8, 0.4, 0.6};
    for (int i = 0; i < 5; ++i) p.push_back(plant(1, 10 + 5 * i, 20, 1.0 + 0.2 * i, ratios[i] * al.crownRadiusM(1.0 + 0.2 * i)));
    const validate::PatternSummary s = validate::summarisePattern("x", p, ctx, plotParams());
    const auto& v = s.scopes[0].radiusRatio[1];
    REQUIRE(v.size() == 5);
    CHECK(validate::sortedQuantile(v, 0.5) == Approx(0.6));
    CHECK(validate::sortedQuantile(v, 0.05) == Approx(0.24));  // 0.2 + 0.2 x (0.4 - 0.2)
    // Exact allometry gives exactly 1.
    std::vector<Plant> q;
    for (int i = 0; i < 5; ++i) q.push_back(plant(1, 10 + 5 * i, 30, 1.0 + 0.3 * i));
    const validate::PatternSummary t = validate::summarisePattern("y", q, ctx, plotParams());
    CHECK(validate::sortedQuantile(t.scopes[0].radiusRatio[1], 0.5) == Approx(1.0));
    CHECK(validate::sortedQuantile(t.scopes[0].radiusRatio[1], 0.05) == Approx(1.0));
}

TEST_CASE("fidelity: L(r) - r of CSR is near 0", "[fidelity]") {
    // 2500 uniform points in 60 x 60 m: the RMS of L(r) - r over 0.25..10 m stays below
    // 0.1 m (at most 0.042 m over seeds 1-20, the mean at most 0.033 m; "[.seeds]"); a
    // Thomas pattern is far above it.
    const validate::FidelityContext ctx = plotContext();
    for (std::uint64_t seed : {1u, 2u, 3u}) {
        const validate::PatternSummary s = validate::summarisePattern("csr", uniformPattern(2500, 60, seed), ctx, plotParams());
        const std::vector<double> zero(s.lMinusR.size(), 0.0);
        CHECK(validate::rmsDifference(s.lMinusR, zero) < 0.1);
        CHECK(std::abs(s.ripleyIndex) < 0.1);
    }
    const validate::PatternSummary t = validate::summarisePattern("thomas", thomasPattern(90, 25, 0.8, 60, 5), ctx, plotParams());
    CHECK(t.ripleyIndex > 0.5);
}

TEST_CASE("fidelity: light classes around one crown", "[fidelity]") {
    // A crown of radius 10 m at the plot's centre: deep = disc of 8 m, edge = ring 8..12 m,
    // clearing = the rest (areas on a 0.2 m raster, within 1 %; the band's width is right
    // to about 0.02 m).
    const validate::FidelityContext ctx = plotContext({plant(0, 30, 30, 30, 10)});
    const validate::PatternSummary s = validate::summarisePattern("x", {}, ctx, plotParams());
    const auto& sc = s.scopes[0];
    CHECK(sc.classAreaM2[0] == Approx(M_PI * 64).epsilon(0.01));
    CHECK(sc.classAreaM2[1] == Approx(M_PI * (144 - 64)).epsilon(0.01));
    CHECK(sc.classAreaM2[2] == Approx(3600 - M_PI * 144).epsilon(0.01));
    // Plants: 2 in deep shade, 1 at the edge, 1 in the clearing.
    const validate::PatternSummary p = validate::summarisePattern("x", {plant(1, 30, 30), plant(1, 33, 30), plant(1, 40.5, 30), plant(1, 55, 55)},
                                                                  ctx, plotParams());
    CHECK(p.scopes[0].classCount[0] == 2);
    CHECK(p.scopes[0].classCount[1] == 1);
    CHECK(p.scopes[0].classCount[2] == 1);
}

TEST_CASE("fidelity: the CSR pattern keeps counts and sizes, stays on region cells and off trunks", "[fidelity]") {
    validate::FidelityContext ctx = plotContext({plant(0, 30, 30, 30, 10)});
    for (int iy = 0; iy < 60; ++iy)
        for (int ix = 0; ix < 20; ++ix) ctx.regionMap(ix, iy) = -1;  // the western third: no undergrowth
    validate::FidelityParams params = plotParams();
    params.trunkExclusionFactor = 0.3;  // a 3 m disc around the trunk
    std::vector<Plant> ref = thomasPattern(40, 20, 1.0, 60, 9, 1);
    std::size_t inRegion = 0;
    for (const Plant& p : ref) inRegion += p.xM >= 20;
    const std::vector<Plant> csr = validate::csrPattern(ref, ctx, params);
    CHECK(csr.size() == inRegion);
    for (const Plant& p : csr) {
        CHECK(p.xM >= 20);
        CHECK(std::hypot(p.xM - 30, p.yM - 30) >= 3.0);
    }
    CHECK(validate::csrPattern(ref, ctx, params)[5].xM == csr[5].xM);  // a pure function of its seed
}

TEST_CASE("fidelity: score and guard, PCT.DEV", "[fidelity]") {
    bool scored = false;
    CHECK(validate::fidelityScore(0.3, 0.1, 0.5, 0.05, scored) == Approx(0.5));
    CHECK(scored);
    CHECK(std::isnan(validate::fidelityScore(0.3, 0.1, 0.1, 0.05, scored)));
    CHECK_FALSE(scored);
    CHECK(std::isnan(validate::fidelityScore(0.3, 0.5, 0.1, 0.05, scored)));  // CSR closer than the replicate
    CHECK_FALSE(scored);
    CHECK(std::isnan(validate::fidelityScore(0.3, 0.0, 1e-12, 0.05, scored)));
    CHECK_FALSE(scored);
    CHECK(validate::pctDev(105, 100) == Approx(5.0));
    CHECK(validate::pctDev(-0.9, -1.0) == Approx(10.0));
    CHECK(std::isnan(validate::pctDev(1, 0)));
}

TEST_CASE("fidelity: identical report for 1 and 2 threads", "[fidelity]") {
    const validate::FidelityContext ctx = plotContext({plant(0, 20, 20, 30, 6)});
    const auto B = thomasPattern(60, 20, 1.0, 60, 1, 1);
    const auto A = thomasPattern(60, 20, 1.0, 60, 2, 1);
    const auto S = uniformPattern(B.size(), 60, 3, 1);
    test::TempDir dir("fidelity_threads");
    omp_set_num_threads(1);
    validate::writeFidelityCsv(dir.file("one.csv"), validate::evaluateFidelity(S, A, B, ctx, plotParams()));
    omp_set_num_threads(2);
    validate::writeFidelityCsv(dir.file("two.csv"), validate::evaluateFidelity(S, A, B, ctx, plotParams()));
    std::ifstream a(dir.file("one.csv")), b(dir.file("two.csv"));
    const std::string ta((std::istreambuf_iterator<char>(a)), {}), tb((std::istreambuf_iterator<char>(b)), {});
    CHECK(!ta.empty());
    CHECK(ta == tb);
}


// Hidden (run with "[.seeds]"): the ranges the statistical bounds above were set from,
// printed for seeds 1-20.
TEST_CASE("fidelity: score ranges over seeds 1-20", "[.seeds]") {
    const validate::FidelityContext ctx = plotContext();
    const validate::FidelityParams params = plotParams();
    double uMin = 1e9, uMax = -1e9, tMin = 1e9, tMax = -1e9, lMin = 1e9, csrLMax = 0, csrIdxMax = 0;
    for (std::uint64_t seed = 1; seed <= 20; ++seed) {
        const auto B = thomasPattern(90, 25, 0.8, 60, 100 + seed);
        const auto A = thomasPattern(90, 25, 0.8, 60, 200 + seed);
        bool scored = false;
        double d = 0;
        const double u = figure(validate::evaluateFidelity(uniformPattern(B.size(), 60, 400 + seed), A, B, ctx, params),
                                "g pooled undergrowth (RMS, regions)", "overall", scored, d);
        const validate::FidelityReport rU = validate::evaluateFidelity(uniformPattern(B.size(), 60, 400 + seed), A, B, ctx, params);
        const double l = figure(rU, "L(r) - r, plot rectangle (RMS, m)", "overall", scored, d);
        const double t = figure(validate::evaluateFidelity(thomasPattern(90, 25, 0.8, 60, 300 + seed), A, B, ctx, params),
                                "g pooled undergrowth (RMS, regions)", "overall", scored, d);
        uMin = std::min(uMin, u);
        uMax = std::max(uMax, u);
        tMin = std::min(tMin, t);
        tMax = std::max(tMax, t);
        lMin = std::min(lMin, l);
        const validate::PatternSummary s = validate::summarisePattern("csr", uniformPattern(2500, 60, seed), ctx, params);
        csrLMax = std::max(csrLMax, validate::rmsDifference(s.lMinusR, std::vector<double>(s.lMinusR.size(), 0.0)));
        csrIdxMax = std::max(csrIdxMax, std::abs(s.ripleyIndex));
    }
    WARN("uniform scene score " << uMin << " .. " << uMax << "; Thomas scene score " << tMin << " .. " << tMax
                                << "; uniform L score min " << lMin << "; CSR RMS(L - r) max " << csrLMax
                                << " m, |index| max " << csrIdxMax << " m");
}


TEST_CASE("fidelity methods: the list of methods, and the comparison marks the closest scene", "[fidelity][methods]") {
    CHECK(validate::parseMethodList("all") == std::vector<std::string>{"structured", "darts", "deussen", "xu2015"});
    CHECK(validate::parseMethodList("darts,xu2015") == std::vector<std::string>{"darts", "xu2015"});
    CHECK(validate::parseMethodList("deussen") == std::vector<std::string>{"deussen"});
    for (const char* bad : {"structured,structured", "bogus", "", "darts,", ",darts", "darts,,deussen"}) {
        INFO(bad);
        CHECK_THROWS_AS(validate::parseMethodList(bad), ValidationError);
    }

    // A clustered held-out pattern B, its replicate A; one scene clustered as they are, one
    // without structure: the clustered scene is the closer in pooled g and the marked one.
    const validate::FidelityContext ctx = plotContext();
    const auto B = thomasPattern(60, 20, 1.0, 60, 1, 1);
    const auto A = thomasPattern(60, 20, 1.0, 60, 2, 1);
    const auto clustered = thomasPattern(60, 20, 1.0, 60, 3, 1);
    const auto uniform = uniformPattern(B.size(), 60, 4, 1);
    validate::MethodComparison c;
    c.exemplarWindow = validate::xuExemplarWindow(plotParams().window);
    CHECK(c.exemplarWindow.x0 == Approx(20));
    CHECK(c.exemplarWindow.x1 == Approx(40));
    const RectWindow sceneWindow{0, 0, 60, 60};
    // Xu's evaluation needs many clusters in the 20 m exemplar square: denser, smaller clusters.
    const auto exemplar = thomasPattern(240, 10, 0.7, 60, 5, 1);
    const auto xuScene = [](const std::string& name) {
        return name == "clustered" ? thomasPattern(240, 10, 0.7, 60, 6, 1) : uniformPattern(2400, 60, 7, 1);
    };
    for (const auto& [name, scene] : {std::pair{std::string("uniform"), uniform}, std::pair{std::string("clustered"), clustered}}) {
        validate::MethodResult m;
        m.method = name;
        m.fidelity = validate::evaluateFidelity(scene, A, B, ctx, plotParams());
        m.xu = validate::evaluateXuEnlargements(exemplar, c.exemplarWindow, xuScene(name), sceneWindow, plotParams().bins, 1,
                                                m.xuFactorsSkipped);
        m.scenePlants = static_cast<std::int64_t>(scene.size());
        m.samplingSeconds = 0.5;
        c.methods.push_back(m);
    }
    // 3 x 3 exemplars (60 m) fit in the scene, 6 x 6 and 10 x 10 do not.
    for (const auto& m : c.methods) {
        CHECK(m.xuFactorsSkipped == std::vector<int>{6, 10});
        REQUIRE(m.xu.enlargements.size() == 1);
        CHECK(m.xu.enlargements[0].factor == 3);
    }
    // The clustered scene keeps the exemplar's aggregation; the uniform one loses it.
    INFO("Ripley index: exemplar " << c.methods[0].xu.exemplar.ripleyIndexM << ", uniform "
                                   << c.methods[0].xu.enlargements[0].mean.ripleyIndexM << ", clustered "
                                   << c.methods[1].xu.enlargements[0].mean.ripleyIndexM);
    CHECK(c.methods[0].xu.exemplar.ripleyIndexM > 0.2);
    // (37 % against 101 %: the small exemplar square reads a higher index than the patches.)
    CHECK(c.methods[1].xu.enlargements[0].pctDevRipley < 0.5 * c.methods[0].xu.enlargements[0].pctDevRipley);
    CHECK(c.methods[0].xu.enlargements[0].pctDevRipley > 80);
    const std::string md = validate::methodComparisonMarkdown(c, "## test");
    const auto rowOf = [&](const std::string& figure) {
        const auto at = md.find("| " + figure + " |");
        REQUIRE(at != std::string::npos);
        std::vector<std::string> cells;
        std::string cell;
        for (std::size_t i = at + 1; i < md.size() && md[i] != '\n'; ++i) {
            if (md[i] == '|' && md[i - 1] != '\\') {
                cells.push_back(cell);
                cell.clear();
            } else {
                cell += md[i];
            }
        }
        return cells;  // figure, replicate, CSR, uniform, clustered
    };
    const auto g = rowOf("g pooled undergrowth, plot rectangle (RMS)");
    REQUIRE(g.size() == 5);
    CHECK(g[4].find("**") != std::string::npos);
    CHECK(g[3].find("**") == std::string::npos);
    // A figure with '|' in its name stays one cell.
    CHECK(rowOf("under-crown share (\\|difference\\|, weighted by species)").size() == 5);
    CHECK(md.find("| clustered | 3 |") != std::string::npos);
    CHECK(md.find("| uniform | 6 | patch larger than the scene |") != std::string::npos);
    // Speed: 0.5 s for the scene's plants, per million.
    const double perMillion = 0.5 / (static_cast<double>(clustered.size()) * 1e-6);
    char expected[96];
    std::snprintf(expected, sizeof expected, "| clustered | %zu | 0.500 | %.2f |", clustered.size(), perMillion);
    CHECK(md.find(expected) != std::string::npos);
}
