// Biome parsing and strict validation (core/biome.h).
#include <catch2/catch.hpp>

#include <cmath>
#include <fstream>
#include <set>
#include <sstream>

#include "biome.h"
#include "error.h"
#include "text_format.h"
#include "param_table_check.h"
#include "test_util.h"

using namespace eco;

namespace {

std::string sonomaText() {
    std::ifstream in(test::sourcePath("biomes/sonoma.toml"));
    std::ostringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

/// Replace the first occurrence of `from` after the line `anchor` (a species name line).
std::string mutate(const std::string& text, const std::string& anchor, const std::string& from,
                   const std::string& to) {
    const auto a = text.find(anchor);
    REQUIRE(a != std::string::npos);
    const auto p = text.find(from, a);
    REQUIRE(p != std::string::npos);
    return text.substr(0, p) + to + text.substr(p + from.size());
}

/// Parse and return the ValidationError message (fails the test if parsing succeeds).
std::string errorOf(const std::string& text) {
    try {
        parseBiome(text, "mutated.toml");
    } catch (const ValidationError& e) {
        return e.what();
    } catch (const IoError& e) {
        return e.what();
    }
    FAIL("expected a validation error");
    return {};
}

}  // namespace

TEST_CASE("the Sonoma biome has every species of Table 3", "[biome]") {
    const Biome b = loadBiome(test::sourcePath("biomes/sonoma.toml"));
    REQUIRE(b.species.size() == 16);
    REQUIRE(b.subBiomes.size() == 4);
    const Species& redwood = b.species[static_cast<std::size_t>(b.speciesIndex("Redwood"))];
    CHECK(redwood.maxAgeYears == 800);
    CHECK(redwood.maxHeightM == 110);
    CHECK(redwood.alpha == Approx(0.45));
    CHECK(redwood.response(Factor::Sun).c == 9.5);
    CHECK(redwood.response(Factor::Sun).r == 11);
    CHECK(redwood.canopy);
    CHECK(redwood.growthMonths == std::vector<int>{11, 0, 1, 2, 3, 4});
    const Species& laurel = b.species[static_cast<std::size_t>(b.speciesIndex("California Laurel"))];
    CHECK(laurel.growthMonths.size() == 9);
    CHECK(laurel.subBiomes == std::vector<int>{1, 2, 4});
    CHECK_FALSE(laurel.canopy);
    // Allometry D at 30 m: exp(-0.72 + 0.65 ln 30).
    CHECK(b.species[static_cast<std::size_t>(b.speciesIndex("Douglas-Fir"))].allometry.crownRadiusM(30.0) ==
          Approx(std::exp(-0.72 + 0.65 * std::log(30.0))));
    // Allometry E is linear: r = 4 h.
    CHECK(b.species[0].allometry.crownRadiusM(0.25) == Approx(1.0));
    CHECK(b.climate.latitudeDeg == Approx(38.58));
    CHECK(b.climate.rainfallMm[0] == Approx(201.3));
    CHECK(b.climate.temperatureC[6] == Approx(32.1));
    CHECK(b.soil.saturationMm == 180);
    CHECK(b.vigour.a == Approx(0.2));
    int canopyCount = 0;
    for (const auto& s : b.species) canopyCount += s.canopy;
    CHECK(canopyCount == 7);
}

TEST_CASE("the embedded default equals biomes/sonoma.toml and survives a TOML round trip", "[biome]") {
    const Biome file = loadBiome(test::sourcePath("biomes/sonoma.toml"));
    const Biome embedded = defaultBiome();
    const Biome again = parseBiome(biomeToToml(embedded), "roundtrip.toml");
    for (const Biome* b : {&embedded, &again}) {
        REQUIRE(b->species.size() == file.species.size());
        for (std::size_t i = 0; i < file.species.size(); ++i) {
            const Species &x = file.species[i], &y = b->species[i];
            CHECK(x.name == y.name);
            CHECK(x.maxAgeYears == y.maxAgeYears);
            CHECK(x.maxHeightM == y.maxHeightM);
            CHECK(x.alpha == y.alpha);
            CHECK(x.response(Factor::Sun).c == y.response(Factor::Sun).c);
            CHECK(x.response(Factor::Moisture).r == y.response(Factor::Moisture).r);
            CHECK(x.response(Factor::Temperature).c == y.response(Factor::Temperature).c);
            CHECK(x.response(Factor::Slope).r == y.response(Factor::Slope).r);
            CHECK(x.growthMonths == y.growthMonths);
            CHECK(x.subBiomes == y.subBiomes);
            CHECK(x.allometry.crownRadiusM(10) == y.allometry.crownRadiusM(10));
            CHECK(x.canopy == y.canopy);
        }
        CHECK(b->climate.skyClarity == file.climate.skyClarity);
        CHECK(b->soil.runoffLimitMm == file.soil.runoffLimitMm);
    }
}

TEST_CASE("vigour shape g(d) of Eq. 1", "[biome]") {
    const VigourShape g;  // a = 0.2, q = 0.01, p = 4.5
    CHECK(g.g(0.0, 7.0) == Approx(1.0));
    CHECK(g.g(7.0, 7.0) == Approx(1.2 * 0.01 - 0.2));
    CHECK(g.g(-7.0, 7.0) == Approx(g.g(7.0, 7.0)));
    CHECK(g.g(100.0, 7.0) == Approx(-0.2));
    const Biome b = defaultBiome();
    const int sorrel = b.speciesIndex("Redwood Sorrel");
    // At every optimum the vigour is alpha.
    CHECK(b.vigourOf(sorrel, {3.5, 100, 13.5, 30}) == Approx(0.60));
    // The limiting factor wins (minimum).
    CHECK(b.vigourOf(sorrel, {3.5 + 7, 100, 13.5, 30}) == Approx(0.60 * (1.2 * 0.01 - 0.2)));
}

TEST_CASE("biome validation names the file, the species and the field", "[biome]") {
    const std::string base = sonomaText();
    struct Case {
        std::string what, anchor, from, to, expectField, expectWords;
    };
    const std::vector<Case> cases = {
        {"alpha above 1", "name = \"Toyon\"", "alpha = 0.68", "alpha = 1.4", "alpha", "must lie in [0, 1]"},
        {"negative alpha", "name = \"Toyon\"", "alpha = 0.68", "alpha = -0.1", "alpha", "must lie in [0, 1]"},
        {"zero max age", "name = \"Toyon\"", "max_age_years = 150", "max_age_years = 0", "max_age_years", "must lie in (0, 10000]"},
        {"negative max height", "name = \"Toyon\"", "max_height_m = 9.0", "max_height_m = -9.0", "max_height_m", "must lie in (0, 200]"},
        {"max height of 1e300", "name = \"Toyon\"", "max_height_m = 9.0", "max_height_m = 1e300", "max_height_m", "must lie in (0, 200]"},
        {"max age of 1e300", "name = \"Toyon\"", "max_age_years = 150", "max_age_years = 1e300", "max_age_years", "value 1e+300 must lie in (0, 10000]"},
        {"zero range r", "name = \"Toyon\"", "sun = { c = 9.5, r = 11 }", "sun = { c = 9.5, r = 0 }", "'r'", "positive"},
        {"unknown key", "name = \"Toyon\"", "canopy = false", "canopy = false\ncanopy_height = 3", "canopy_height", "unknown key"},
        {"missing field", "name = \"Toyon\"", "alpha = 0.68\n", "", "alpha", "missing"},
        {"sub-biome that does not exist", "name = \"Toyon\"", "sub_biomes = [1, 2, 3]", "sub_biomes = [1, 2, 7]", "sub_biomes", "does not exist"},
        {"alpha as a string", "name = \"Toyon\"", "alpha = 0.68", "alpha = \"high\"", "alpha", "expected a number"},
        {"unknown growth period", "name = \"Toyon\"", "growth_period = \"S\"", "growth_period = \"X\"", "growth_period", "unknown growth period"},
        {"unknown allometry", "name = \"Toyon\"", "allometry = \"A\"", "allometry = \"Q\"", "allometry", "unknown allometry"},
    };
    for (const auto& c : cases) {
        SECTION(c.what) {
            const std::string msg = errorOf(mutate(base, c.anchor, c.from, c.to));
            INFO(msg);
            CHECK_THAT(msg, Catch::Contains("mutated.toml"));
            CHECK_THAT(msg, Catch::Contains("species 'Toyon'"));
            CHECK_THAT(msg, Catch::Contains(c.expectField));
            CHECK_THAT(msg, Catch::Contains(c.expectWords));
        }
    }
}

TEST_CASE("one description of the species keys drives reading, printing, messages and the docs table", "[biome]") {
    std::ifstream in(test::sourcePath("docs/biome.md"));
    REQUIRE(in);
    std::stringstream docs;
    docs << in.rdbuf();
    const std::string base = sonomaText();
    const Biome sonoma = parseBiome(base, "sonoma.toml");
    const Species& toyon = sonoma.species[static_cast<std::size_t>(sonoma.speciesIndex("Toyon"))];
    const Biome again = parseBiome(biomeToToml(sonoma), "roundtrip.toml");
    const Species& toyonAgain = again.species[static_cast<std::size_t>(again.speciesIndex("Toyon"))];
    std::set<std::string> keys;
    for (const SpeciesField& f : speciesFields()) {
        INFO(f.key);
        CHECK(keys.insert(f.key).second);
        CHECK(docs.str().find(speciesDocRow(f)) != std::string::npos);
        if (f.kind == SpeciesField::Kind::EcoMod) {
            // Optional: Sonoma gives none (printed without it); given, read, printed only with
            // the keys given, and a bad value refused naming the file, species, key and value.
            CHECK(std::isnan(toyon.ecomod.maturityAgeYears));
            CHECK(biomeToToml(sonoma).find("ecomod") == std::string::npos);
            const auto nameLine = base.find("name = \"Toyon\"");
            const auto eol = base.find('\n', nameLine);
            auto with = [&](const std::string& value) {
                return base.substr(0, eol) + "\necomod = " + value + base.substr(eol);
            };
            const Biome given = parseBiome(with("{ maturity_age_years = 12.0, persistence = 0.25 }"), "given.toml");
            const Species& t = given.species[static_cast<std::size_t>(given.speciesIndex("Toyon"))];
            CHECK(t.ecomod.maturityAgeYears == 12.0);
            CHECK(t.ecomod.persistence == 0.25);
            CHECK(std::isnan(t.ecomod.fullGrownAgeYears));
            const Biome back = parseBiome(biomeToToml(given), "roundtrip.toml");
            CHECK(back.species[static_cast<std::size_t>(t.id)].ecomod.persistence == 0.25);
            CHECK(std::isnan(back.species[static_cast<std::size_t>(t.id)].ecomod.maxAgeYears));
            CHECK(std::isnan(back.species[0].ecomod.persistence));
            CHECK_THROWS_WITH(parseBiome(with("{ persistence = 1.5 }"), "mutated.toml"),
                              Catch::Contains("mutated.toml") && Catch::Contains("species 'Toyon'") &&
                                  Catch::Contains("persistence") && Catch::Contains("1.5"));
            CHECK_THROWS_WITH(parseBiome(with("{ persistance = 0.5 }"), "mutated.toml"),
                              Catch::Contains("mutated.toml") && Catch::Contains("persistance"));
            continue;
        }
        if (f.kind == SpeciesField::Kind::Response && !kFactors[factorIndex(f.factor)].responseRequired) {
            // An optional response (wind): Sonoma gives none, so the species is indifferent
            // and the printed biome has no such key; given, it is read, printed and checked.
            CHECK(toyon.response(f.factor).isIndifferent());
            CHECK(biomeToToml(sonoma).find("\n" + f.key + " = ") == std::string::npos);
            const auto nameLine = base.find("name = \"Toyon\"");
            const auto eol = base.find('\n', nameLine);
            auto with = [&](const std::string& value) {
                return base.substr(0, eol) + "\n" + f.key + " = " + value + base.substr(eol);
            };
            const Biome given = parseBiome(with("{ c = 3.5, r = 4 }"), "given.toml");
            const Species& t = given.species[static_cast<std::size_t>(given.speciesIndex("Toyon"))];
            CHECK(t.response(f.factor).c == 3.5);
            CHECK(t.response(f.factor).r == 4);
            const Biome back = parseBiome(biomeToToml(given), "roundtrip.toml");
            CHECK(back.species[static_cast<std::size_t>(t.id)].response(f.factor).r == 4);
            CHECK(back.species[0].response(f.factor).isIndifferent());
            CHECK_THROWS_WITH(parseBiome(with("{ c = 3.5, r = -1 }"), "mutated.toml"),
                              Catch::Contains("mutated.toml") && Catch::Contains("species 'Toyon'") &&
                                  Catch::Contains(f.key));
            continue;
        }
        if (f.kind == SpeciesField::Kind::OptionalReal) {
            // An optional number (fire_tolerance): Sonoma gives none (NaN, not printed); given,
            // it is read, printed back and checked against its range.
            CHECK(std::isnan(toyon.*(f.real)));
            CHECK(biomeToToml(sonoma).find("\n" + f.key + " = ") == std::string::npos);
            const auto eol = base.find('\n', base.find("name = \"Toyon\""));
            auto with = [&](const std::string& value) { return base.substr(0, eol) + "\n" + f.key + " = " + value + base.substr(eol); };
            const Biome given = parseBiome(with("0.25"), "given.toml");
            const Species& t = given.species[static_cast<std::size_t>(given.speciesIndex("Toyon"))];
            CHECK(t.*(f.real) == 0.25);
            const Biome back = parseBiome(biomeToToml(given), "roundtrip.toml");
            CHECK(back.species[static_cast<std::size_t>(t.id)].*(f.real) == 0.25);
            CHECK(std::isnan(back.species[0].*(f.real)));
            CHECK_THROWS_WITH(parseBiome(with("1.5"), "mutated.toml"),
                              Catch::Contains("mutated.toml") && Catch::Contains(f.key));
            continue;
        }
        // Every other key is required: without it the species is refused, naming the key.
        const auto at = base.find("\n" + f.key + " = ", base.find("name = \"Toyon\"") - 1);
        REQUIRE(at != std::string::npos);
        const auto eol = base.find('\n', at + 1);
        const std::string without = base.substr(0, at) + base.substr(eol);
        CHECK_THROWS_WITH(parseBiome(without, "mutated.toml"),
                          Catch::Contains("mutated.toml") && Catch::Contains("field '" + f.key + "': missing"));
        if (f.kind != SpeciesField::Kind::Real) continue;
        // Printed and read back unchanged; a value outside the range is refused with the rule.
        CHECK(toyonAgain.*(f.real) == toyon.*(f.real));
        const double outside = f.range.highBound != ParamRange::Bound::None ? f.range.hi + 1 : f.range.lo - 1;
        const std::string bad = base.substr(0, at) + "\n" + f.key + " = " + formatNumber(outside, 17) + base.substr(eol);
        CHECK_THROWS_WITH(parseBiome(bad, "mutated.toml"),
                          Catch::Contains("mutated.toml:") && Catch::Contains("species 'Toyon'") &&
                              Catch::Contains("field '" + f.key + "'") && Catch::Contains(f.ruleText()));
    }
}

TEST_CASE("biome validation of months, climate and structure", "[biome]") {
    const std::string base = sonomaText();
    SECTION("a month outside 0-11") {
        const std::string msg = errorOf(mutate(base, "[growth_periods]", "S = [11, 0", "S = [12, 0"));
        CHECK_THAT(msg, Catch::Contains("growth_periods") && Catch::Contains("S") && Catch::Contains("outside 0-11"));
    }
    SECTION("negative rainfall") {
        const std::string msg = errorOf(mutate(base, "rainfall_mm", "201.3", "-1"));
        CHECK_THAT(msg, Catch::Contains("rainfall_mm") && Catch::Contains("negative"));
    }
    SECTION("eleven months of temperature") {
        const std::string msg = errorOf(mutate(base, "temperature_c", "13.5, ", ""));
        CHECK_THAT(msg, Catch::Contains("temperature_c") && Catch::Contains("expected 12 values"));
    }
    SECTION("a canopy species that is not canopy-capable") {
        const std::string msg = errorOf(mutate(base, "name = \"Redwood\"\n", "canopy = true", "canopy = false"));
        CHECK_THAT(msg, Catch::Contains("sub_biome 1") && Catch::Contains("Redwood"));
    }
    SECTION("unknown top-level table") {
        const std::string msg = errorOf(base + "\n[weather]\nwind = 3\n");
        CHECK_THAT(msg, Catch::Contains("weather") && Catch::Contains("unknown key"));
    }
    SECTION("invalid TOML names the line") {
        const std::string msg = errorOf("[biome]\nname = \"x\"\nalpha = = 3\n");
        CHECK_THAT(msg, Catch::Contains("mutated.toml:3") && Catch::Contains("invalid TOML"));
    }
    SECTION("a missing file") {
        CHECK_THROWS_WITH(loadBiome("/nonexistent/biome.toml"), Catch::Contains("/nonexistent/biome.toml"));
    }
    SECTION("unknown species name lists the known ones") {
        CHECK_THROWS_WITH(defaultBiome().speciesIndex("Oak"), Catch::Contains("unknown species 'Oak'") && Catch::Contains("Redwood"));
    }
}

TEST_CASE("the biome's [climate], [soil] and [vigour] keys: one table drives reading, writing, ranges and docs", "[biome]") {
    // Validation through the real path: the default biome with the struct set, printed as
    // TOML and parsed back; a value out of range must be refused naming the key and rule.
    auto roundTrip = [](auto set) {
        eco::Biome b = eco::defaultBiome();
        set(b);
        return eco::parseBiome(eco::biomeToToml(b), "b.toml");
    };
    auto none = [](const auto&) { return std::vector<std::pair<std::string, std::string>>{}; };
    eco::test::checkParamTable(
        eco::climateFields(), "docs/biome.md",
        [&](const eco::Climate& c) { roundTrip([&](eco::Biome& b) { b.climate = c; }); }, none, 0);
    eco::test::checkParamTable(
        eco::soilFields(), "docs/biome.md", [&](const eco::Soil& s) { roundTrip([&](eco::Biome& b) { b.soil = s; }); },
        none, 0);
    eco::test::checkParamTable(
        eco::vigourFields(), "docs/biome.md",
        [&](const eco::VigourShape& v) { roundTrip([&](eco::Biome& b) { b.vigour = v; }); }, none, 0);
    eco::test::checkParamTable(
        eco::windFields(), "docs/biome.md",
        [&](const eco::Wind& w) {
            roundTrip([&](eco::Biome& b) {
                b.wind = w;
                b.windGiven = true;
            });
        },
        none, 0);
    // [wind] is optional: without it the defaults and no table in the record; with it, read
    // and printed back.
    {
        const eco::Biome sonoma = eco::defaultBiome();
        CHECK_FALSE(sonoma.windGiven);
        CHECK(sonoma.wind.samples == eco::Wind{}.samples);
        CHECK(eco::biomeToToml(sonoma).find("[wind]") == std::string::npos);
        const eco::Biome windy = eco::parseBiome(
            sonomaText() + "\n[wind]\ndirection_deg = 180\nstrength_m_s = 7.5\nsamples = 12\n", "windy.toml");
        CHECK(windy.windGiven);
        CHECK(windy.wind.directionDeg == 180);
        CHECK(windy.wind.strengthMS == 7.5);
        CHECK(windy.wind.samples == 12);
        CHECK(windy.wind.thresholdDeg == eco::Wind{}.thresholdDeg);
        const eco::Biome back = eco::parseBiome(eco::biomeToToml(windy), "b.toml");
        CHECK(back.windGiven);
        CHECK(back.wind.samples == 12);
        CHECK(back.wind.strengthMS == 7.5);
        CHECK_THROWS_WITH(eco::parseBiome(sonomaText() + "\n[wind]\nthreshold_deg = 0\n", "w.toml"),
                          Catch::Contains("w.toml") && Catch::Contains("threshold_deg"));
        CHECK_THROWS_WITH(eco::parseBiome(sonomaText() + "\n[wind]\ngust = 3\n", "w.toml"),
                          Catch::Contains("gust") && Catch::Contains("unknown key"));
    }
    // The defaults of the structs are the Sonoma biome's, and a round trip keeps every value.
    const eco::Biome sonoma = eco::defaultBiome();
    for (const auto& f : eco::soilFields()) CHECK(sonoma.soil.*(f.real) == eco::Soil{}.*(f.real));
    for (const auto& f : eco::vigourFields()) CHECK(sonoma.vigour.*(f.real) == eco::VigourShape{}.*(f.real));
    const eco::Biome back = eco::parseBiome(eco::biomeToToml(sonoma), "b.toml");
    CHECK(eco::biomeToToml(back) == eco::biomeToToml(sonoma));
    // The cross-key rule stays.
    CHECK_THROWS_WITH(roundTrip([](eco::Biome& b) { b.soil.slopeMaxDeg = b.soil.slopeThresholdDeg; }),
                      Catch::Contains("'slope_max_deg'") && Catch::Contains("must exceed slope_threshold_deg"));
}

// The calibrated biomes of docs/calibration.md (configs/calibrated/) are Table 3 with a few
// fitted values: each must still load, and differ from biomes/sonoma.toml in exactly the
// fields its header and the docs name (a drifted or hand-edited file fails here).
TEST_CASE("the calibrated Sonoma biomes differ from Table 3 only in their fitted fields", "[biome]") {
    const Biome table3 = loadBiome(test::sourcePath("biomes/sonoma.toml"));
    struct Expected {
        const char* file;
        std::set<std::string> changed;  // "species/field"
    };
    const Expected cases[] = {
        {"configs/calibrated/laurel-150-biome.toml", {"California Laurel/alpha", "Toyon/alpha"}},
        {"configs/calibrated/laurel-150-converged-biome.toml", {"California Laurel/alpha", "Toyon/alpha"}},
        {"configs/calibrated/laurel-fig15-biome.toml",
         {"California Laurel/alpha", "California Laurel/max_age_years", "California Laurel/max_height_m",
          "California Laurel/sun.c", "Toyon/alpha"}},
    };
    for (const Expected& e : cases) {
        INFO(e.file);
        const Biome b = loadBiome(test::sourcePath(e.file));
        REQUIRE(b.species.size() == table3.species.size());
        std::set<std::string> changed;
        for (std::size_t i = 0; i < b.species.size(); ++i) {
            const Species &x = table3.species[i], &y = b.species[i];
            REQUIRE(x.name == y.name);
            const auto diff = [&](const char* field, bool differs) {
                if (differs) changed.insert(x.name + "/" + field);
            };
            diff("max_age_years", x.maxAgeYears != y.maxAgeYears);
            diff("max_height_m", x.maxHeightM != y.maxHeightM);
            diff("alpha", x.alpha != y.alpha);
            for (Factor f : {Factor::Sun, Factor::Moisture, Factor::Temperature, Factor::Slope}) {
                const std::string name = f == Factor::Sun ? "sun" : f == Factor::Moisture ? "moisture"
                                                                    : f == Factor::Temperature ? "temperature" : "slope";
                diff((name + ".c").c_str(), x.response(f).c != y.response(f).c);
                diff((name + ".r").c_str(), x.response(f).r != y.response(f).r);
            }
            diff("growth_period", x.growthMonths != y.growthMonths);
            diff("sub_biomes", x.subBiomes != y.subBiomes);
            diff("canopy", x.canopy != y.canopy);
        }
        CHECK(changed == e.changed);
    }
    // The fitted values the docs quote for the Fig. 15 fit.
    const Biome fig15 = loadBiome(test::sourcePath("configs/calibrated/laurel-fig15-biome.toml"));
    const Species& laurel = fig15.species[static_cast<std::size_t>(fig15.speciesIndex("California Laurel"))];
    CHECK(laurel.maxAgeYears == 600);
    CHECK(laurel.maxHeightM == Approx(21.875));
    CHECK(laurel.alpha == Approx(1.0));
    CHECK(laurel.response(Factor::Sun).c == Approx(4.9));
    CHECK(fig15.species[static_cast<std::size_t>(fig15.speciesIndex("Toyon"))].alpha == Approx(0.30));
}
