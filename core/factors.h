// The abiotic factors of Eq. 1 as one indexed axis: the factor enum, its table (names and
// units as written in files), the per-cell feature vector and the per-factor annual maps.
// Every module that handles "the abiotics of a cell" goes through these types, so adding a
// factor is a change to this table and to the places that produce its values (docs/factors.md).
#pragma once

#include <array>
#include <cstddef>

#include "grid.h"

namespace eco {

/// The abiotic factors, in the one order used everywhere (feature vectors, the species'
/// responses, database columns, k-means features).
enum class Factor : std::size_t { Sun, Moisture, Temperature, Slope, Wind };

/// Number of factors (the length of every Features vector).
constexpr std::size_t kFactorCount = 5;

/// Names and units of one factor. The key and unit are file formats: the biome TOML's
/// species response tables are named by `key`, a database's /features/names and
/// /features/units hold `key` and `unit`.
struct FactorInfo {
    const char* key;    ///< "sun": TOML table of a species' response, database feature name
    const char* unit;   ///< "hours/day": unit of the annual value
    const char* label;  ///< "sunlight": words for messages ("the sunlight map")
    /// true: every species of a biome gives its response (the paper's four factors); false:
    /// the response is optional and a species without one is indifferent to the factor
    /// (Response::indifferent(), core/vigour.h: normalised distance 0, vigour unchanged).
    bool responseRequired = true;
};

/// The factor table, in Factor order.
inline constexpr std::array<FactorInfo, kFactorCount> kFactors = {{
    {"sun", "hours/day", "sunlight"},
    {"moisture", "mm", "moisture"},
    {"temperature", "degC", "temperature"},
    {"slope", "degrees", "slope"},
    // Zamuda & Brest's wind shelter (EcoMod): the prevailing wind's speed left after the
    // terrain upwind occludes it (core/abiotics.h windSpeedMS, docs/abiotics.md).
    {"wind", "m/s", "wind exposure", false},
}};

/// Position of factor f in every factor-indexed array.
constexpr std::size_t factorIndex(Factor f) { return static_cast<std::size_t>(f); }

/// A cell's (or plant's) abiotic values, one per factor, in factor order. The template is
/// for tests with another number of factors (tests/factors_test.cpp); code uses Features.
template <std::size_t N>
using FeaturesOf = std::array<double, N>;
using Features = FeaturesOf<kFactorCount>;

/// One annual map per factor (hours/day, mm, degC, degrees: see kFactors), one geometry.
struct FactorGrids {
    std::array<Grid<float>, kFactorCount> maps;

    Grid<float>& operator[](Factor f) { return maps[factorIndex(f)]; }
    const Grid<float>& operator[](Factor f) const { return maps[factorIndex(f)]; }
    /// Every map with the geometry of `like`, factor f's map filled with values[f] (tests and
    /// synthetic scenes; a factor added later gets 0 from a shorter initialiser list).
    template <typename T>
    static FactorGrids uniform(const Grid<T>& like, const Features& values) {
        FactorGrids g;
        for (std::size_t f = 0; f < kFactorCount; ++f) g.maps[f] = Grid<float>::like(like, static_cast<float>(values[f]));
        return g;
    }
    /// The grid whose geometry all the maps share (the first factor's).
    const Grid<float>& geometry() const { return maps[0]; }
    /// The features of cell index `cell` (Grid::index), in factor order.
    Features at(std::size_t cell) const {
        Features x{};
        for (std::size_t f = 0; f < kFactorCount; ++f) x[f] = maps[f].data()[cell];
        return x;
    }
    /// The features of cell (ix, iy).
    Features at(int ix, int iy) const { return at(maps[0].index(ix, iy)); }
};

}  // namespace eco
