// Biome definition: species parameters (paper Table 3), sub-biomes, climate, soil and the
// vigour shape. Read from TOML (biomes/*.toml) with strict validation.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "factors.h"
#include "vigour.h"

namespace eco {

/// Crown radius from height, r = exp(a + b ln h) (Eq. 2), or r = factor * h (code E).
struct Allometry {
    std::string code;       ///< "A".."E" as in Table 3, or a user name
    bool linear = false;    ///< true: r = linearFactor * h
    double a = 0.0;
    double b = 1.0;
    double linearFactor = 0.0;
    /// Crown radius in metres for a plant of height heightM metres.
    double crownRadiusM(double heightM) const;
    /// The inverse: height in metres of a plant of crown radius crownRadiusM (0 for r <= 0;
    /// the allometry is increasing when b > 0 / linearFactor > 0, as every biome's is).
    double heightForCrownRadiusM(double crownRadiusM) const;
};

struct Species {
    std::string name;
    int id = 0;                      ///< index in Biome::species
    double maxAgeYears = 1.0;        ///< l_s
    double maxHeightM = 1.0;         ///< h'_s
    double alpha = 0.5;              ///< light absorption / vigour scale, [0, 1]
    Responses responses;             ///< per factor (factors.h order and units): optimum c, range r
    std::string growthPeriod;        ///< name of a Biome::growthPeriods entry
    std::vector<int> growthMonths;   ///< resolved months, 0 = January
    Allometry allometry;
    std::vector<int> subBiomes;      ///< 1-based sub-biome numbers (as in the paper)
    bool canopy = false;             ///< can be a canopy tree
    /// The response to factor f.
    const Response& response(Factor f) const { return responses[factorIndex(f)]; }
    Response& response(Factor f) { return responses[factorIndex(f)]; }
};

struct SubBiome {
    int number = 1;  ///< 1-based, as in the paper
    std::string name;
    std::vector<std::string> canopySpecies;
};

struct Climate {
    double latitudeDeg = 38.58;
    std::array<double, 12> temperatureC{};     ///< sea-level monthly mean, Jan..Dec
    std::array<double, 12> rainfallMm{};       ///< monthly total
    std::array<double, 12> skyClarity{};       ///< fraction of direct sun reaching ground, [0, 1]
    double lapseRateCPerKm = 9.8;
};

struct Soil {
    double runoffLimitMm = 100.0;      ///< most water a cell absorbs in one month
    double slopeThresholdDeg = 5.0;    ///< below: all water infiltrates
    double slopeMaxDeg = 55.0;         ///< above: all water runs off
    double evaporationFraction = 0.25; ///< fraction of soil water evaporated per month
    double saturationMm = 180.0;       ///< soil water capacity
};

struct Biome {
    std::string name;
    std::string sourcePath;
    std::vector<Species> species;
    std::vector<SubBiome> subBiomes;
    Climate climate;
    Soil soil;
    VigourShape vigour;
    std::vector<std::pair<std::string, std::vector<int>>> growthPeriods;

    /// Index of a species by exact name; ValidationError listing the names if unknown.
    int speciesIndex(const std::string& name) const;
    /// Vigour v_s = alpha_s * min_f g(x_f - c_sf, r_sf) of species s (Eq. 1, the scalar form
    /// of vigour.h) for the abiotic values x (one per factor, factors.h units).
    double vigourOf(int s, const Features& x) const;
};

/// Parse and validate a biome TOML file. Throws IoError (unreadable, bad TOML) or
/// ValidationError naming the file, species and field.
Biome loadBiome(const std::string& path);
/// Same from TOML text; `sourceName` is used in messages.
Biome parseBiome(const std::string& tomlText, const std::string& sourceName);
/// The embedded Sonoma biome (paper Table 3), identical to biomes/sonoma.toml.
Biome defaultBiome();
/// TOML text of a biome, loadable by parseBiome (used to record it in outputs).
std::string biomeToToml(const Biome& b);

}  // namespace eco
